"""Group stops planned as arrays (:mod:`motion_server.kernel.stop_plan`) change nothing
but speed: a controller with the fast lanes (which plans a group stop's ramps in one
batch) and one without (``lanes=False``: the stop axis by axis, the reference), given the
same random motion on many axes and then the same group stop, in any mode, or MGSD (a
batch of shutdowns with the lanes), at a random moment, agree bit for bit after every
cycle on every array, every axis and every process ever started, its state, abort
reason and kinematics (a laned process is read through its lane's sync, which leaves it
in the lane)."""

from __future__ import annotations

import gc
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    JogProcess,
    Limits,
    MotionError,
    MotionStatusBit,
    MoveProcess,
    PLCopenState,
    ProcessKind,
    ProgrammedStopMode,
)
from motion_server.kernel.cam_profile import SegmentType, compute_profile
from motion_server.kernel.cams import CamMode, CamProcess, LockDirection
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterReference, RateRamp
from motion_server.kernel.group import OperatingMode
from motion_server.kernel.processes import Process, StopRamp
from motion_server.kernel.stop_plan import ramp
from motion_server.scan import statecodec

DT = 0.002
N_AXES = 16
ARRAYS = ("cmd_pos", "cmd_vel", "cmd_acc", "act_x", "act_pos", "act_vel", "drive_on")
MODES = list(ProgrammedStopMode)
PROFILE = compute_profile(
    (0.0, 90.0, 180.0, 270.0, 360.0), (0.0, 0.0, 5.0, 10.0, 10.0), [SegmentType.CUBIC] * 5
)


def configs(modes: list[ProgrammedStopMode]) -> list[AxisConfig]:
    """Virtual axes 1-4, servo axes 5-15 (some rotary, a low Maximum Speed on every third: a
    geared or superimposed velocity beyond it makes the stop steeper), a feedback-only
    axis 16; each axis's programmed stop mode drawn."""
    out = []
    for k in range(N_AXES):
        n = k + 1
        kind = AxisType.VIRTUAL if n <= 4 else AxisType.SERVO
        if n == N_AXES:
            kind = AxisType.FEEDBACK_ONLY
        out.append(
            AxisConfig(
                n,
                f"A{n}",
                kind,
                max_velocity=60.0 if n % 3 == 0 else 1000.0,
                max_acceleration=3000.0 + 100.0 * n,
                max_deceleration=2500.0 + 150.0 * n,
                rollover=360.0 if n % 7 == 0 else 0.0,
                following_error_limit=1e6,
                programmed_stop_mode=modes[k],
            )
        )
    return out


def pair(modes: list[ProgrammedStopMode]) -> tuple[Controller, Controller]:
    out = []
    for lanes in (True, False):
        cfg = configs(modes)
        ctl = Controller(cfg, [GroupConfig(1, "G", tuple(a.number for a in cfg), DT)], lanes)
        for ax in ctl.axes[: N_AXES - 1]:
            ctl.servo_on(ax)
        out.append(ctl)
    return out[0], out[1]


# -- commands: (name, axis, master, value) applied to one controller --------------------
Command = tuple[str, int, int, float]


