"""Jogs started on many axes in one call (``Controller.start_jogs``): the same state as
``Controller.start`` with the jog's factory on each axis in order, attribute by
attribute, and the same motion after every step, lanes on and off; an error stops at
the same axis. The jogs from rest are built by the constructors once per target and
join their lane (profile or S-curve) as one batch planned in the call: the objects read
(or taken out of the lanes) at any moment are those the loop leaves, and a snapshot taken
before the first step runs on bit for bit."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    JogProcess,
    Limits,
    MoveProcess,
    ProcessKind,
)
from motion_server.kernel.errors import MotionError
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterReference
from motion_server.kernel.lanes import ramps, scurve
from motion_server.kernel.override import Override
from motion_server.scan import statecodec

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


def moving_speed(n: int) -> float:
    """The speed of axis ``n``'s jog in the set-ups that start some axes before the
    batch: forward on odd axes, back on even ones, so that they move at two speeds."""
    return 40.0 if n % 2 else -25.0


def moving_limits(speed: float) -> Limits:
    """The limits of a jog at ``speed`` in those set-ups (two accelerations)."""
    return Limits(abs(speed), 800.0 if speed > 0 else 500.0, 800.0)


def moving_jog(n: int) -> Callable[[float, float], JogProcess]:
    """The factory of axis ``n``'s jog in those set-ups."""
    speed = moving_speed(n)
    limits = moving_limits(speed)
    return lambda v, a: JogProcess(PERIOD, speed, limits, v, a)


