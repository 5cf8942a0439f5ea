"""A group stop whose axes each have one process stepped in a fast lane (the common case:
jogs at speed, locked gears, moves and ramps on their way) is planned from the
controller's arrays (:func:`motion_server.kernel.stop_plan.stop_axes`): what each ramp
inherits and each axis's new base come from the command the last step wrote, the
emptied lanes are cleared at once, the composition order is kept. None of this may
change anything but speed: a controller with the lanes and one without
(``lanes=False``, the stop axis by axis), given the same one process per axis, the
same commands in the stop's scan and the same stop, agree bit for bit after every
cycle on every array and every axis, and on every process whenever it is read (at
random moments, so that the stop's ramps are made from their rows at any point)."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import event, given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    JogProcess,
    Limits,
    ProgrammedStopMode,
)
from motion_server.kernel.appl_limits import Limit, set_application_limit
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterReference
from motion_server.kernel.processes import Process

from .test_stop_plan import (
    DT,
    MODES,
    Command,
    apply,
    assert_same,
    assert_same_unread,
    process_state,
)

N = 12
#: what each axis runs before the stop: one process each (and now and then, on one axis,
#: a MAS ramp, which keeps the batch off the arrays' path, or a cam)
KINDS = ("jog",) * 4 + ("move", "gear", "gear", "gear", "clutch")


def configs(feedback: bool) -> list[AxisConfig]:
    """Virtual axes 1-3, servo axes after them (a low Maximum Speed on every third: a
    geared velocity beyond it makes the stop steeper; every fifth rotary), optionally a
    feedback-only axis last (then the order is sorted again after the stop)."""
    out = []
    for k in range(N):
        n = k + 1
        kind = AxisType.VIRTUAL if n <= 3 else AxisType.SERVO
        if feedback and n == N:
            kind = AxisType.FEEDBACK_ONLY
        out.append(
            AxisConfig(
                n, f"A{n}", kind,
                max_velocity=60.0 if n % 3 == 0 else 1000.0,
                max_acceleration=3000.0 + 100.0 * n,
                max_deceleration=2500.0 + 150.0 * n,
                rollover=360.0 if n % 5 == 0 else 0.0,
                following_error_limit=1e6,
                programmed_stop_mode=ProgrammedStopMode.FAST_STOP,
            )
        )  # fmt: skip
    return out


def pair(feedback: bool) -> tuple[Controller, Controller]:
    out = []
    for lanes in (True, False):
        cfg = configs(feedback)
        ctl = Controller(cfg, [GroupConfig(1, "G", tuple(a.number for a in cfg), DT)], lanes)
        for ax in ctl.axes:
            if ax.type != AxisType.FEEDBACK_ONLY:
                ctl.servo_on(ax)
        out.append(ctl)
    return out[0], out[1]


def one_each(kinds: list[str], masters: list[int], values: list[float]) -> list[Command]:
    """One command per axis: masters are the axes before it (no loops)."""
    out: list[Command] = []
    for k in range(N):
        kind = kinds[k]
        if kind in ("gear", "clutch", "cam") and k == 0:
            kind = "jog"
        out.append((kind, k, masters[k] % max(k, 1), values[k]))
    return out


def stopped_by_arrays(ctl: Controller) -> bool:
    """The stop took the arrays' path: the lanes it emptied are cleared (no member, no
    rebuild pending), every axis's ramp a row."""
    lanes = ctl.motion.lanes[1]
    return bool(lanes.stops.rows) and not any(lane.members or lane.changed for lane in lanes.all)