def apply(ctl: Controller, cmd: Command, started: list[Process], stops: list[Any]) -> str:
    """Apply ``cmd``; what it raised (for both controllers to agree on), or ""."""
    name, n, m, x = cmd
    ax, master = ctl.axes[n], ctl.axes[m]
    lim = Limits(abs(x) + 1.0, 2000.0 + x, 1500.0 + x, 0.0)
    try:
        if name == "jog":
            started.append(
                ctl.start(ax, lambda v, a: JogProcess(DT, x, lim, v, a), (ProcessKind.JOG,))
            )
        elif name == "move":
            started.append(ctl.start(ax, lambda v, a: MoveProcess(DT, x / 3.0, lim, v, a), ()))
        elif name in ("gear", "clutch"):
            ref = MasterReference.COMMAND if x > 0 else MasterReference.ACTUAL
            term = GearTerm(master.number, ref, int(abs(x)) % 7 + 1, 4)
            clutch = RateRamp(1000.0) if name == "clutch" else None

            def make(v: float, a: float) -> GearProcess:
                return GearProcess(ctl, ax, (term,), clutch, v, a)

            if n != m and not ctl.would_cycle(ax.number, (master.number,)):
                started.append(ctl.start(ax, make, (ProcessKind.GEAR,)))
                ctl.coupling_changed()
        elif name == "cam":

            def make_cam(v: float, a: float) -> CamProcess:
                return CamProcess(
                    ctl, PROFILE, CamMode.CONTINUOUS, 1.0, 0.1, 0.0, master=master.index,
                    source=MasterReference.COMMAND, master_number=master.number,
                    lock=LockDirection.IMMEDIATE, rollover=master.config.rollover,
                )  # fmt: skip

            if n != m and not ctl.would_cycle(ax.number, (master.number,)):
                started.append(ctl.start(ax, make_cam, ()))
                ctl.coupling_changed()
        elif name == "mas":
            started.append(ctl.stop(ax, None, 500.0 + abs(x)))
        elif name in ("many", "halts"):
            # MAS (all motion), or MC_Halt (aborting, no jerk), on the moving axes between
            # n and m, in one scan
            halt = name == "halts"
            lo, hi = sorted((n, m))
            axes = [a for a in ctl.axes[lo : hi + 1] if a.active()]
            decels = [400.0 + abs(x) + 50.0 * k for k in range(len(axes))]
            if ctl.lanes_enabled:
                batch = bool(axes) and ctl._stops_as_batch(axes, decels)
                event(f"{'halts' if halt else 'stops'} planned as one batch: {batch}")
            owners = [f"{'MC_Halt' if halt else 'MAS'}{a.number}" for a in axes]
            started.extend(ctl.stop_many(axes, decels, owners, halt=halt))
        elif name == "off":
            ctl.servo_off(ax)
        elif name == "on":
            ctl.servo_on(ax)
        elif name == "mgs":
            forced = None if x < 0 else MODES[int(x) % len(MODES)]
            stops.append(ctl.group_stop(1, forced, owner="MGS"))
        elif name == "mgsd":
            ctl.group_shutdown(1)
        elif name == "program":
            stops.extend(ctl.set_mode(OperatingMode.PROGRAM))
            ctl.set_mode(OperatingMode.RUN)
    except MotionError as exc:
        return f"{exc.code}"
    return ""


def process_state(p: Process) -> tuple[Any, ...]:
    """What a process is: its kind, state and kinematics; a stop ramp's limits and
    profile too (the lanes' bookkeeping, ``lane`` and ``offer_pending``, left out)."""
    if p.lane is not None:
        p.lane.sync(p)
    out: tuple[Any, ...] = (
        type(p).__name__,
        p.state,
        p.abort_reason,
        p.error_code,
        p.position,
        p.velocity,
        p.acceleration,
        p.stopping,
        p.owner,
    )
    if isinstance(p, StopRamp):
        out += (p.limits, vars(p.profile))
    return out


def assert_same(fast: Controller, ref: Controller, fp: list[Process], rp: list[Process],
                fs: list[Any], rs: list[Any], where: str) -> None:  # fmt: skip
    for name in ARRAYS:
        a, b = getattr(fast, name), getattr(ref, name)
        assert np.array_equal(a, b), f"{where}: {name}"
    for x, y in zip(fast.status_arrays(), ref.status_arrays(), strict=True):
        assert np.array_equal(x, y), where
    for af, ar in zip(fast.axes, ref.axes, strict=True):
        assert (af.state, af.base, af.after_stop, af.stop_latch is None, af.buffered) == (
            ar.state, ar.base, ar.after_stop, ar.stop_latch is None, ar.buffered,
        ), f"{where}: {af.name}"  # fmt: skip
        assert [process_state(p) for p in af.processes] == [
            process_state(p) for p in ar.processes
        ], f"{where}: {af.name} processes"
    assert [process_state(p) for p in fp] == [process_state(p) for p in rp], where
    assert [(s.initiated, s.complete) for s in fs] == [(s.initiated, s.complete) for s in rs]
    assert fast.groups[0].after_stops == ref.groups[0].after_stops, where


