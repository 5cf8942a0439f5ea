"""The step after a batch of starts, in proportion to what changed: followers admitted to
their lanes are levelled alone (``GroupLanes._order_command_followers`` after
``_hand_over``), the followers already in a lane keep their levels, and a lane that only
gained members appends them (``Lane.rebuild``). The lanes must be what a rebuild from
scratch makes of the same processes (the members of every lane, their levels, the
stepping schedule, the axes left to Python), and the motion the reference's, bit for bit,
after every cycle, whatever the mix: gears, clutched gears and cams started on slaves
whose masters jog, rest, follow other slaves (chains of levels) or are composed in
Python, stops and jogs in the same scans, the stop ramps made lazily read at random
moments."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig
from motion_server.kernel.cam_profile import CamProfile, SegmentType, compute_profile
from motion_server.kernel.cams import CamMode, CamProcess, LockDirection
from motion_server.kernel.enums import MasterReference
from motion_server.kernel.lanes import GroupLanes
from motion_server.kernel.lanes.base import LevelledLane
from motion_server.kernel.processes import Process
from motion_server.scan import statecodec

from .test_lanes import assert_same

MASTERS = tuple(range(1, 7))
SLAVES = tuple(range(7, 19))
#: (instruction type, operands), or ("CAM", slave and master numbers) for a kernel cam
Command = tuple[str, dict[str, Any]]
#: a dwell, a rise of 10 over 180 cam units, a dwell (cubic segments)
CAM_MASTERS = (0.0, 90.0, 180.0, 270.0, 360.0)
CAM_SLAVES = (0.0, 0.0, 5.0, 10.0, 10.0)


def pair() -> tuple[MotionSystem, MotionSystem]:
    """Six virtual masters and twelve servo slaves in one group, lanes on and off."""
    out = []
    for lanes in (True, False):
        cfg = [
            AxisConfig(
                n, f"M{n}", AxisType.VIRTUAL, max_acceleration=5000.0, max_deceleration=5000.0
            )
            for n in MASTERS
        ] + [
            AxisConfig(
                n,
                f"S{n}",
                AxisType.SERVO,
                max_acceleration=5000.0,
                max_deceleration=5000.0,
                following_error_limit=1e6,
            )
            for n in SLAVES
        ]
        group = GroupConfig(1, "G", tuple(a.number for a in cfg), 0.002)
        s = MotionSystem(Controller(cfg, [group], lanes=lanes))
        for a in cfg:
            s.ctl.servo_on(s.ctl.axis(a.number))
        out.append(s)
    return out[0], out[1]


def cam_profile() -> CamProfile:
    return compute_profile(CAM_MASTERS, CAM_SLAVES, [SegmentType.CUBIC] * len(CAM_MASTERS))


def start_cam(s: MotionSystem, slave: int, master: int, source: int, profile: CamProfile) -> None:
    """A Continuous, Immediate position cam as MAPC builds it, started on the kernel."""
    ctl = s.ctl
    m = ctl.axis(master)
    ax = ctl.axis(slave)
    if ctl.motion.would_cycle(slave, (master,)):
        return  # (MAPC refuses a loop of masters too)

    def make(v: float, a: float) -> Process:
        return CamProcess(
            ctl,
            profile,
            CamMode.CONTINUOUS,
            1.0,
            0.1,
            0.0,
            master=m.index,
            source=MasterReference(source),
            master_number=m.number,
            lock=LockDirection.IMMEDIATE,
            rollover=m.config.rollover,
        )

    ctl.start(ax, make, replace=())


speeds = st.sampled_from([10.0, 50.0, 120.0])
rates = st.sampled_from([200.0, 1000.0, 5000.0])
any_axis = st.sampled_from(MASTERS + SLAVES)


@st.composite
def command(draw: st.DrawFn) -> Command:
    kind = draw(st.sampled_from(["MAJ", "MAJ", "MAG", "MAG", "MAG", "CAM", "CAM", "MAS", "MAM"]))
    if kind == "MAJ":
        return kind, {
            "Axis": draw(any_axis), "Direction": draw(st.sampled_from([0, 1])),
            "Speed": draw(speeds), "AccelRate": draw(rates), "DecelRate": draw(rates),
            "Profile": draw(st.sampled_from([0, 0, 1])),
        }  # fmt: skip
    if kind == "MAM":
        return kind, {
            "Axis": draw(any_axis), "MoveType": 1, "Position": draw(st.sampled_from([5.0, -20.0])),
            "Speed": draw(speeds), "AccelRate": draw(rates), "DecelRate": draw(rates),
            "Profile": draw(st.sampled_from([0, 0, 1])),
        }  # fmt: skip
    if kind == "MAS":
        return kind, {"Axis": draw(any_axis), "StopType": draw(st.sampled_from([0, 1]))}
    slave = draw(st.sampled_from(SLAVES))
    # a master among the slaves too: followers of followers (levels above 0)
    master = draw(st.sampled_from(MASTERS + SLAVES).filter(lambda m: m != slave))
    reference = draw(st.sampled_from([1, 1, 0]))  # mostly the command: levelled
    if kind == "CAM":
        return kind, {"Slave": slave, "Master": master, "Source": reference}
    return kind, {
        "SlaveAxis": slave, "MasterAxis": master, "Ratio": draw(st.sampled_from([0.5, -2.0])),
        "MasterReference": reference, "Clutch": draw(st.sampled_from([0, 1, 1])),
        "AccelRate": draw(st.sampled_from([100.0, 2000.0])),
    }  # fmt: skip


def lanes_view(lanes: GroupLanes) -> tuple[Any, ...]:
    """What the lanes hold, by axis number: every lane's members (and the command
    followers' levels), the schedule by lane position and level, the axes left to
    compose in Python (as a set: their order is the group's)."""
    members = [sorted(ax.number for ax in lane.axes) for lane in lanes.all]
    members.append(sorted(ax.number for ax in lanes.stops.row_axes))
    cmd = lanes.followers[MasterReference.COMMAND]
    levels = tuple(
        sorted(zip((ax.number for ax in lane.axes), lane.member_levels, strict=True))
        for lane in cmd
    )
    position = {id(lane): k for k, lane in enumerate(lanes.all)}
    schedule = sorted((position[id(lane)], level) for lane, level in lanes.schedule)
    python = sorted(ax.number for ax in lanes.python_order)
    return tuple(map(tuple, members)), levels, schedule, python, lanes.depth


def from_scratch(s: MotionSystem) -> MotionSystem:
    """A copy of ``s`` (a snapshot) whose lanes are rebuilt and levelled from scratch."""
    copy: MotionSystem = statecodec.loads(statecodec.dumps(s))
    lanes = copy.ctl.motion.lanes[1]
    for lane in lanes.followers[MasterReference.COMMAND]:
        lane.member_levels = []  # not known: levelled again
    lanes._ordered = {}
    lanes.dirty = True
    lanes.rebuild(copy.ctl.arrays, copy.ctl.axes)
    return copy


def pending(lanes: GroupLanes) -> bool:
    return lanes.dirty or lanes.joined or lanes.handed or getattr(lanes, "followed", False)


def run_rounds(
    fast: MotionSystem,
    ref: MotionSystem,
    rounds: list[tuple[list[Command], int]],
    reads: Sequence[int] = (),
) -> None:
    """Each round: its commands issued before the same cycle, then its cycles, the
    systems compared after each; the lanes compared with a rebuild from scratch after
    every cycle that left nothing for the next rebuild (a rebuild pending is what the
    next step does first), and every follower lane's masters with those its members
    name after every cycle. ``reads``: cycles (counted over all rounds) after which every
    axis's processes are read, making the stop ramps kept as rows."""
    profile = cam_profile()
    cycle = 0
    for r, (commands, cycles) in enumerate(rounds):
        names = []
        for type_name, ops in commands:
            if type_name == "CAM":
                for s in (fast, ref):
                    start_cam(s, ops["Slave"], ops["Master"], ops["Source"], profile)
                continue
            name = f"C{len(fast.instances)}"
            names.append(name)
            for s in (fast, ref):
                inst = s.add(type_name, name, {})
                inst.inputs.update(ops)
                inst.inputs[inst.TRIGGER] = True
        for c in range(cycles):
            fast.cycle()
            ref.cycle()
            where = f"round {r} {commands}, cycle {c}"
            assert_same(fast, ref, where)
            lanes = fast.ctl.motion.lanes[1]
            assert_masters_current(lanes, len(fast.ctl.axes), where)
            if not pending(lanes) and not fast.ctl.motion.order_dirty:
                fresh = from_scratch(fast)
                assert lanes_view(lanes) == lanes_view(fresh.ctl.motion.lanes[1]), where
            if cycle in reads:
                for ax in fast.ctl.axes:
                    _ = ax.processes
            cycle += 1
            if c == 0:
                for s in (fast, ref):
                    for name in names:
                        s.instances[name].inputs[s.instances[name].TRIGGER] = False


def jog_masters(speed: float) -> list[Command]:
    return [
        ("MAJ", {"Axis": m, "Direction": 0, "Speed": speed, "AccelRate": 1000.0,
                 "DecelRate": 1000.0})
        for m in MASTERS
    ]  # fmt: skip


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.lists(command(), min_size=1, max_size=14), st.integers(1, 25)),
        min_size=1,
        max_size=4,
    ),
    st.lists(st.integers(0, 100), max_size=3),
    st.booleans(),
)
def test_random_starts_and_stops_in_one_scan_match_a_rebuild_from_scratch(
    rounds: list[tuple[list[Command], int]], reads: list[int], masters_jog: bool
) -> None:
    """Random batches of gears, clutched gears, cams, jogs, moves and stops in the same
    scans on many axes (followers of followers among them): the lanes after every cycle
    are those a rebuild from scratch makes, and the motion is the reference's."""
    fast, ref = pair()
    run_rounds(fast, ref, [(jog_masters(40.0) if masters_jog else [], 30), *rounds], reads)