@settings(max_examples=200, deadline=None)
@given(
    kinds=st.lists(st.sampled_from(KINDS), min_size=N, max_size=N),
    masters=st.lists(st.integers(0, N), min_size=N, max_size=N),
    values=st.lists(
        st.one_of(
            st.sampled_from([1.0, 3.0, 50.0, -80.0, 150.0, 0.0]),
            st.floats(1.5, 300.0),
            st.floats(-300.0, -1.5),
        ),
        min_size=N,
        max_size=N,
    ),
    odd=st.one_of(st.none(), st.tuples(st.sampled_from(("mas", "cam")), st.integers(0, N - 1))),
    settle=st.sampled_from([0, 1, 2, 5, 30, 30, 200, 200]),
    feedback=st.booleans(),
    same_scan=st.one_of(
        st.just([]),
        st.lists(
            st.tuples(
                st.sampled_from(("jog", "mas", "gear", "off")),
                st.integers(0, N - 1),
                st.integers(0, N - 1),
                st.floats(-100.0, 100.0, allow_nan=False),
            ),
            max_size=2,
        ),
    ),
    stop=st.one_of(
        st.tuples(
            st.just("mgs"), st.just(0), st.just(0), st.sampled_from([-1.0, 0.0, 1.0, 2.0, 3.0, 4.0])
        ),
        st.just(("program", 0, 0, 0.0)),
    ),
    reads=st.lists(st.integers(0, 120), max_size=3),
    peeks=st.lists(st.tuples(st.integers(0, 120), st.integers(0, N - 1)), max_size=4),
)  # fmt: skip
def test_a_group_stop_of_lane_members_equals_the_stop_axis_by_axis(
    kinds: list[str],
    masters: list[int],
    values: list[float],
    odd: tuple[str, int] | None,
    settle: int,
    feedback: bool,
    same_scan: list[Command],
    stop: Command,
    reads: list[int],
    peeks: list[tuple[int, int]],
) -> None:
    fast, ref = pair(feedback)
    fp: list[Process] = []
    rp: list[Process] = []
    fs: list[Any] = []
    rs: list[Any] = []
    if odd is not None:
        kinds = [odd[0] if k == odd[1] else kind for k, kind in enumerate(kinds)]
    commands = one_each(kinds, masters, values)
    if feedback:
        commands = commands[:-1]
    for cmd in commands:
        assert apply(fast, cmd, fp, fs) == apply(ref, cmd, rp, rs), cmd
    for _ in range(settle):
        fast.step()
        ref.step()
    assert_same(fast, ref, fp, rp, fs, rs, "before the stop")
    for ctl, procs in ((fast, fp), (ref, rp)):
        seen = {id(p) for p in procs}
        procs.extend(p for ax in ctl.axes for p in ax.processes if id(p) not in seen)
    # commands in the stop's scan, before it (they take their axes out of the lanes)
    for cmd in [*same_scan, stop]:
        if cmd[0] in ("gear",) and cmd[2] >= cmd[1]:
            continue  # masters before their slaves (no loops)
        assert apply(fast, cmd, fp, fs) == apply(ref, cmd, rp, rs), cmd
    lanes = fast.motion.lanes[1]
    event(f"the stop left no lane to rebuild: {not any(lane.changed for lane in lanes.all)}")
    assert_same_unread(fast, ref, fs, rs, "after the stop")
    for cycle in range(1, 121):
        fast.step()
        ref.step()
        where = f"cycle {cycle} after the stop"
        assert_same_unread(fast, ref, fs, rs, where)
        assert np.array_equal(fast.cmd_vel, ref.cmd_vel), where
        for at, n in peeks:
            if at == cycle:
                assert [process_state(p) for p in fast.axes[n].processes] == [
                    process_state(p) for p in ref.axes[n].processes
                ], f"{where}: axis {n} read"
        if cycle in reads:
            assert_same(fast, ref, fp, rp, fs, rs, f"{where}: read")
    assert_same(fast, ref, fp, rp, fs, rs, "at the end")


def jogging_pair(feedback: bool = False) -> tuple[Controller, Controller, list[list[Process]]]:
    """Every driven axis jogging at its own speed, the jogs at speed in the cruise lane
    (and, with ``feedback``, a feedback-only axis in the group)."""
    fast, ref = pair(feedback)
    jogs: list[list[Process]] = [[], []]
    for ctl, started in ((fast, jogs[0]), (ref, jogs[1])):
        for ax in ctl.axes:
            if ax.type == AxisType.FEEDBACK_ONLY:
                continue
            speed = 10.0 + 3.0 * ax.index

            def make(v: float, a: float, speed: float = speed) -> JogProcess:
                return JogProcess(DT, speed, Limits(speed, 5e3, 5e3), v, a)

            started.append(ctl.start(ax, make))
        ctl.run(30)
    return fast, ref, jogs