def count_built(monkeypatch: Any, cls: type, pick: Callable[[tuple[Any, ...]], Any]) -> list[Any]:
    """What ``pick`` takes of the arguments of every ``cls`` constructed from now until
    ``monkeypatch`` is undone, in order."""
    built: list[Any] = []
    init = cls.__init__

    def counting(self: Any, *args: Any, **kwargs: Any) -> None:
        built.append(pick(args))
        init(self, *args, **kwargs)

    monkeypatch.setattr(cls, "__init__", counting)
    return built


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
    moving=st.lists(st.integers(1, N), max_size=N, unique=True),
    overridden=st.sampled_from([None, 1, 3]),
    rates=st.sampled_from([(1000.0, 1000.0), (500.0, 2000.0)]),
    jerk=st.sampled_from([0.0, 0.0, math.inf, 20_000.0]),
    steps=st.integers(1, 80),
    aborting=st.booleans(),
    warm=st.sampled_from([3, 40]),
)
def test_start_jogs_is_start_on_each_axis_in_order(
    axes: list[int],
    targets: list[float],
    moving: list[int],
    overridden: int | None,
    rates: tuple[float, float],
    jerk: float,
    steps: int,
    aborting: bool,
    warm: int,
) -> None:
    """MAJ's jogs (replacing a jog) and, ``aborting``, MC_MoveVelocity's (replacing
    every process: the axes already moving run a move, which a jog of MAJ would not
    replace). The axes moving were started ``warm`` cycles before: still ramping (3) or,
    the jogs, at speed (40)."""
    check_same(axes, targets, moving, overridden, rates, jerk, steps, aborting, warm)


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
    aborting: bool = False,
    warm: int = 3,
) -> None:
    """``start_jogs`` on one controller, ``start`` in a loop on two others (lanes on,
    lanes off) from the same state: the same errors, processes and motion. ``aborting``:
    the moving axes run a move and the jogs replace every process (``replace=None``).
    ``warm``: the cycles run before the batch."""
    replace = None if aborting else (ProcessKind.JOG,)
    limits = Limits(100.0, rates[0], rates[1], jerk)
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for ctl in ctls.values():
        # some axes already jogging or moving (inherit their velocity), one maybe
        # overridden
        for n in moving:
            if aborting:
                ctl.start(
                    ctl.axis(n),
                    lambda v, a: MoveProcess(PERIOD, 30.0, Limits(40.0, 800.0, 800.0), v, a),
                    replace=None,
                )
                continue
            ctl.start(
                ctl.axis(n),
                moving_jog(n),
                replace=(ProcessKind.JOG,),
            )
        if overridden is not None:
            ctl.set_override(ctl.axis(overridden), Override(0.5, 0.5))
        ctl.run(warm)
    owners = [object() for _ in axes]
    errors: dict[str, tuple[int, int] | None] = {}
    for name, ctl in ctls.items():
        errors[name] = None
        chosen = [ctl.axis(n) for n in axes]
        if name == "batch":
            try:
                ctl.start_jogs(chosen, targets[: len(axes)], limits, owners, replace)
            except MotionError as exc:
                errors[name] = (int(exc.code), -1)
        else:
            for ax, target, owner in zip(chosen, targets, owners, strict=False):
                try:
                    ctl.start(
                        ax,
                        lambda v, a, t=target, o=owner: JogProcess(PERIOD, t, limits, v, a, o),
                        replace=replace,
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


def described(p: object) -> str:
    """A process's state as text (a gear's: its kind; it refers to its controller)."""
    if isinstance(p, GearProcess):
        return type(p).__name__
    return repr(sorted(state(p).items()))


#: a few targets, each one object (a batch of equal targets passes the same object)
FEW = (100.0, -40.0, 3, -0.0, 250.5)


@settings(max_examples=60, deadline=None)
@given(
    picks=st.lists(st.integers(0, len(FEW) - 1), min_size=N, max_size=N),
    axes=st.lists(st.integers(1, N), min_size=1, max_size=N, unique=True),
    moving=st.lists(st.integers(1, N), max_size=N, unique=True),
    jerk=st.sampled_from([0.0, 20_000.0, 5_000.0]),
    reads=st.lists(st.tuples(st.integers(0, 100), st.integers(1, N), st.booleans()), max_size=6),
    same=st.booleans(),
)
def test_jogs_read_at_any_moment_are_those_the_loop_leaves(
    picks: list[int],
    axes: list[int],
    moving: list[int],
    jerk: float,
    reads: list[tuple[int, int, bool]],
    same: bool,
) -> None:
    """Axes at rest and moving, targets repeated (copies of one jog) or not, trapezoidal
    or jerk-limited; at random cycles an axis's processes are read (and, at some, taken
    out of the lanes, ``Motion.settle``) on the batch and the loop alike: the same
    objects' state, and after every step the reference's motion. ``same``: one target
    for all (an int given as int and float in turn), on masters only (at rest unless
    jogging already)."""
    limits = Limits(300.0, 1000.0, 2000.0, jerk)
    targets = [FEW[k] for k in picks]
    if same:
        t = FEW[picks[0]]
        targets = [float(t) if k % 2 else t for k in range(N)]
        axes = [n for n in axes if n <= N // 2] or [1, 2]
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for ctl in ctls.values():
        for n in moving:
            ctl.start(
                ctl.axis(n),
                moving_jog(n),
                replace=(ProcessKind.JOG,),
            )
        ctl.run(3)
    for name, ctl in ctls.items():
        chosen = [ctl.axis(n) for n in axes]
        if name == "batch":
            ctl.start_jogs(chosen, targets[: len(axes)], limits)
        else:
            for ax, target in zip(chosen, targets, strict=False):
                ctl.start(
                    ax,
                    lambda v, a, t=target: JogProcess(PERIOD, t, limits, v, a),
                    replace=(ProcessKind.JOG,),
                )
    step_with_reads(ctls, reads, 101)


def step_with_reads(
    ctls: dict[str, Controller], reads: list[tuple[int, int, bool]], cycles: int
) -> None:
    """``cycles`` steps of ``ctls`` ("batch", "loop" and "ref"). Before the step of each
    ``(cycle, n, settle)`` of ``reads``, axis ``n``'s processes are read (taken out of
    the lanes first, ``Motion.settle``, when ``settle``) on the batch and the loop alike:
    the same objects' state; after every step, the same commands on all three."""
    batch, loop, ref = ctls["batch"], ctls["loop"], ctls["ref"]
    for c in range(cycles):
        for cycle, n, settle in reads:
            if cycle != c:
                continue
            if settle:
                batch.motion.settle(batch.axis(n))
                loop.motion.settle(loop.axis(n))
            ps, qs = batch.axis(n).processes, loop.axis(n).processes
            assert list(map(described, ps)) == list(map(described, qs)), (c, n)
        for ctl in ctls.values():
            ctl.step()
        for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
            x = getattr(batch, arr)
            assert x.tobytes() == getattr(loop, arr).tobytes(), (arr, c)
            assert x.tobytes() == getattr(ref, arr).tobytes(), (arr, c)


def test_jogs_from_rest_are_built_once_per_target_and_planned_in_the_call(
    monkeypatch: Any,
) -> None:
    """Six masters at rest, three to one target and three to another, jerk-limited: the
    constructor runs twice (once per target), and the first step plans nothing (the
    lane takes the columns the call planned); the motion is the loop's."""
    limits = Limits(300.0, 1000.0, 2000.0, 20_000.0)
    a, b = 100.0, -60.0
    targets = [a, a, b, a, b, b]
    batch, ref = controller(True), controller(False)
    built = count_built(monkeypatch, JogProcess, lambda args: args[1])
    batch.start_jogs(batch.axes[: N // 2], targets, limits)
    assert sorted(built) == [b, a]

    def refuse(*args: Any) -> None:
        raise AssertionError("planned at the step")

    monkeypatch.setattr(scurve, "jerk_plans", refuse)
    monkeypatch.setattr(ramps, "velocity_plans", refuse)
    batch.step()
    monkeypatch.undo()
    for ax, t in zip(ref.axes, targets, strict=False):
        ref.start(ax, lambda v, acc, t=t: JogProcess(PERIOD, t, limits, v, acc))
    ref.step()
    for _ in range(200):
        assert batch.cmd_pos.tobytes() == ref.cmd_pos.tobytes()
        assert batch.cmd_vel.tobytes() == ref.cmd_vel.tobytes()
        batch.step()
        ref.step()


@pytest.mark.parametrize("jerk", [0.0, 20_000.0])
def test_jogs_replaced_on_moving_axes_are_built_once_per_start_and_keep_the_levels(
    monkeypatch: Any, jerk: float
) -> None:
    """Six masters jogging, their slaves geared to them: three at speed (40 mm/s, in the
    cruise lane), two still ramping (in the profile lane) and one at speed at 25 mm/s.
    ``start_jogs`` to one target on all six builds one jog per velocity and acceleration
    they start from (three at speed alike: one built, two copied); the first step plans
    nothing (the call planned the jogs) and levels no follower again (the masters pass
    from one time-driven lane to another: their slaves read them as before); the motion
    is the loop's and the reference's, step by step, and so are the objects. The new
    jogs are trapezoidal (the profile lane) or jerk-limited (the S-curve lane, the
    closed form from the velocity and acceleration each starts from)."""
    limits = Limits(300.0, 1000.0, 2000.0, jerk)
    slow = Limits(25.0, 800.0, 800.0)
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for ctl in ctls.values():
        for n in (1, 2, 3, 6):
            lim = slow if n == 6 else Limits(40.0, 800.0, 800.0)
            speed = lim.velocity
            ctl.start(
                ctl.axis(n),
                lambda v, a, s=speed, lim=lim: JogProcess(PERIOD, s, lim, v, a),
                replace=(ProcessKind.JOG,),
            )
        ctl.run(40)  # at speed: 40 mm/s at 800 mm/s² is 25 cycles
        for n in (4, 5):
            ctl.start(
                ctl.axis(n),
                lambda v, a: JogProcess(PERIOD, 40.0, Limits(40.0, 800.0, 800.0), v, a),
                replace=(ProcessKind.JOG,),
            )
        ctl.run(3)  # 4 and 5 ramping: 4.8 mm/s, 800 mm/s²
    batch, loop, ref = ctls["batch"], ctls["loop"], ctls["ref"]
    lanes = batch.motion.lanes[1]
    assert [type(batch.axis(n).processes[0].lane).__name__ for n in range(1, 7)] == [
        "CruiseLane", "CruiseLane", "CruiseLane", "ProfileLane", "ProfileLane", "CruiseLane"
    ]  # fmt: skip
    target = -60.0
    # (the velocity and acceleration each jog starts from)
    built = count_built(monkeypatch, JogProcess, lambda args: (args[3], args[4]))
    batch.start_jogs(batch.axes[: N // 2], [target] * (N // 2), limits)
    monkeypatch.undo()
    # (40, 0) once for 1-3, (4.8, 800) once for 4 and 5, (25, 0) for 6
    assert len(built) == 3 and built[0] == (40.0, 0.0) and built[2] == (25.0, 0.0)
    assert built[1][1] == 800.0 and math.isclose(built[1][0], 4.8)
    for ax in loop.axes[: N // 2]:
        loop.start(
            ax,
            lambda v, a: JogProcess(PERIOD, target, limits, v, a),
            replace=(ProcessKind.JOG,),
        )
    for ax in ref.axes[: N // 2]:
        ref.start(
            ax,
            lambda v, a: JogProcess(PERIOD, target, limits, v, a),
            replace=(ProcessKind.JOG,),
        )

    # jogs replaced by jogs: no process that reads a master came or went, the
    # composition order stands (``Motion.retire``)
    assert not batch.motion.order_dirty and not loop.motion.order_dirty

    def refuse(*args: Any) -> None:
        raise AssertionError("planned or levelled at the step")

    monkeypatch.setattr(ramps, "velocity_plans", refuse)
    monkeypatch.setattr(scurve, "jerk_plans", refuse)
    monkeypatch.setattr(type(lanes), "_order_command_followers", refuse)
    batch.step()
    lane = "SCurveLane" if jerk else "ProfileLane"
    assert {type(ax.processes[0].lane).__name__ for ax in batch.axes[: N // 2]} == {lane}
    monkeypatch.undo()
    loop.step()
    ref.step()
    for c in range(120):
        for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
            x = getattr(batch, arr)
            assert x.tobytes() == getattr(loop, arr).tobytes(), (arr, c)
            assert x.tobytes() == getattr(ref, arr).tobytes(), (arr, c)
        for a, b in zip(batch.axes, loop.axes, strict=True):
            assert list(map(described, a.processes)) == list(map(described, b.processes))
        for ctl in ctls.values():
            ctl.step()


def test_a_snapshot_taken_before_the_batch_joins_runs_on_bit_for_bit() -> None:
    """The batch's columns wait in the lanes for the first step: a copy of the
    controller through the snapshot codec taken then runs on as the original does."""
    for jerk in (0.0, 20_000.0):
        limits = Limits(300.0, 1000.0, 2000.0, jerk)
        fast, ref = controller(True), controller(False)
        targets = [100.0, 100.0, -30.0, 7.5, 100.0, -30.0]
        fast.start_jogs(fast.axes[: N // 2], targets, limits)
        for ax, t in zip(ref.axes, targets, strict=False):
            ref.start(ax, lambda v, acc, t=t, lim=limits: JogProcess(PERIOD, t, lim, v, acc))
        copy = statecodec.loads(statecodec.dumps(fast))
        for c in range(150):
            for ctl in (fast, ref, copy):
                ctl.step()
            assert fast.cmd_pos.tobytes() == ref.cmd_pos.tobytes(), (jerk, c)
            assert copy.cmd_pos.tobytes() == ref.cmd_pos.tobytes(), (jerk, c)
            assert copy.cmd_vel.tobytes() == ref.cmd_vel.tobytes(), (jerk, c)


def two_groups(lanes: bool) -> Controller:
    """Eight virtual axes in two groups of different periods, interleaved in number."""
    cfg = [
        AxisConfig(n, f"A{n}", AxisType.VIRTUAL, max_acceleration=5000.0,
                   max_deceleration=5000.0)
        for n in range(1, 9)
    ]  # fmt: skip
    groups = [GroupConfig(1, "G1", (1, 3, 5, 7), 0.002), GroupConfig(2, "G2", (2, 4, 6, 8), 0.001)]
    ctl = Controller(cfg, groups, lanes=lanes)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    ctl.run(2)
    return ctl


def test_a_batch_over_two_groups_joins_each_group_in_order() -> None:
    """Jogs on axes of two groups in turn (each period its own prototype, each group's
    lane its own batches), trapezoidal then jerk-limited on the same axes: the loop's
    processes and motion, lanes on and off."""
    order = [1, 2, 3, 4, 6, 8, 5, 7]
    targets = [50.0, 50.0, -20.0, 50.0, 50.0, -20.0, 50.0, 80.0]
    for jerk in (0.0, 20_000.0):
        limits = Limits(300.0, 1000.0, 2000.0, jerk)
        batch, loop, ref = two_groups(True), two_groups(True), two_groups(False)
        batch.start_jogs([batch.axis(n) for n in order], targets, limits)
        for ctl in (loop, ref):
            for n, t in zip(order, targets, strict=True):
                ax = ctl.axis(n)
                ctl.start(
                    ax,
                    lambda v, a, t=t, dt=ax.period, lim=limits: JogProcess(dt, t, lim, v, a),
                    replace=(ProcessKind.JOG,),
                )
        for n in order:
            assert list(map(described, batch.axis(n).processes)) == list(
                map(described, loop.axis(n).processes)
            ), (jerk, n)
        for c in range(200):
            for ctl in (batch, loop, ref):
                ctl.step()
            for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
                x = getattr(batch, arr).tobytes()
                assert x == getattr(loop, arr).tobytes(), (jerk, arr, c)
                assert x == getattr(ref, arr).tobytes(), (jerk, arr, c)
