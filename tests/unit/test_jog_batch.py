"""Jogs started on many axes in one call (``Controller.start_jogs``): the same state as
``Controller.start`` with the jog's factory on each axis in order, attribute by
attribute, and the same motion after every step, lanes on and off; an error stops at
the same axis."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    JogProcess,
    Limits,
    ProcessKind,
)
from motion_server.kernel.errors import MotionError
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterReference
from motion_server.kernel.override import Override

N = 12
PERIOD = 0.002


def controller(lanes: bool) -> Controller:
    """Six virtual masters, six servo slaves geared to them (real ratio 0.5, command
    reference, locked): the followers of the masters the jogs start."""
    cfg = [
        AxisConfig(n, f"A{n}", AxisType.VIRTUAL if n <= N // 2 else AxisType.SERVO,
                   max_acceleration=5000.0, max_deceleration=5000.0,
                   following_error_limit=1e6)
        for n in range(1, N + 1)
    ]  # fmt: skip
    ctl = Controller(cfg, [GroupConfig(1, "G", tuple(range(1, N + 1)), PERIOD)], lanes=lanes)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    for k in range(N // 2):
        slave = ctl.axes[N // 2 + k]
        term = GearTerm(k + 1, MasterReference.COMMAND, 0.5)

        def make(v: float, a: float, slave: Any = slave, term: GearTerm = term) -> GearProcess:
            return GearProcess(ctl, slave, (term,), None, v, a)

        ctl.start(slave, make, replace=(ProcessKind.GEAR,))
    ctl.run(2)
    return ctl


def state(p: object) -> dict[str, object]:
    """A process's attributes, its profile's as a dict, its lane by kind."""
    out = dict(vars(p))
    lane = out.pop("lane", None)
    out["lane"] = type(lane).__name__
    if "profile" in out:
        out["profile"] = dict(vars(out["profile"]))
    return out


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


targets = st.one_of(
    st.sampled_from([0.0, -0.0, 10.0, -25.0, 100.0, 3]),
    st.floats(-500.0, 500.0),
    st.sampled_from([math.inf, math.nan, 1e300]),  # refused: not finite, too long
)


@settings(max_examples=60, deadline=None)
@given(
    axes=st.lists(st.integers(1, N), min_size=1, max_size=N, unique=True),
    targets=st.lists(targets, min_size=N, max_size=N),
    moving=st.lists(st.integers(1, N), max_size=4, unique=True),
    overridden=st.sampled_from([None, 1, 3]),
    rates=st.sampled_from([(1000.0, 1000.0), (500.0, 2000.0)]),
    jerk=st.sampled_from([0.0, 0.0, math.inf, 20_000.0]),
    steps=st.integers(1, 80),
)
def test_start_jogs_is_start_on_each_axis_in_order(
    axes: list[int],
    targets: list[float],
    moving: list[int],
    overridden: int | None,
    rates: tuple[float, float],
    jerk: float,
    steps: int,
) -> None:
    check_same(axes, targets, moving, overridden, rates, jerk, steps)


def test_jogs_from_rest_copied_from_the_first_keep_their_own_target_exactly() -> None:
    """Every axis at rest: the first jog is built by the constructors, the others
    copied from it; an int target stays an int, -0.0 stays -0.0, as the constructor
    keeps them."""
    targets: list[float] = [10.0, 3, -0.0, -25.0, 0.0, 7, 250.5, -1, 0.1, 42.0, -3.5, 1e-300]
    check_same(list(range(1, N + 1)), targets, [], None, (1000.0, 1000.0), 0.0, 120)
    check_same(list(range(N, 0, -1)), targets, [2], 5, (500.0, 2000.0), math.inf, 60)


def check_same(
    axes: list[int],
    targets: list[float],
    moving: list[int],
    overridden: int | None,
    rates: tuple[float, float],
    jerk: float,
    steps: int,
) -> None:
    """``start_jogs`` on one controller, ``start`` in a loop on two others (lanes on,
    lanes off) from the same state: the same errors, processes and motion."""
    limits = Limits(100.0, rates[0], rates[1], jerk)
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for ctl in ctls.values():
        # some axes already jogging (inherit their velocity), one maybe overridden
        for n in moving:
            ctl.start(
                ctl.axis(n),
                lambda v, a: JogProcess(PERIOD, 40.0, Limits(40.0, 800.0, 800.0), v, a),
                replace=(ProcessKind.JOG,),
            )
        if overridden is not None:
            ctl.set_override(ctl.axis(overridden), Override(0.5, 0.5))
        ctl.run(3)
    owners = [object() for _ in axes]
    errors: dict[str, tuple[int, int] | None] = {}
    for name, ctl in ctls.items():
        errors[name] = None
        chosen = [ctl.axis(n) for n in axes]
        if name == "batch":
            try:
                ctl.start_jogs(chosen, targets[: len(axes)], limits, owners)
            except MotionError as exc:
                errors[name] = (int(exc.code), -1)
        else:
            for ax, target, owner in zip(chosen, targets, owners, strict=False):
                try:
                    ctl.start(
                        ax,
                        lambda v, a, t=target, o=owner: JogProcess(PERIOD, t, limits, v, a, o),
                        replace=(ProcessKind.JOG,),
                    )
                except MotionError as exc:
                    errors[name] = (int(exc.code), -1)
                    break
    assert errors["batch"] == errors["loop"] == errors["ref"]
    batch, loop, ref = ctls["batch"], ctls["loop"], ctls["ref"]
    for a, b in zip(batch.axes, loop.axes, strict=True):
        assert len(a.processes) == len(b.processes), a.name
        for p, q in zip(a.processes, b.processes, strict=True):
            sp, sq = state(p), state(q)
            if isinstance(p, JogProcess):
                assert p.owner is q.owner
                sp.pop("owner")
                sq.pop("owner")
                prof_p, prof_q = sp.pop("profile"), sq.pop("profile")
                assert isinstance(prof_p, dict) and isinstance(prof_q, dict)
                assert prof_p.keys() == prof_q.keys()
                for key in prof_p:
                    x, y = prof_p[key], prof_q[key]
                    assert repr(x) == repr(y), (a.name, key)  # -0.0 and NaN alike
            if not isinstance(p, GearProcess):
                assert repr(sorted(sp.items(), key=lambda kv: kv[0])) == repr(
                    sorted(sq.items(), key=lambda kv: kv[0])
                ), a.name
    for c in range(steps):
        for ctl in ctls.values():
            ctl.step()
        for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
            x = getattr(batch, arr)
            assert x.tobytes() == getattr(loop, arr).tobytes(), (arr, c)
            assert x.tobytes() == getattr(ref, arr).tobytes(), (arr, c)
    assert np.array_equal(batch.cmd_pos, ref.cmd_pos)
    assert all(same(float(x), float(y)) for x, y in zip(batch.cmd_vel, ref.cmd_vel, strict=True))