def test_a_group_stop_of_lane_members_leaves_no_lane_to_rebuild() -> None:
    """The stop empties the lanes at once: after the command no lane holds a member or
    waits for a rebuild (before, the first step rebuilt each emptied lane field by
    field), and the jogs it aborted are in their final state, as the reference's."""
    fast, ref, jogs = jogging_pair()
    lanes = fast.motion.lanes[1]
    assert len(lanes.cruise.members) == N
    fast.group_stop(1, ProgrammedStopMode.FAST_STOP)
    ref.group_stop(1, ProgrammedStopMode.FAST_STOP)
    assert not any(lane.members or lane.changed for lane in lanes.all)
    assert all(p.lane is None for p in jogs[0])
    assert [process_state(p) for p in jogs[0]] == [process_state(p) for p in jogs[1]]
    assert [ax.base for ax in fast.axes] == [ax.base for ax in ref.axes]
    fast.step()
    ref.step()
    assert np.array_equal(fast.cmd_pos, ref.cmd_pos)


def test_the_order_is_kept_when_the_rows_hold_the_whole_group() -> None:
    """Rows on every axis of the group: nothing reads a master, so the composition order
    is the group's axes as configured, already the order kept: nothing is sorted again
    (with a feedback-only axis in the group, outside the rows, it is)."""
    fast, ref, _ = jogging_pair()
    g = fast.groups[0]
    order = g.order
    fast.group_stop(1, ProgrammedStopMode.FAST_STOP)
    assert not fast.motion.order_dirty
    assert g.order is order and order == g.axes
    fed, _, _ = jogging_pair(feedback=True)
    fed.group_stop(1, ProgrammedStopMode.FAST_STOP)
    assert fed.motion.order_dirty
    for ctl in (fast, ref):
        if ctl is ref:
            ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
        ctl.run(5)
    assert [ax.number for ax in g.order] == [ax.number for ax in ref.groups[0].order]
    assert np.array_equal(fast.cmd_pos, ref.cmd_pos)


def test_the_composition_order_puts_masters_first_and_keeps_the_rest() -> None:
    """``Motion.sort``: with no process reading a master (every axis jogging), the order is
    the group's axes as configured; a gear on axis 1 reading axis 3 puts axis 3 first and
    keeps the others in their configured order (3, 1, 2, 4, ...), as a depth-first visit
    of the masters gives it."""
    fast, _, _ = jogging_pair()
    g = fast.groups[0]
    fast.motion.sort()
    assert g.order == g.axes
    slave, master = fast.axes[0], fast.axes[2]
    term = GearTerm(master.number, MasterReference.COMMAND, 1, 2)
    fast.start(slave, lambda v, a: GearProcess(fast, slave, (term,), None, v, a), None)
    fast.motion.sort()
    numbers = [ax.number for ax in g.axes]
    assert [ax.number for ax in g.order] == [3, 1, 2, *numbers[3:]]


def test_commands_in_the_stops_scan_keep_it_off_the_arrays_path() -> None:
    """A jog commanded on one axis in the stop's scan, before the stop, takes that axis
    out of its lane: its command no longer is its processes' sum, so the stop sums the
    processes axis by axis, as the reference."""
    fast, ref, jogs = jogging_pair()
    for ctl, started in ((fast, jogs[0]), (ref, jogs[1])):
        apply(ctl, ("jog", 4, 0, -70.0), started, [])
        ctl.group_stop(1, MODES[0])
    assert not stopped_by_arrays(fast)
    for k in range(80):
        fast.step()
        ref.step()
        assert_same_unread(fast, ref, [], [], f"cycle {k}")
    assert_same(fast, ref, jogs[0], jogs[1], [], [], "at the end")


def test_a_limit_changed_at_run_time_is_the_one_the_stop_ramps_at() -> None:
    """The group keeps its axes' maximum decelerations and velocities as arrays: an
    application limit written at run time (MC_WriteParameter) replaces an axis's
    configuration, and the next group stop ramps at the new limit, as the reference."""
    fast, ref, jogs = jogging_pair()
    for ctl in (fast, ref):
        set_application_limit(ctl.axes[2], Limit.DECELERATION, 700.0)
        set_application_limit(ctl.axes[7], Limit.VELOCITY, 20.0)  # below its jog's speed
        ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)
    assert stopped_by_arrays(fast)
    for k in range(120):
        fast.step()
        ref.step()
        assert_same_unread(fast, ref, [], [], f"cycle {k}")
    assert_same(fast, ref, jogs[0], jogs[1], [], [], "at the end")


