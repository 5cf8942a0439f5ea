"""The scan's scheduling policy follows the clock mode, and an overloaded scan leaves the
real-time policy (the calls to the operating system are recorded, not made)."""

from __future__ import annotations

import os

import pytest

from motion_server.scan import process
from motion_server.tagmap.fields import ClockMode


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    made: list[int] = []
    monkeypatch.setattr(os, "setpriority", lambda *args: None)
    monkeypatch.setattr(os, "sched_setscheduler", lambda pid, policy, param: made.append(policy))
    return made


def test_real_time_policy_while_the_clock_follows_the_wall_clock(calls: list[int]) -> None:
    p = process._Priority()
    p.follow(ClockMode.REALTIME, 5.0)
    p.follow(ClockMode.REALTIME, 5.0)  # no change: no call
    p.follow(ClockMode.MANUAL, 5.0)
    p.follow(ClockMode.FAST, 100.0)
    p.follow(ClockMode.SCALED, 100.0)  # the fast mode's load: not this mode's
    assert calls == [os.SCHED_FIFO, os.SCHED_OTHER, os.SCHED_FIFO]


def test_an_overloaded_scan_leaves_the_real_time_policy_for_good(
    calls: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    now = [1000.0]
    monkeypatch.setattr(process.time, "monotonic", lambda: now[0])
    p = process._Priority()
    p.follow(ClockMode.REALTIME, 0.0)
    now[0] += 1.0
    p.follow(ClockMode.REALTIME, 95.0)  # too soon after the switch to judge
    assert calls == [os.SCHED_FIFO]
    now[0] += 2.0
    p.follow(ClockMode.REALTIME, 95.0)
    p.follow(ClockMode.MANUAL, 5.0)
    p.follow(ClockMode.REALTIME, 5.0)
    assert calls == [os.SCHED_FIFO, os.SCHED_OTHER]