def test_followers_admitted_in_chains_are_levelled_as_from_scratch() -> None:
    """Gears started in one scan on slaves that follow each other (S7 on M1, S8 on S7,
    S9 on S8, S10 on S9) and cams on a level-0 gear's slave, beside followers already
    locked: levels 0 to 3, as a rebuild from scratch gives them, and the reference's
    motion."""
    fast, ref = pair()
    gears = [("MAG", {"SlaveAxis": s, "MasterAxis": m, "Ratio": 0.5, "MasterReference": 1,
                      "Clutch": 1})
             for s, m in ((11, 2), (12, 3))]  # fmt: skip
    run_rounds(fast, ref, [(jog_masters(40.0), 30), (gears, 5)])
    chain: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": m, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 1})
        for s, m in ((10, 9), (9, 8), (8, 7), (7, 1))
    ]  # fmt: skip
    chain.append(("CAM", {"Slave": 13, "Master": 11, "Source": 1}))
    run_rounds(fast, ref, [(chain, 40)])
    lanes = fast.ctl.motion.lanes[1]
    levels = {
        ax.number: level
        for lane in lanes.followers[MasterReference.COMMAND]
        for ax, level in zip(lane.axes, lane.member_levels, strict=True)
    }
    assert levels == {7: 0, 8: 1, 9: 2, 10: 3, 11: 0, 12: 0, 13: 1}