NAMES = ("jog", "jog", "jog", "move", "gear", "gear", "clutch", "cam", "mas", "off", "on")
STOPS = ("mgs", "mgs", "mgs", "program", "mgsd")


def command(names: tuple[str, ...]) -> st.SearchStrategy[Command]:
    return st.tuples(
        st.sampled_from(names),
        st.integers(0, N_AXES - 1),
        st.integers(0, N_AXES - 1),
        st.one_of(
            st.sampled_from([-1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 50.0, -80.0, 150.0]),
            st.floats(-300.0, 300.0, allow_nan=False),
        ),
    )


def run_side_by_side(
    modes: list[ProgrammedStopMode],
    before: list[tuple[list[Command], int]],
    stop: Command,
    after: list[tuple[list[Command], int]],
) -> None:
    """Random motion (commands issued in the same scan, then cycles), the stop (with the
    commands of its scan after it), then more commands and cycles until all rest; both
    controllers compared after every command batch and every cycle."""
    fast, ref = pair(modes)
    fp: list[Process] = []
    rp: list[Process] = []
    fs: list[Any] = []
    rs: list[Any] = []
    script = [*before, ([stop], 0), *after, ([], 150)]
    for i, (cmds, cycles) in enumerate(script):
        if i == len(before):
            laned = sum(p.lane is not None for ax in fast.axes for p in ax.processes)
            event(f"processes in a lane when the stop comes: {laned if laned < 3 else '3 or more'}")
            on = all(ax.servo_on for ax in fast.axes[: N_AXES - 1])
            event(f"every driven axis in Servo Control when the stop comes: {on}")
        for cmd in cmds:
            assert apply(fast, cmd, fp, fs) == apply(ref, cmd, rp, rs), f"{i}: {cmd}"
        assert_same(fast, ref, fp, rp, fs, rs, f"after the commands of step {i}")
        # every process on an axis now (the stop ramps too) is followed to its end
        for ctl, procs in ((fast, fp), (ref, rp)):
            seen = {id(p) for p in procs}
            procs.extend(p for ax in ctl.axes for p in ax.processes if id(p) not in seen)
        for k in range(cycles + 1):
            fast.step()
            ref.step()
            assert_same(fast, ref, fp, rp, fs, rs, f"step {i} ({cmds}), cycle {k}")


def scans(names: tuple[str, ...], most: int) -> st.SearchStrategy[list[tuple[list[Command], int]]]:
    return st.lists(
        st.tuples(st.lists(command(names), min_size=1, max_size=8), st.integers(0, 40)),
        min_size=1,
        max_size=most,
    )


@settings(max_examples=150, deadline=None)
@given(
    modes=st.lists(st.sampled_from(MODES), min_size=N_AXES, max_size=N_AXES),
    before=scans(NAMES, 4),
    stop=command(STOPS),
    after=st.lists(st.tuples(st.lists(command(NAMES), max_size=3), st.integers(1, 40)),
                   max_size=3),
)  # fmt: skip
def test_a_group_stop_planned_as_arrays_equals_the_stop_axis_by_axis(
    modes: list[ProgrammedStopMode],
    before: list[tuple[list[Command], int]],
    stop: Command,
    after: list[tuple[list[Command], int]],
) -> None:
    run_side_by_side(modes, before, stop, after)


#: commands that leave every axis in Servo Control
MOVING = tuple(n for n in NAMES if n not in ("off", "on"))