def test_a_hard_disable_of_lane_members_switches_the_group_off_in_one_batch() -> None:
    """Hard Disable of jogging axes, then a Fast Disable's drives switched off once the
    group is at rest: the lanes are emptied at once, the jogs aborted and the axes in
    Axis Ready with their status as the reference's, after every cycle."""
    for mode in (ProgrammedStopMode.HARD_DISABLE, ProgrammedStopMode.FAST_DISABLE):
        fast, ref, jogs = jogging_pair()
        lanes = fast.motion.lanes[1]
        for ctl in (fast, ref):
            ctl.group_stop(1, mode)
        assert not any(lane.members or lane.changed for lane in lanes.all)
        assert_same(fast, ref, jogs[0], jogs[1], [], [], f"{mode.name}: after the stop")
        for k in range(150):
            fast.step()
            ref.step()
            assert_same_unread(fast, ref, [], [], f"{mode.name}: cycle {k}")
        assert not fast.drive_on.any()
        assert_same(fast, ref, jogs[0], jogs[1], [], [], f"{mode.name}: at the end")


def test_a_hard_shutdown_releases_followers_as_axis_by_axis() -> None:
    """Hard Shutdown of a group where gears follow masters shut down before them (whose
    release gives them a stop ramp, aborted at once by their own shutdown) and masters
    shut down after them: in one batch, the same processes, bases and status as axis
    by axis, whatever signed zeros the ramps fold into the bases."""
    fast, ref = pair(False)
    fp: list[Process] = []
    rp: list[Process] = []
    # axes 1-3 jog (one backwards, one at rest); 4-7 follow 1-3 (after their masters),
    # 0 follows 5 (before its master), the others jog
    script: list[Command] = [
        ("jog", 1, 0, 40.0), ("jog", 2, 0, -25.0), ("jog", 3, 0, 0.0),
        ("gear", 4, 1, 2.0), ("gear", 5, 2, -3.0), ("gear", 6, 3, 1.0), ("gear", 7, 1, -5.0),
        ("gear", 0, 5, 1.0),
        *[("jog", k, 0, 10.0 + k) for k in range(8, N)],
    ]  # fmt: skip
    for cmd in script:
        assert apply(fast, cmd, fp, []) == apply(ref, cmd, rp, []), cmd
    fast.run(40)
    ref.run(40)
    for ctl in (fast, ref):
        ctl.group_stop(1, ProgrammedStopMode.HARD_SHUTDOWN)
    lanes = fast.motion.lanes[1]
    assert not any(lane.members or lane.changed for lane in lanes.all)
    assert_same(fast, ref, fp, rp, [], [], "after the stop")
    assert [repr(ax.base) for ax in fast.axes] == [repr(ax.base) for ax in ref.axes]
    for k in range(50):
        fast.step()
        ref.step()
        assert_same_unread(fast, ref, [], [], f"cycle {k}")
    assert_same(fast, ref, fp, rp, [], [], "at the end")


def test_a_group_with_cams_in_the_lanes_stops_on_the_arrays_path() -> None:
    """Cams on half the axes (each reading a jogging master), the cams in their lane: a
    cam with no successor waiting aborts as any process does, so the stop, in every
    mode, takes the arrays' path and agrees with the reference after every cycle and
    whenever the processes are read."""
    for mode in MODES:
        fast, ref = pair(False)
        fp: list[Process] = []
        rp: list[Process] = []
        half = N // 2
        commands = [("jog", k, 0, 40.0 + 7.0 * k) for k in range(half)] + [
            ("cam", k, k - half, 0.0) for k in range(half, N)
        ]
        for cmd in commands:
            assert apply(fast, cmd, fp, []) == apply(ref, cmd, rp, []), cmd
        fast.run(40)
        ref.run(40)
        lanes = fast.motion.lanes[1].all
        in_cam_lanes = [
            p for lane in lanes if type(lane).__name__ == "CamLane" for p in lane.members
        ]
        assert len(in_cam_lanes) == N - half
        fast.group_stop(1, mode)
        ref.group_stop(1, mode)
        arrays_path = not any(lane.members or lane.changed for lane in fast.motion.lanes[1].all)
        assert arrays_path, mode.name
        assert_same(fast, ref, fp, rp, [], [], f"{mode.name}: after the stop")
        for k in range(150):
            fast.step()
            ref.step()
            assert_same_unread(fast, ref, [], [], f"{mode.name}: cycle {k}")
        assert_same(fast, ref, fp, rp, [], [], f"{mode.name}: at the end")
