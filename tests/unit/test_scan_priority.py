"""The scan's scheduling policy follows the clock mode, the Modbus front-end runs real-time
below it, and a process that is overloaded leaves the real-time policy (the calls to the
operating system are recorded, not made)."""

from __future__ import annotations

import os

import pytest

from motion_server import scheduling
from motion_server.frontends import process as frontend
from motion_server.scan import process
from motion_server.tagmap.fields import ClockMode


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, int]]:
    made: list[tuple[int, int]] = []
    monkeypatch.setattr(os, "setpriority", lambda *args: None)
    monkeypatch.setattr(
        os,
        "sched_setscheduler",
        lambda pid, policy, param: made.append((policy, param.sched_priority)),
    )
    return made


@pytest.fixture
def now(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The monotonic clock the policies read, moved by hand."""
    clock = [1000.0]
    monkeypatch.setattr(scheduling.time, "monotonic", lambda: clock[0])
    return clock


FIFO_SCAN = (os.SCHED_FIFO, scheduling.SCAN_RT_PRIORITY)
OTHER = (os.SCHED_OTHER, 0)


def test_real_time_policy_while_the_clock_follows_the_wall_clock(
    calls: list[tuple[int, int]],
) -> None:
    p = process.scan_policy()
    for mode, load in [
        (ClockMode.REALTIME, 5.0),
        (ClockMode.REALTIME, 5.0),  # no change: no call
        (ClockMode.MANUAL, 5.0),
        (ClockMode.FAST, 100.0),
        (ClockMode.SCALED, 100.0),  # the fast mode's load: not this mode's
    ]:
        p.follow(process._realtime(mode), load)
    assert calls == [FIFO_SCAN, OTHER, FIFO_SCAN]


def test_an_overloaded_scan_leaves_the_real_time_policy_for_good(
    calls: list[tuple[int, int]], now: list[float]
) -> None:
    p = process.scan_policy()
    p.follow(True, 0.0)
    now[0] += 1.0
    p.follow(True, 95.0)  # too soon after the switch to judge
    assert calls == [FIFO_SCAN]
    now[0] += 2.0
    p.follow(True, 95.0)
    p.follow(False, 5.0)
    p.follow(True, 5.0)
    assert calls == [FIFO_SCAN, OTHER]


def test_the_modbus_front_end_runs_real_time_below_the_scan(
    calls: list[tuple[int, int]], now: list[float]
) -> None:
    p = frontend.modbus_policy()
    p.follow(True, 0.0)
    assert calls == [(os.SCHED_FIFO, scheduling.MODBUS_RT_PRIORITY)]
    assert scheduling.MODBUS_RT_PRIORITY < scheduling.SCAN_RT_PRIORITY
    now[0] += 3.0
    p.follow(True, frontend.MODBUS_OVERLOAD - 1)  # busy, not overloaded
    assert p.realtime
    p.follow(True, frontend.MODBUS_OVERLOAD + 1)  # a flood: the ordinary policy
    p.follow(True, 0.0)
    assert calls[1:] == [OTHER] and p.demoted


def test_cpu_load_is_the_share_of_a_window_spent_on_a_cpu(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    wall, cpu = [10.0], [2.0]
    monkeypatch.setattr(scheduling.time, "monotonic", lambda: wall[0])
    monkeypatch.setattr(scheduling.time, "process_time", lambda: cpu[0])
    load = scheduling.CpuLoad()
    wall[0] += 0.5
    cpu[0] += 0.5
    assert load.sample() == 0.0  # half a window: not measured yet
    wall[0] += 1.5
    cpu[0] += 0.0
    assert load.sample() == pytest.approx(25.0)  # 0.5 s of CPU in 2 s


def test_the_modbus_front_end_is_real_time_again_once_a_flood_has_passed(
    calls: list[tuple[int, int]], now: list[float]
) -> None:
    p = frontend.modbus_policy()
    p.follow(True, 0.0)
    now[0] += 3.0
    p.follow(True, 100.0)
    assert calls[-1] == OTHER
    now[0] += 1.0
    p.follow(True, 0.0)  # too soon after the switch to judge
    now[0] += 2.0
    p.follow(True, frontend.MODBUS_OVERLOAD / 2 + 1)  # still busy
    assert calls[-1] == OTHER
    p.follow(True, frontend.MODBUS_OVERLOAD / 2 - 1)
    assert calls[-1] == (os.SCHED_FIFO, scheduling.MODBUS_RT_PRIORITY) and not p.demoted


def test_without_the_permission_the_policy_is_asked_for_once(
    monkeypatch: pytest.MonkeyPatch, now: list[float]
) -> None:
    asked: list[int] = []

    def refuse(pid: int, policy: int, param: os.sched_param) -> None:
        asked.append(policy)
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    p = frontend.modbus_policy()
    p.follow(True, 0.0)
    now[0] += 3.0
    p.follow(True, 100.0)  # never real-time: nothing to leave, no warning
    assert asked == [os.SCHED_FIFO] and not p.realtime and not p.demoted