@settings(max_examples=100, deadline=None)
@given(
    mode=st.sampled_from(MODES),
    before=scans(MOVING, 3),
    forced=st.sampled_from([-1.0, 0.0, 1.0, 2.0, 3.0, 4.0]),
    program=st.booleans(),
    after=st.lists(st.tuples(st.lists(command(MOVING), max_size=3), st.integers(1, 40)),
                   max_size=2),
)  # fmt: skip
def test_a_group_in_servo_control_stops_in_one_batch_as_axis_by_axis(
    mode: ProgrammedStopMode,
    before: list[tuple[list[Command], int]],
    forced: float,
    program: bool,
    after: list[tuple[list[Command], int]],
) -> None:
    """Every axis in Servo Control with one programmed stop mode, the stop forced to any
    mode or programmed (MGS), or leaving run mode: the group is stopped in one batch
    (ramps, or every drive off at once for Hard Disable and Hard Shutdown)."""
    stop = ("program", 0, 0, 0.0) if program else ("mgs", 0, 0, forced)
    run_side_by_side([mode] * N_AXES, before, stop, after)


@settings(max_examples=150, deadline=None)
@given(
    before=scans(MOVING, 4),
    stop=command(("many", "halts")),
    after=st.lists(st.tuples(st.lists(command(NAMES), max_size=3), st.integers(1, 40)),
                   max_size=3),
)  # fmt: skip
def test_stops_of_many_axes_in_one_call_equal_the_stops_one_by_one(
    before: list[tuple[list[Command], int]],
    stop: Command,
    after: list[tuple[list[Command], int]],
) -> None:
    """MAS stopping all motion on many axes in one scan (``Controller.stop_many``, one
    batch with the lanes) against ``Controller.stop`` axis by axis (the reference), and
    MC_Halt halting them (``stop_many`` with ``halt``) against MC_Halt's ``start`` of a
    ramp that is not Stopping, axis by axis: the same ramps, owners and state, bit for
    bit, after every cycle."""
    run_side_by_side([ProgrammedStopMode.FAST_STOP] * N_AXES, before, stop, after)


def test_the_planned_ramp_is_the_constructed_ramp() -> None:
    """:func:`ramp` sets the attributes ``StopRamp.__init__`` sets, to the same values."""
    for v, d in ((100.0, 2000.0), (-3.5, 10.0), (1e-12, 5.0), (-0.0, 1.0)):
        built = ramp(DT, d, v, "owner")
        if v == 0.0:
            built.finish()  # from rest, nothing inherited: the caller finishes it
        made = StopRamp(DT, d, 0.0, v, 0.0, owner="owner")
        a, b = dict(vars(built)), dict(vars(made))
        assert vars(a.pop("profile")) == vars(b.pop("profile"))
        assert a == b


