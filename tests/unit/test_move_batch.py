"""Moves started on many axes in one call (``Controller.start_moves``): the same state
as ``Controller.start`` with MAM's factory on each axis in order (replacing a move),
attribute by attribute, and the same motion after every step, lanes on and off; an
error stops at the same axis. The trapezoidal moves from rest are built by the
constructors once per distance and join the profile lane as one batch: the objects
read (or taken out of the lanes) at any moment are those the loop leaves, and a
snapshot taken before the first step runs on bit for bit."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import JogProcess, Limits, MoveProcess, ProcessKind, move_batch
from motion_server.kernel.errors import MotionError
from motion_server.kernel.gearing import GearProcess
from motion_server.kernel.lanes import ramps
from motion_server.kernel.lanes.scurve import SCurveLane
from motion_server.kernel.override import Override
from motion_server.kernel.trapezoid import MAX_DURATION
from motion_server.scan import statecodec

from .test_jog_batch import PERIOD, N, controller, count_built, state, step_with_reads

_MOVE = (ProcessKind.MOVE,)

distances = st.one_of(
    st.sampled_from([0.0, -0.0, 10.0, -25.0, 100.0, 3]),
    st.floats(-500.0, 500.0),
    st.sampled_from([math.inf, math.nan, 1e300]),  # refused: not finite, too long
)


def plain(p: object) -> str:
    """A process's state (:func:`.test_jog_batch.state`) but its owner, as text; an
    object without a repr of its own (a jerk-limited profile's ruckig) by its type."""
    out = state(p)
    out.pop("owner")
    profile = out.get("profile")
    if isinstance(profile, dict):
        out["profile"] = {
            k: type(v).__name__ if " at 0x" in repr(v) else v for k, v in profile.items()
        }
    return repr(sorted(out.items()))


def start_loop(ctl: Any, axes: list[Any], dist: list[float], limits: Limits,
               owners: list[Any] | None, landings: list[float | None] | None,
               replace: tuple[ProcessKind, ...] | None = _MOVE) -> None:  # fmt: skip
    """``Controller.start`` with MAM's factory on each axis in order (``replace``: what
    each move supersedes)."""
    for k, ax in enumerate(axes):
        owner = None if owners is None else owners[k]
        landing = None if landings is None else landings[k]

        def make(v: float, a: float, d: float = dist[k], o: Any = owner,
                 ld: float | None = landing) -> MoveProcess:  # fmt: skip
            return MoveProcess(PERIOD, d, limits, v, a, o, ld)

        ctl.start(ax, make, replace=replace)


@settings(max_examples=60, deadline=None)
@given(
    axes=st.lists(st.integers(1, N), min_size=1, max_size=N, unique=True),
    dist=st.lists(distances, min_size=N, max_size=N),
    landed=st.lists(st.booleans(), min_size=N, max_size=N),
    moving=st.lists(
        st.tuples(st.integers(1, N), st.booleans(), st.sampled_from([40.0, -25.0])), max_size=N
    ),
    overridden=st.sampled_from([None, 1, 3]),
    rates=st.sampled_from([(1000.0, 1000.0), (500.0, 2000.0), (1e-6, 1e-6)]),
    jerk=st.sampled_from([0.0, 0.0, math.inf, 20_000.0]),
    steps=st.integers(1, 80),
    aborting=st.booleans(),
    warm=st.sampled_from([3, 40]),
    shared=st.booleans(),
)
def test_start_moves_is_start_on_each_axis_in_order(
    axes: list[int],
    dist: list[float],
    landed: list[bool],
    moving: list[tuple[int, bool, float]],
    overridden: int | None,
    rates: tuple[float, float],
    jerk: float,
    steps: int,
    aborting: bool,
    warm: int,
    shared: bool,
) -> None:
    """Axes at rest and moving (a move, which the new one replaces and inherits, or a
    jog, which it superimposes on, or which it replaces too when ``aborting``: the
    PLCopen moves replace every process; forward or back, at two rates), one maybe
    overridden, rates that make long
    moves too long to plan (refused in the middle), trapezoidal or jerk-limited. The
    axes moving were started ``warm`` cycles before: ramping (3) or, the jogs, at speed
    and the moves landed (40). ``shared``: one distance (one object) for every axis, as
    MC_MoveRelative instances with the same operands give."""
    if shared:
        dist = [dist[0]] * N
    replace = None if aborting else _MOVE
    limits = Limits(100.0, rates[0], rates[1], jerk)
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for ctl in ctls.values():
        for n, move, speed in moving:
            lim = Limits(abs(speed), 800.0 if speed > 0 else 500.0, 800.0)
            if move:
                ctl.start(ctl.axis(n), lambda v, a, s=speed, lim=lim: MoveProcess(
                    PERIOD, 0.75 * s, lim, v, a), replace=_MOVE)  # fmt: skip
            else:
                ctl.start(ctl.axis(n), lambda v, a, s=speed, lim=lim: JogProcess(
                    PERIOD, s, lim, v, a), replace=(ProcessKind.JOG,))  # fmt: skip
        if overridden is not None:
            ctl.set_override(ctl.axis(overridden), Override(0.5, 0.5))
        ctl.run(warm)
    owners = [object() for _ in axes]
    landings: list[float | None] = [
        d + 7.0 if flag else None for d, flag in zip(dist, landed, strict=True)
    ][: len(axes)]
    errors: dict[str, int | None] = {}
    for name, ctl in ctls.items():
        errors[name] = None
        chosen = [ctl.axis(n) for n in axes]
        try:
            if name == "batch":
                ctl.start_moves(chosen, dist[: len(axes)], limits, owners, landings, replace)
            else:
                start_loop(ctl, chosen, dist, limits, owners, landings, replace)
        except MotionError as exc:
            errors[name] = int(exc.code)
    assert errors["batch"] == errors["loop"] == errors["ref"]
    batch, loop, ref = ctls["batch"], ctls["loop"], ctls["ref"]
    for a, b in zip(batch.axes, loop.axes, strict=True):
        assert len(a.processes) == len(b.processes), a.name
        for p, q in zip(a.processes, b.processes, strict=True):
            if isinstance(p, GearProcess):
                continue
            assert p.owner is q.owner
            assert plain(p) == plain(q), a.name
    for c in range(steps):
        for ctl in ctls.values():
            ctl.step()
        for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
            x = getattr(batch, arr).tobytes()
            assert x == getattr(loop, arr).tobytes() == getattr(ref, arr).tobytes(), (arr, c)


@settings(max_examples=40, deadline=None)
@given(
    picks=st.lists(st.sampled_from([25.0, -40.0, 3, -0.0, 250.5]), min_size=N, max_size=N),
    axes=st.lists(st.integers(1, N // 2), min_size=1, max_size=N // 2, unique=True),
    reads=st.lists(st.tuples(st.integers(0, 300), st.integers(1, N), st.booleans()), max_size=6),
    jerk=st.sampled_from([0.0, 40_000.0]),
)
def test_moves_read_at_any_moment_are_those_the_loop_leaves(
    picks: list[float], axes: list[int], reads: list[tuple[int, int, bool]], jerk: float
) -> None:
    """Masters at rest, distances repeated (copies of one move) or not, trapezoidal or
    jerk-limited; at random cycles an axis's processes are read (and, at some, taken out
    of the lanes, ``Motion.settle``) on the batch and the loop alike: the same objects'
    state, and after every step the reference's motion, until every move has landed."""
    limits = Limits(300.0, 1000.0, 2000.0, jerk)
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for name, ctl in ctls.items():
        chosen = [ctl.axis(n) for n in axes]
        if name == "batch":
            ctl.start_moves(chosen, picks[: len(axes)], limits)
        else:
            start_loop(ctl, chosen, picks, limits, None, None)
    batch = ctls["batch"]
    step_with_reads(ctls, reads, 301)
    # 250.5 units at 300 units/s, 1,000 up and 2,000 down: under 1.2 s (600 cycles of
    # 2 ms), also with the jerk limit (1.0975 s: 250.5/300 + 300/2000 + 300/4000 +
    # 1000/80,000 + 2000/80,000)
    for _ in range(300):
        batch.step()
    for n, d in zip(axes, picks, strict=False):
        assert batch.axis(n).command_position == d
        assert not batch.axis(n).processes


@pytest.mark.parametrize("jerk", [0.0, 40_000.0])
def test_moves_from_rest_are_built_once_per_distance_and_read_once(
    monkeypatch: Any, jerk: float
) -> None:
    """Six masters at rest, three moves of one distance and three of another,
    trapezoidal (the profile lane) or jerk-limited (the S-curve lane): the constructor
    runs twice (once per distance), and the first step reads no move's plan (the lane
    takes the columns the call read); the motion is the loop's."""
    limits = Limits(300.0, 1000.0, 2000.0, jerk)
    a, b = 100.0, -60.0
    dist = [a, a, b, a, b, b]
    batch, ref = controller(True), controller(False)
    built = count_built(monkeypatch, MoveProcess, lambda args: args[1])
    landings = [float(k) for k in range(N // 2)]
    started = batch.start_moves(batch.axes[: N // 2], dist, limits, None, landings)
    assert sorted(built) == [b, a]
    assert [p.landing for p in started] == landings  # (each copy its own)

    def refuse(*args: Any) -> None:
        raise AssertionError("a move read at the step")

    monkeypatch.setattr(ramps.ProfileLane, "_load", refuse)
    monkeypatch.setattr(SCurveLane, "_load", refuse)
    batch.step()
    monkeypatch.undo()
    lane = batch.motion.lanes[1].scurves if jerk else batch.motion.lanes[1].profiles
    assert len(lane.members) == N // 2
    start_loop(ref, ref.axes[: N // 2], dist, limits, None, landings)
    ref.step()
    for _ in range(400):
        assert batch.cmd_pos.tobytes() == ref.cmd_pos.tobytes()
        assert batch.cmd_vel.tobytes() == ref.cmd_vel.tobytes()
        batch.step()
        ref.step()


@pytest.mark.parametrize("jerk", [0.0, 40_000.0])
def test_absolute_moves_on_jogging_axes_land_on_their_target(monkeypatch: Any, jerk: float) -> None:
    """Six masters jogging at 40 mm/s (at speed, in the cruise lane), their slaves geared
    to them; MC_MoveAbsolute to 100 mm on each, aborting, trapezoidal or jerk-limited
    (planned in closed form from the cruise): each move replaces the jog and starts from
    40 mm/s. Masters 1 to 3 were started together, so they stand at one
    position and share one distance: one move built, two copied; 4 to 6 each their own.
    The first step plans nothing and levels no follower again; the motion is the loop's
    and the reference's step by step, and every master comes to rest on 100 exactly
    (the landing of an absolute move)."""
    jog = Limits(40.0, 800.0, 800.0)
    limits = Limits(300.0, 1000.0, 2000.0, jerk)
    ctls = {name: controller(lanes) for name, lanes in (("batch", True), ("loop", True),
                                                         ("ref", False))}  # fmt: skip
    for ctl in ctls.values():
        ctl.start_jogs(ctl.axes[:3], [40.0] * 3, jog)
        ctl.run(5)
        for ax in ctl.axes[3 : N // 2]:
            ctl.start_jogs([ax], [40.0], jog)
            ctl.run(1 + ax.index)
        ctl.run(40)  # at speed: 40 mm/s at 800 mm/s² is 25 cycles
    batch, loop, ref = ctls["batch"], ctls["loop"], ctls["ref"]
    assert {type(ax.processes[0].lane).__name__ for ax in batch.axes[: N // 2]} == {"CruiseLane"}
    target = 100.0

    def refuse(*args: Any) -> None:
        raise AssertionError("planned or levelled at the step")

    for name, ctl in ctls.items():
        masters = ctl.axes[: N // 2]
        dist = [target - ax.command_position for ax in masters]
        if name == "batch":
            assert dist[0] == dist[1] == dist[2] and len(set(dist)) == 4
            built = count_built(monkeypatch, MoveProcess, lambda args: args[1])
            ctl.start_moves(masters, dist, limits, None, [target] * len(masters), None)
            monkeypatch.undo()
            assert built == [dist[0], *dist[3:]]
            monkeypatch.setattr(ramps.ProfileLane, "_load", refuse)
            monkeypatch.setattr(SCurveLane, "_load", refuse)
            monkeypatch.setattr(type(ctl.motion.lanes[1]), "_order_command_followers", refuse)
            ctl.step()
            monkeypatch.undo()
            lanes = ctl.motion.lanes[1]
            lane = lanes.scurves if jerk else lanes.profiles
            assert {ax.processes[0].lane for ax in masters} == {lane}
        else:
            start_loop(ctl, masters, dist, limits, None, [target] * len(masters), None)
            ctl.step()
    for c in range(600):
        for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
            x = getattr(batch, arr).tobytes()
            assert x == getattr(loop, arr).tobytes() == getattr(ref, arr).tobytes(), (arr, c)
        for ctl in ctls.values():
            ctl.step()
    for ax in batch.axes[: N // 2]:
        assert ax.command_position == target
        assert not ax.processes


def test_a_snapshot_taken_before_the_batch_joins_runs_on_bit_for_bit() -> None:
    """The batch's columns wait in the profile lane for the first step: a copy of the
    controller through the snapshot codec taken then runs on as the original does."""
    limits = Limits(300.0, 1000.0, 2000.0)
    fast, ref = controller(True), controller(False)
    dist = [100.0, 100.0, -30.0, 7.5, 100.0, -30.0]
    fast.start_moves(fast.axes[: N // 2], dist, limits)
    start_loop(ref, ref.axes[: N // 2], dist, limits, None, None)
    copy = statecodec.loads(statecodec.dumps(fast))
    for c in range(400):
        for ctl in (fast, ref, copy):
            ctl.step()
        assert fast.cmd_pos.tobytes() == ref.cmd_pos.tobytes(), c
        assert copy.cmd_pos.tobytes() == ref.cmd_pos.tobytes(), c


def test_a_move_too_long_to_plan_is_refused_where_the_loop_refuses_it() -> None:
    """At 10^-6 units/s² up and down, a move of d units from rest is a triangle of
    2 sqrt(d / 10^-6) s: 2,000 s for 1 unit, 20,000 s for 100, beyond the kernel's
    longest plan. The batch of 1, 100, 1 starts the first move and refuses the second
    with the loop's error; the third is not started."""
    assert 2 * math.sqrt(100 / 1e-6) > MAX_DURATION > 2 * math.sqrt(1 / 1e-6)
    limits = Limits(1000.0, 1e-6, 1e-6)
    ctl = controller(True)
    try:
        ctl.start_moves(ctl.axes[:3], [1.0, 100.0, 1.0], limits)
    except MotionError as exc:
        assert exc.code.name == "PROFILE_FAILED"
    else:
        raise AssertionError("the 100-unit move was planned")
    assert [len(ax.processes) for ax in ctl.axes[:3]] == [1, 0, 0]


@pytest.mark.parametrize("jerk", [0.0, 40_000.0])
def test_moves_of_many_distances_are_planned_together(monkeypatch: Any, jerk: float) -> None:
    """Six masters at rest, six distances (absolute moves to one target from six
    positions give as many): the constructor builds the first move alone, the other
    five are its copies with plans built together (``move_plan.position_plans``, or
    ``scurve_position_plan.plans_from_rest`` with a jerk limit;
    :data:`~motion_server.kernel.move_batch.AHEAD` distances or more), each the plan
    the scalar planner builds, bit for bit: the same objects and motion as the loop's,
    every move on its target at the end."""
    limits = Limits(300.0, 1000.0, 2000.0, jerk)
    dist = [100.0, -60.0, 7.5, 0.25, -0.0, 3]
    assert len(set(dist)) >= move_batch.AHEAD
    batch, loop, ref = controller(True), controller(True), controller(False)
    built = count_built(monkeypatch, MoveProcess, lambda args: args[1])
    batch.start_moves(batch.axes[: N // 2], dist, limits)
    monkeypatch.undo()
    assert built == [100.0]
    for ctl in (loop, ref):
        start_loop(ctl, ctl.axes[: N // 2], dist, limits, None, None)
    for a, b in zip(batch.axes[: N // 2], loop.axes[: N // 2], strict=True):
        (p,), (q,) = a.processes, b.processes
        assert plain(p) == plain(q), a.name
    for c in range(400):
        for ctl in (batch, loop, ref):
            ctl.step()
        assert batch.cmd_pos.tobytes() == loop.cmd_pos.tobytes() == ref.cmd_pos.tobytes(), c
    # 100 mm at 300 mm/s, 1,000 up and 2,000 down, 40,000 mm/s³: 100/300 + 300/2000 +
    # 300/4000 + 1000/80,000 + 2000/80,000 = 0.596 s, 298 cycles of 2 ms
    assert [ax.command_position for ax in batch.axes[: N // 2]] == [float(x) for x in dist]