def test_followers_already_in_a_lane_are_not_levelled_again_when_others_join(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Six slaves locked to jogging masters; then cams start on four other slaves: the
    step that takes the cams in levels them alone: no locked gear's master is looked up
    (the levels of followers already in a lane do not change when followers of axes
    nobody reads join)."""
    fast, ref = pair()
    gears = [("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "MasterReference": 1,
                      "Clutch": 1})
             for s in SLAVES[:6]]  # fmt: skip
    run_rounds(fast, ref, [(jog_masters(40.0), 30), (gears, 5)])
    lanes = fast.ctl.motion.lanes[1]
    gear_lane = next(lane for lane in lanes.followers[MasterReference.COMMAND] if lane.members)
    assert len(gear_lane.members) == 6
    looked_up: list[int] = []
    original = type(gear_lane).master_index

    def counted(p: Process) -> int:
        looked_up.append(id(p))
        return original(p)

    monkeypatch.setattr(type(gear_lane), "master_index", staticmethod(counted))
    cams: list[Command] = [("CAM", {"Slave": s, "Master": s - 12, "Source": 1})
                           for s in SLAVES[6:10]]  # fmt: skip
    run_rounds(fast, ref, [(cams, 3)])
    cam_lane = next(
        lane
        for lane in lanes.followers[MasterReference.COMMAND]
        if type(lane).__name__ == "CamLane"
    )
    assert len(cam_lane.members) == 4
    assert not set(looked_up) & {id(p) for p in gear_lane.members}


def test_an_admitted_axis_read_by_a_follower_in_a_lane_levels_it_again() -> None:
    """S8 is locked (level 0) to S7, which is at rest; a gear then starts on S7 from a
    jogging master: S8's level becomes 1, as a rebuild from scratch gives it, and the
    motion stays the reference's."""
    fast, ref = pair()
    first = [("MAG", {"SlaveAxis": 8, "MasterAxis": 7, "Ratio": 2.0, "MasterReference": 1,
                      "Clutch": 1})]  # fmt: skip
    run_rounds(fast, ref, [(jog_masters(40.0), 30), (first, 5)])
    second = [("MAG", {"SlaveAxis": 7, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                       "Clutch": 1})]  # fmt: skip
    run_rounds(fast, ref, [(second, 40)])
    lanes = fast.ctl.motion.lanes[1]
    levels = {
        ax.number: level
        for lane in lanes.followers[MasterReference.COMMAND]
        for ax, level in zip(lane.axes, lane.member_levels, strict=True)
    }
    assert levels == {7: 0, 8: 1}


def test_a_lane_that_only_gained_members_keeps_the_rows_it_had() -> None:
    """Cams joining a lane of cams already stepping: the rows kept are the same values
    (appended to, not selected again), the members' slots and axis indices those a
    rebuild from scratch gives."""
    fast, ref = pair()
    cams: list[Command] = [("CAM", {"Slave": s, "Master": s - 6, "Source": 1})
                           for s in SLAVES[:3]]  # fmt: skip
    more: list[Command] = [("CAM", {"Slave": s, "Master": s - 6, "Source": 1})
                           for s in SLAVES[3:6]]  # fmt: skip
    run_rounds(fast, ref, [(jog_masters(40.0), 30), (cams, 5), (more, 5)])
    lanes = fast.ctl.motion.lanes[1]
    cam_lane = next(
        lane
        for lane in lanes.followers[MasterReference.COMMAND]
        if type(lane).__name__ == "CamLane"
    )
    assert [ax.number for ax in cam_lane.axes] == list(SLAVES[:6])
    assert cam_lane._slot == {id(p): k for k, p in enumerate(cam_lane.members)}
    assert cam_lane.idx.tolist() == [ax.index for ax in cam_lane.axes]
    assert cam_lane.at == slice(SLAVES[0] - 1, SLAVES[5])
    assert isinstance(cam_lane, LevelledLane)
    assert np.array_equal(cam_lane.midx, [ax.index for ax in fast.ctl.axes[:6]])


def named_master(p: Process) -> int:
    """The index of the master a follower reads, from the process itself (not through
    ``master_index``, which tests count)."""
    if isinstance(p, CamProcess):
        assert p.index is not None
        return p.index
    single = p.single  # type: ignore[attr-defined]
    assert single is not None
    return int(single.index)


def assert_masters_current(lanes: GroupLanes, n_axes: int, where: str) -> None:
    """Every follower lane's masters (``midx``, and the indices each level reads) are
    those its members' processes name, row by row."""
    every = np.arange(n_axes)
    for lane in (
        *lanes.followers[MasterReference.COMMAND],
        *lanes.followers[MasterReference.ACTUAL],
    ):
        if not lane.members:
            continue
        named = [named_master(p) for p in lane.members]
        name = f"{where}: {type(lane).__name__} {lane.source.name}"
        assert lane.midx.tolist() == named, name
        for sl, masters in zip(lane.levels, lane.masters, strict=True):
            assert every[masters].tolist() == named[sl], name


def test_a_follower_evicted_after_a_gear_replaced_reads_the_masters_of_its_lane() -> None:
    """The scan that found it (hypothesis, the fast lanes against the reference): masters
    jogging, each of S7 to S12 locked to one (MAG, no clutch), then in one scan MAJ
    three times on M1, MAM on M2 (a move over its jog: composed in Python) and MAG of
    S7 to M1 again. The rebuild drops S7's old gear and appends its new one, and
    levelling the followers then evicts S8 (its master is composed in Python), which
    rebuilds the lane a second time before it is ordered: that rebuild must carry the
    masters over from the first one, not from the order before both (each follower
    would read the master of its neighbour: S9 M2's, S7 M6's)."""
    fast, ref = pair()
    gears: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "Clutch": 1})
        for s in SLAVES[:6]
    ]  # fmt: skip
    jogs: list[Command] = [
        ("MAJ", {"Axis": m, "Speed": 50.0, "AccelRate": 1000.0, "DecelRate": 1000.0})
        for m in MASTERS
    ]  # fmt: skip
    run_rounds(fast, ref, [(jogs, 3), (gears, 5)])
    maj = {"Axis": 1, "Direction": 0, "Speed": 5.0, "AccelRate": 100.0, "DecelRate": 100.0,
           "Profile": 0, "Merge": 0}  # fmt: skip
    scan: list[Command] = [
        ("MAJ", maj), ("MAJ", maj), ("MAJ", maj),
        ("MAM", {"Axis": 2, "MoveType": 0, "Position": 0.0, "Speed": 5.0, "AccelRate": 100.0,
                 "DecelRate": 100.0, "Profile": 0}),
        ("MAG", {"SlaveAxis": 7, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 1, "AccelRate": 50.0}),
    ]  # fmt: skip
    run_rounds(fast, ref, [(scan, 1)])
    lanes = fast.ctl.motion.lanes[1]
    gear_lane = lanes.followers[MasterReference.COMMAND][0]
    assert sorted(ax.number for ax in gear_lane.axes) == [7, 9, 10, 11, 12]
    assert_masters_current(lanes, len(fast.ctl.axes), "after the scan")
    run_rounds(fast, ref, [([], 20)])