def test_a_group_stop_with_the_lanes_builds_no_ramp_axis_by_axis(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The point of the batch: with the lanes, a group stop of 14 jogging axes neither
    calls the ramp's constructor nor Controller.stop once (the reference does both per
    jogging axis), and every ramp joins the stop lane."""
    fast, ref = pair([ProgrammedStopMode.FAST_STOP] * N_AXES)
    for ctl in (fast, ref):
        for ax in ctl.axes[: N_AXES - 2]:
            ctl.start(ax, lambda v, a: JogProcess(DT, 50.0, Limits(50.0, 5e3, 5e3), v, a))
        ctl.run(20)
    calls: list[str] = []
    init: Callable[..., None] = StopRamp.__init__
    stop = Controller.stop

    def counted_init(self: StopRamp, *args: Any, **kwargs: Any) -> None:
        calls.append("init")
        init(self, *args, **kwargs)

    def counted_stop(self: Controller, *args: Any, **kwargs: Any) -> StopRamp:
        calls.append("stop")
        return stop(self, *args, **kwargs)

    monkeypatch.setattr(StopRamp, "__init__", counted_init)
    monkeypatch.setattr(Controller, "stop", counted_stop)
    fast.group_stop(1, ProgrammedStopMode.FAST_STOP)
    assert calls == []
    ref.group_stop(1, ProgrammedStopMode.FAST_STOP)
    # the jogging axes: the servo or virtual axis at rest has nothing to stop (no ramp
    # from rest), the feedback-only one is not stopped
    assert calls.count("stop") == N_AXES - 2
    fast.step()
    ref.step()
    ramps = [ax.processes[0] for ax in fast.axes[: N_AXES - 2]]
    assert all(r.lane is fast.motion.lanes[1].stops for r in ramps)
    assert np.array_equal(fast.cmd_pos, ref.cmd_pos)


def test_a_ramp_the_batch_would_refuse_is_refused_as_axis_by_axis() -> None:
    """A stop longer than any profile (Maximum Speed / Maximum Deceleration beyond
    7,600 s) is refused (PROFILE_FAILED) by both paths alike, leaving the same state."""
    out = []
    for lanes in (True, False):
        cfg = [
            AxisConfig(n, f"A{n}", AxisType.VIRTUAL, max_velocity=1e6, max_deceleration=1e-3)
            for n in range(1, 11)
        ]
        ctl = Controller(cfg, [GroupConfig(1, "G", tuple(range(1, 11)), DT)], lanes)
        for ax in ctl.axes:
            ctl.servo_on(ax)
            ctl.start(ax, lambda v, a: JogProcess(DT, 20.0, Limits(20.0, 1e4, 1e4), v, a))
        ctl.run(5)
        with pytest.raises(MotionError) as exc:
            ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
        out.append((exc.value.code, [[process_state(p) for p in ax.processes] for ax in ctl.axes]))
    assert out[0] == out[1]


# -- ramps left as rows, their objects made when read -----------------------------------
def assert_same_unread(fast: Controller, ref: Controller, fs: list[Any], rs: list[Any],
                       where: str) -> None:  # fmt: skip
    """:func:`assert_same` without reading any axis's processes (which would make the
    ramps the stop left as rows): the arrays, the status, the axes' other state and the
    stops."""
    for name in ARRAYS:
        assert np.array_equal(getattr(fast, name), getattr(ref, name)), f"{where}: {name}"
    for x, y in zip(fast.status_arrays(), ref.status_arrays(), strict=True):
        assert np.array_equal(x, y), where
    for af, ar in zip(fast.axes, ref.axes, strict=True):
        assert (af.state, af.base, af.after_stop, af.stop_latch is None, af.buffered) == (
            ar.state, ar.base, ar.after_stop, ar.stop_latch is None, ar.buffered,
        ), f"{where}: {af.name}"  # fmt: skip
    assert [(s.initiated, s.complete) for s in fs] == [(s.initiated, s.complete) for s in rs]
    assert fast.groups[0].after_stops == ref.groups[0].after_stops, where


@settings(max_examples=150, deadline=None)
@given(
    modes=st.lists(st.sampled_from(MODES), min_size=N_AXES, max_size=N_AXES),
    before=scans(NAMES, 4),
    stop=command(STOPS),
    after=st.lists(st.tuples(st.lists(command(NAMES), max_size=3), st.integers(1, 40)),
                   max_size=3),
    reads=st.lists(st.integers(0, 200), max_size=4),
    peeks=st.lists(st.tuples(st.integers(0, 200), st.integers(0, N_AXES - 1)), max_size=6),
)  # fmt: skip
def test_ramps_made_when_read_at_random_moments_equal_the_stop_axis_by_axis(
    modes: list[ProgrammedStopMode],
    before: list[tuple[list[Command], int]],
    stop: Command,
    after: list[tuple[list[Command], int]],
    reads: list[int],
    peeks: list[tuple[int, int]],
) -> None:
    """As above, but the processes are read only at random moments (``reads``: every
    axis's, ``peeks``: one axis's, counted in cycles after the stop), so that the ramps
    the stop left as rows of the stop lane are stepped, brought to rest, or made (and
    then stepped as objects in the lane, or moved out by a command) at any point; the
    arrays, the status and the axes agree after every command and every cycle, the
    processes whenever they are read, and everything at the end."""
    fast, ref = pair(modes)
    fp: list[Process] = []
    rp: list[Process] = []
    fs: list[Any] = []
    rs: list[Any] = []
    script = [*before, ([stop], 0), *after, ([], 150)]
    cycle = 0  # cycles since the stop
    stopped = False
    rowed = 0
    for i, (cmds, cycles) in enumerate(script):
        for cmd in cmds:
            assert apply(fast, cmd, fp, fs) == apply(ref, cmd, rp, rs), f"{i}: {cmd}"
        if i == len(before):
            stopped = True
            rowed = sum(len(r) for r in fast.motion.lanes[1].stops.rows)
            event(f"ramps left as rows by the stop: {min(rowed, 5)}")
        if not stopped:
            assert_same(fast, ref, fp, rp, fs, rs, f"after the commands of step {i}")
            for ctl, procs in ((fast, fp), (ref, rp)):
                seen = {id(p) for p in procs}
                procs.extend(p for ax in ctl.axes for p in ax.processes if id(p) not in seen)
        else:
            assert_same_unread(fast, ref, fs, rs, f"after the commands of step {i}")
        for k in range(cycles + 1):
            fast.step()
            ref.step()
            where = f"step {i} ({cmds}), cycle {k}"
            if stopped:
                cycle += 1
                assert_same_unread(fast, ref, fs, rs, where)
                for at, n in peeks:
                    if at == cycle:
                        assert [process_state(p) for p in fast.axes[n].processes] == [
                            process_state(p) for p in ref.axes[n].processes
                        ], f"{where}: axis {n} read"
                if cycle in reads:
                    assert_same(fast, ref, fp, rp, fs, rs, f"{where}: read")
            else:
                assert_same(fast, ref, fp, rp, fs, rs, where)
    assert_same(fast, ref, fp, rp, fs, rs, "at the end")


def test_a_group_stop_leaves_its_ramps_as_rows_until_they_are_read() -> None:
    """The design's point: after a Fast Stop of 14 jogging axes the stop lane holds 14
    rows and no ramp object exists until an axis's processes are read; reading one
    makes that ramp alone, a member of the stop lane, where it stays."""
    fast, ref = pair([ProgrammedStopMode.FAST_STOP] * N_AXES)
    for ctl in (fast, ref):
        for ax in ctl.axes[: N_AXES - 2]:
            ctl.start(ax, lambda v, a: JogProcess(DT, 50.0, Limits(50.0, 5e3, 5e3), v, a))
        ctl.run(20)
        ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
        ctl.run(3)
    stops = fast.motion.lanes[1].stops
    assert [len(r) for r in stops.rows] == [N_AXES - 2]
    assert all(ax.stop_rows is not None for ax in fast.axes[: N_AXES - 2])
    (made,) = fast.axes[4].processes
    assert made.lane is stops and fast.axes[4].stop_rows is None
    assert sum(ax.stop_rows is not None for ax in fast.axes) == N_AXES - 3
    assert process_state(made) == process_state(ref.axes[4].processes[0])
    fast.run(2)
    ref.run(2)
    assert made.lane is stops  # read, not moved out: still stepped by the lane
    assert process_state(made) == process_state(ref.axes[4].processes[0])
    assert np.array_equal(fast.cmd_pos, ref.cmd_pos)


def test_ramps_left_as_rows_round_trip_through_a_snapshot() -> None:
    """A snapshot taken while a group stop's ramps are rows (one of them made) runs on
    as the original and as the reference: the rows, the made ramp and its place in the
    lane survive the copy."""
    fast, ref = pair([ProgrammedStopMode.FAST_STOP] * N_AXES)
    for ctl in (fast, ref):
        for ax in ctl.axes[: N_AXES - 2]:
            ctl.start(ax, lambda v, a: JogProcess(DT, 80.0, Limits(80.0, 5e3, 5e3), v, a))
        ctl.run(20)
        ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
        ctl.run(3)
    made = fast.axes[2].processes[0]
    copy = statecodec.loads(statecodec.dumps(fast))
    assert [len(r) for r in copy.motion.lanes[1].stops.rows] == [N_AXES - 2]
    (copied,) = copy.axes[2].processes
    assert copied is not made and copied.lane is copy.motion.lanes[1].stops
    for k in range(40):
        for ctl in (fast, copy, ref):
            ctl.step()
        assert_same_unread(copy, ref, [], [], f"cycle {k}")
        assert_same_unread(fast, ref, [], [], f"cycle {k}")
    assert_same(copy, ref, [], [], [], [], "at the end")
    assert process_state(copied) == process_state(made)
    assert not copy.motion.lanes[1].stops.rows


def test_the_members_a_group_stop_evicts_are_freed_over_the_next_steps() -> None:
    """64 jogs evicted by a group stop are not freed in the first step after it (the
    cycle that executes the stop) but within the next few, 32 a step."""
    cfg = [
        AxisConfig(n, f"A{n}", AxisType.VIRTUAL, max_velocity=1000.0, max_deceleration=1e4)
        for n in range(1, 65)
    ]
    ctl = Controller(cfg, [GroupConfig(1, "G", tuple(range(1, 65)), DT)], True)
    for ax in ctl.axes:
        ctl.servo_on(ax)
        ctl.start(ax, lambda v, a: JogProcess(DT, 20.0, Limits(20.0, 1e4, 1e4), v, a))
    ctl.run(5)
    jogs = [weakref.ref(ax.processes[0]) for ax in ctl.axes]
    ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
    gc.collect()
    ctl.step()
    assert sum(r() is not None for r in jogs) == 64
    ctl.step()
    assert sum(r() is not None for r in jogs) == 32
    ctl.step()
    assert all(r() is None for r in jogs)


@pytest.mark.parametrize("second", ["mgs", "program"])
def test_a_second_group_stop_while_the_rows_ramp_equals_the_reference(second: str) -> None:
    """A group stop commanded while the ramps of the first are still rows (none read)
    replaces them as the reference replaces the first ramps: the same state after
    every cycle."""
    fast, ref = pair([ProgrammedStopMode.FAST_STOP] * N_AXES)
    procs: tuple[list[Process], list[Process]] = ([], [])
    stops: tuple[list[Any], list[Any]] = ([], [])
    for ctl, ps, ss in ((fast, procs[0], stops[0]), (ref, procs[1], stops[1])):
        for k in range(N_AXES - 2):
            apply(ctl, ("jog", k, 0, 40.0 + 7.0 * k), ps, ss)
        ctl.run(10)
        apply(ctl, ("mgs", 0, 0, 0.0), ps, ss)
        ctl.run(3)
    assert sum(len(r) for r in fast.motion.lanes[1].stops.rows) == N_AXES - 2
    for ctl, ps, ss in ((fast, procs[0], stops[0]), (ref, procs[1], stops[1])):
        apply(ctl, (second, 0, 0, 1.0), ps, ss)
    for k in range(60):
        fast.step()
        ref.step()
        assert_same_unread(fast, ref, stops[0], stops[1], f"cycle {k}")
    assert_same(fast, ref, procs[0], procs[1], stops[0], stops[1], "at the end")


def test_a_group_stop_makes_no_ramp_for_an_axis_with_nothing_to_stop() -> None:
    """An MGS of a group whose axes are mostly at rest (the group stopped before, a few
    axes started again): the axes at rest keep no process (a ramp from rest would be done
    at once and move nothing), are held Stopping by the stop's latch until its first
    update and keep their positions; the jogging ones ramp to rest. Both paths alike."""
    stopping = 1 << MotionStatusBit.STOPPING
    for ctl in pair([ProgrammedStopMode.FAST_STOP] * N_AXES):
        jogging = ctl.axes[:2]
        for ax in jogging:
            ctl.start(ax, lambda v, a: JogProcess(DT, 50.0, Limits(50.0, 5e3, 5e3), v, a))
        ctl.run(20)
        at_rest = ctl.axes[2 : N_AXES - 1]
        held = [ax.command_position for ax in at_rest]
        handle = ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
        for ax in at_rest:
            assert ax.processes == [] and ax.stop_latch is handle
            assert ax.motion_status & stopping
            assert ax.plcopen_state == PLCopenState.STOPPING
        assert all(ax.processes[0].kind == ProcessKind.STOP for ax in jogging)
        ctl.step()
        for ax, position in zip(at_rest, held, strict=True):
            assert ax.stop_latch is None and not ax.motion_status & stopping
            assert ax.plcopen_state == PLCopenState.STANDSTILL
            assert ax.command_position == position and ax.command_velocity == 0.0
        # 50 mm/s at 2,650 and 2,800 mm/s² (5.3 and 5.6 mm/s a period of 2 ms): at rest
        # in the 10th period (50 / 5.3 = 9.4) and the 9th (8.9)
        ctl.run(8)
        assert jogging[0].command_velocity > 0.0 and jogging[1].command_velocity == 0.0
        assert not handle.complete
        ctl.step()
        assert jogging[0].command_velocity == 0.0 and handle.complete


def whole_group_pair(n: int) -> tuple[Controller, Controller]:
    """Two controllers (lanes, reference) of ``n`` driven axes in one group, none
    feedback-only: a group stop's rows then stop every axis of the group."""
    out = []
    for lanes in (True, False):
        cfg = [c for c in configs([ProgrammedStopMode.FAST_STOP] * N_AXES)][:n]
        ctl = Controller(cfg, [GroupConfig(1, "G", tuple(a.number for a in cfg), DT)], lanes)
        for ax in ctl.axes:
            ctl.servo_on(ax)
        out.append(ctl)
    return out[0], out[1]


@pytest.mark.parametrize("jog_at", [None, 0, 1, 5])
def test_a_stop_of_the_whole_group_leaves_nothing_to_python_until_a_ramp_is_replaced(
    jog_at: int | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After a Fast Stop of a group whose every axis jogged in a lane, the lanes are
    empty and the stop's rows hold every axis: the first step's rebuild leaves no axis
    to Python, and levels no follower (``GroupLanes._emptied``). A jog that replaces
    one ramp (in the stop's scan, ``jog_at`` 0, or later) is composed again, as in the
    reference; the two agree after every cycle."""
    n = 8
    fast, ref = whole_group_pair(n)
    fs: list[Any] = []
    rs: list[Any] = []
    jogs: tuple[list[Process], list[Process]] = ([], [])
    for ctl in (fast, ref):
        for k in range(n):
            apply(ctl, ("jog", k, 0, 30.0 + 5.0 * k), [], [])
        ctl.run(20)
    lanes = fast.motion.lanes[1]
    assert sum(len(lane.members) for lane in lanes.all) == n  # every jog in a lane
    for ctl, ss in ((fast, fs), (ref, rs)):
        apply(ctl, ("mgs", 0, 0, 0.0), [], ss)

    def levelled(*args: object) -> None:
        raise AssertionError("the followers levelled after a stop that emptied the lanes")

    for k in range(80):
        if k == jog_at:
            for ctl, ps, ss in ((fast, jogs[0], fs), (ref, jogs[1], rs)):
                apply(ctl, ("jog", 3, 0, -20.0), ps, ss)
        with monkeypatch.context() as m:
            if k == 0 and jog_at != 0:
                m.setattr(lanes, "_order_command_followers", levelled)
            fast.step()
        ref.step()
        if k == 0 and jog_at != 0:
            assert lanes.python_order == []
            assert [len(r.axes) for r in lanes.stops.rows] == [n]
        if jog_at is not None and k >= jog_at:
            assert fast.axes[3] in lanes.python_order or jogs[0][0].lane is not None
        assert_same_unread(fast, ref, fs, rs, f"cycle {k}")
    if jog_at is not None:
        assert process_state(jogs[0][0]) == process_state(jogs[1][0])
        assert fast.cmd_vel[3] == ref.cmd_vel[3] == -20.0