def test_a_follower_admitted_below_one_kept_leaves_the_axes_composed_in_python() -> None:
    """The scan that found it (hypothesis, the lanes against a rebuild from scratch):
    masters jogging; in one scan MAJ on S8, MAG of S7 on S15 and of S8 on M1 (both
    clutched), MAS (jog) on S8 and MAG of S15 on M1. S7 (level 1: it reads S15) is in the
    lane of locked gears when S8 is admitted to it at level 0; ordered by level, S8 comes
    first, before the member kept. The axes left to Python were those that were without
    the axes that joined, taken from the tail of the lane after that order: S7, not S8.
    S8 was then composed twice, in its lane and in Python."""
    fast, ref = pair()
    jog: Command = ("MAJ", {"Axis": 8, "Direction": 0, "Speed": 10.0, "AccelRate": 200.0,
                            "DecelRate": 200.0, "Profile": 0})  # fmt: skip
    scan: list[Command] = [
        jog,
        ("MAG", {"SlaveAxis": 7, "MasterAxis": 15, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 1, "AccelRate": 100.0}),
        ("MAG", {"SlaveAxis": 8, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 1, "AccelRate": 100.0}),
        ("MAS", {"Axis": 8, "StopType": 1}),
        ("MAG", {"SlaveAxis": 15, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 0, "AccelRate": 100.0}),
    ]  # fmt: skip
    run_rounds(fast, ref, [(jog_masters(40.0), 30), (scan, 3)])
    lanes = fast.ctl.motion.lanes[1]
    laned = {ax.number for lane in lanes.all for ax in lane.axes}
    assert {7, 8, 15} <= laned
    assert not laned & {ax.number for ax in lanes.python_order}
