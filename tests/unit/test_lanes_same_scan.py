"""Many commands in the same scan on many axes: with the fast lanes, the plans of the
jogs and moves commanded in one scan are built together before the step
(:mod:`motion_server.kernel.move_plan`); the motion must stay the reference's bit for bit
after every cycle, whatever the mix (jogs and moves from any state, trapezoidal and
S-curve, MCD changes, stops, clutched gears and PLCopen gears with their catch-up)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig
from motion_server.kernel.axis import Axis
from motion_server.kernel.enums import MasterReference
from motion_server.kernel.lanes import GroupLanes
from motion_server.kernel.lanes.ramps import CruiseLane
from motion_server.kernel.motion import Motion
from motion_server.kernel.processes import Process
from motion_server.kernel.trapezoid import TrapezoidProfile
from motion_server.scan import statecodec

from .test_lanes import assert_same, laned

MASTERS = tuple(range(1, 7))
SLAVES = tuple(range(7, 13))
#: (instruction type, operands)
Command = tuple[str, dict[str, object]]


def pair() -> tuple[MotionSystem, MotionSystem]:
    """Six virtual masters and six servo slaves in one group, lanes on and off."""
    out = []
    for lanes in (True, False):
        cfg = [
            AxisConfig(
                n, f"M{n}", AxisType.VIRTUAL, max_acceleration=5000.0, max_deceleration=5000.0
            )
            for n in MASTERS
        ] + [AxisConfig(n, f"S{n}", AxisType.SERVO, following_error_limit=1e6) for n in SLAVES]
        group = GroupConfig(1, "G", tuple(a.number for a in cfg), 0.002)
        s = MotionSystem(Controller(cfg, [group], lanes=lanes))
        for a in cfg:
            s.ctl.servo_on(s.ctl.axis(a.number))
        out.append(s)
    return out[0], out[1]


speeds = st.sampled_from([5.0, 20.0, 100.0, 250.0])
rates = st.sampled_from([100.0, 1000.0, 5000.0, 20_000.0])
positions = st.one_of(st.sampled_from([0.0, 1.0, 50.0, -30.0]), st.floats(-200.0, 200.0))
any_axis = st.sampled_from(MASTERS + SLAVES)


@st.composite
def command(draw: st.DrawFn) -> Command:
    kind = draw(
        st.sampled_from(
            ["MAJ", "MAJ", "MAM", "MCD", "MAS", "MAG", "MC_MoveVelocity", "MC_MoveAbsolute",
             "MC_MoveRelative", "MC_MoveAdditive", "MC_Halt", "MC_GearIn"]
        )
    )  # fmt: skip
    s_curve = draw(st.sampled_from([0, 0, 1]))
    if kind == "MAJ":
        return kind, {
            "Axis": draw(any_axis), "Direction": draw(st.sampled_from([0, 1])),
            "Speed": draw(speeds), "AccelRate": draw(rates), "DecelRate": draw(rates),
            "Profile": s_curve, "Merge": draw(st.sampled_from([0, 0, 1])),
        }  # fmt: skip
    if kind == "MAM":
        return kind, {
            "Axis": draw(any_axis), "MoveType": draw(st.sampled_from([0, 1])),
            "Position": draw(positions), "Speed": draw(speeds), "AccelRate": draw(rates),
            "DecelRate": draw(rates), "Profile": s_curve,
        }  # fmt: skip
    if kind == "MCD":
        return kind, {
            "Axis": draw(any_axis), "MotionType": draw(st.sampled_from([0, 1])),
            "ChangeSpeed": 1, "Speed": draw(st.sampled_from([0.0, 10.0, 150.0])),
            "ChangeAccel": draw(st.sampled_from([0, 1])), "AccelRate": draw(rates),
            "ChangeDecel": draw(st.sampled_from([0, 1])), "DecelRate": draw(rates),
        }  # fmt: skip
    if kind == "MAS":
        return kind, {"Axis": draw(any_axis), "StopType": draw(st.sampled_from([0, 1]))}
    if kind == "MAG":
        return kind, {
            "SlaveAxis": draw(st.sampled_from(SLAVES)),
            "MasterAxis": draw(st.sampled_from(MASTERS)),
            "Ratio": draw(st.sampled_from([0.5, -1.25, 2.0])),
            "MasterReference": draw(st.sampled_from([0, 1])),
            "Clutch": draw(st.sampled_from([0, 0, 1])),
            "AccelRate": draw(st.sampled_from([50.0, 100.0])),
        }  # fmt: skip
    if kind == "MC_GearIn":
        return kind, {
            "Slave": draw(st.sampled_from(SLAVES)), "Master": draw(st.sampled_from(MASTERS)),
            "RatioNumerator": draw(st.sampled_from([1.0, 3.0, -2.0])), "RatioDenominator": 2.0,
            "Acceleration": draw(rates), "Deceleration": draw(rates),
        }  # fmt: skip
    jerk = draw(st.sampled_from([0.0, 0.0, 50_000.0])) if s_curve else 0.0
    dyn = {"Acceleration": draw(rates), "Deceleration": draw(rates), "Jerk": jerk}
    if kind == "MC_Halt":
        return kind, {"Axis": draw(any_axis), "Deceleration": dyn["Deceleration"]}
    if kind == "MC_MoveVelocity":
        return kind, {
            "Axis": draw(any_axis), "Velocity": draw(speeds),
            "Direction": draw(st.sampled_from([1, 2])), **dyn,
        }  # fmt: skip
    if kind == "MC_MoveAbsolute":
        return kind, {
            "Axis": draw(any_axis), "Position": draw(positions), "Velocity": draw(speeds), **dyn,
        }  # fmt: skip
    return kind, {
        "Axis": draw(any_axis), "Distance": draw(positions), "Velocity": draw(speeds), **dyn,
    }  # fmt: skip


def assert_status(fast: MotionSystem, ref: MotionSystem, where: str) -> None:
    """The status arrays a publish reads agree with the axes' own status (a lane that
    changes a process's state must mark its axis, as composition does) and with the
    reference's."""
    arrays = []
    for s in (fast, ref):
        st = s.ctl.status_arrays()
        axes = s.ctl.axes
        assert st.motion_status.tolist() == [ax.motion_status for ax in axes], where
        assert st.plcopen_state.tolist() == [int(ax.plcopen_state) for ax in axes], where
        arrays.append([a.copy() for a in st])
    for a, b in zip(*arrays, strict=True):
        assert np.array_equal(a, b), where


def assert_order_valid(s: MotionSystem, where: str) -> None:
    """Every axis composes after the masters its processes read in its group (the order
    is current: it may be kept as it was when a new gear reads masters already before
    its slave, ``Motion._order_holds``)."""
    if s.ctl.motion.order_dirty:
        return  # sorted at the next step
    for g in s.ctl.groups:
        place = {ax.index: k for k, ax in enumerate(g.order)}
        assert sorted(place) == sorted(ax.index for ax in g.axes), where
        for ax in g.order:
            for p in ax.processes:
                for m in p.masters:
                    master = s.ctl.axis(m)
                    if master.group == g.number and master is not ax:
                        assert place[master.index] < place[ax.index], where


def run_rounds(
    fast: MotionSystem,
    ref: MotionSystem,
    rounds: list[tuple[list[Command], int]],
    prefix: str = "R",
) -> int:
    """Each round: every command of it triggered before the same cycle, then ``cycles``
    cycles, both systems compared after every one. The most processes seen in a lane."""
    most = 0
    for r, (commands, cycles) in enumerate(rounds):
        names = []
        for k, (type_name, ops) in enumerate(commands):
            name = f"{prefix}{r}C{k}"
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
            assert_status(fast, ref, where)
            assert_order_valid(ref, where)  # (the reference: nothing made lazily is read)
            most = max(most, laned(fast))
            if c == 0:
                for s in (fast, ref):
                    for name in names:
                        s.instances[name].inputs[s.instances[name].TRIGGER] = False
        assert laned(ref) == 0
    return most


def jog_all(speed: float) -> list[Command]:
    return [
        ("MAJ", {"Axis": n, "Speed": speed, "AccelRate": 1000.0, "DecelRate": 1000.0})
        for n in MASTERS
    ]


@settings(max_examples=60, deadline=None)
@given(
    rounds=st.lists(
        st.tuples(st.lists(command(), min_size=1, max_size=12), st.integers(1, 40)),
        min_size=1,
        max_size=5,
    )
)
def test_commands_in_the_same_scan_give_the_reference_motion(
    rounds: list[tuple[list[Command], int]],
) -> None:
    fast, ref = pair()
    # masters jogging, slaves geared: every kind of state for the commands to meet
    gears: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "Clutch": 1}) for s in SLAVES
    ]
    run_rounds(fast, ref, [(jog_all(50.0), 3), (gears, 5)], prefix="P")
    run_rounds(fast, ref, rounds)


def test_jogs_commanded_together_are_planned_together_and_run_in_the_lane() -> None:
    """Six jogs in one scan: each judged at its command and not planned yet; the lane
    plans them together before the step, and every one is in the lane from that step on,
    sampling what the reference's plans sample."""
    fast, ref = pair()
    for s in (fast, ref):
        for k, (type_name, ops) in enumerate(jog_all(80.0)):
            inst = s.add(type_name, f"J{k}", {})
            inst.inputs.update(ops)
            inst.inputs[inst.TRIGGER] = True
            inst.scan()  # the scan executes it (the cycle's own scan sees no new edge)
    for n in MASTERS:
        prof = fast.ctl.axis(n).processes[0].profile
        assert isinstance(prof, TrapezoidProfile)
        assert prof.request is not None  # judged, not planned: planned with the others
    assert run_rounds(fast, ref, [([], 60)]) == len(MASTERS)
    # 80 mm/s at 1000 mm/s² takes 80 ms, 40 cycles of 2 ms: all at speed
    assert np.array_equal(fast.ctl.cmd_vel[: len(MASTERS)], np.full(len(MASTERS), 80.0))


def geared_at_rest() -> tuple[MotionSystem, MotionSystem]:
    """``pair`` with every slave locked to its master (MAG, no clutch, command or actual
    reference alternately) while the masters stand still: the followers step at level 0,
    their masters having no motion."""
    fast, ref = pair()
    gears: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "Clutch": 1,
                 "MasterReference": s % 2})
        for s in SLAVES
    ]  # fmt: skip
    run_rounds(fast, ref, [(gears, 3)], prefix="P")
    return fast, ref


@settings(max_examples=40, deadline=None)
@given(
    rounds=st.lists(
        st.tuples(st.lists(command(), min_size=1, max_size=12), st.integers(1, 60)),
        min_size=1,
        max_size=4,
    )
)
def test_commands_on_masters_at_rest_with_followers_give_the_reference_motion(
    rounds: list[tuple[list[Command], int]],
) -> None:
    """Masters that start from rest join the time-driven lanes without their followers
    being levelled again (``GroupLanes._rejoin``); whatever follows (stops coming to
    rest, jogs reaching speed, moves landing, new commands on the same axes), the motion
    stays the reference's after every cycle."""
    fast, ref = geared_at_rest()
    run_rounds(fast, ref, rounds)


def test_masters_starting_from_rest_leave_their_followers_levels_alone(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Jogs started from rest on the masters of locked gears: the followers read them at
    level 0 before (no motion) and after (a time-driven lane), so neither the step that
    starts them nor the one in which they reach their speed (profile lane to cruise lane)
    levels the followers again; a stop's ramps coming to rest neither, nor a jerk-limited
    move from rest (the S-curve lane), nor a move slower than the one it replaces
    (ruckig's plan, sampled in the same lane). A master composed in Python (a
    superimposed move beside its move) does level them again."""
    fast, ref = geared_at_rest()
    lanes = fast.ctl.motion.lanes[1]
    calls: list[int] = []
    original = GroupLanes._order_command_followers

    def counted(self: GroupLanes, axes: Sequence[Axis]) -> None:
        if self is lanes:  # (the reference's lanes stay empty, but rebuild as well)
            calls.append(fast.ctl.tick)
        original(self, axes)

    monkeypatch.setattr(GroupLanes, "_order_command_followers", counted)
    # 80 mm/s at 1000 mm/s² takes 80 ms, 40 cycles of 2 ms: at speed within 45
    run_rounds(fast, ref, [(jog_all(80.0), 45)], prefix="J")
    assert np.array_equal(fast.ctl.cmd_vel[: len(MASTERS)], np.full(len(MASTERS), 80.0))
    assert len(lanes.cruise.members) == len(MASTERS)
    followers = [lane for lanes_ in lanes.followers.values() for lane in lanes_]
    assert sum(len(lane.members) for lane in followers) == len(SLAVES)
    assert calls == []
    stops: list[Command] = [("MAS", {"Axis": n, "StopType": 1}) for n in MASTERS]
    # MAS without jerk: the jogs are replaced by stop ramps (the masters leave the cruise
    # lane for Python in that scan: levelled again once), which come to rest in the lane
    run_rounds(fast, ref, [(stops, 60)], prefix="S")
    levelled = len(calls)
    assert levelled >= 1
    assert not fast.ctl.cmd_vel[: len(MASTERS)].any()
    # from rest again: a jerk-limited move, planned in closed form, joins the S-curve
    # lane, so its followers keep their levels
    move: list[Command] = [
        ("MC_MoveRelative", {"Axis": 1, "Distance": 10.0, "Velocity": 50.0,
                             "Acceleration": 1000.0, "Deceleration": 1000.0, "Jerk": 50_000.0})
    ]  # fmt: skip
    run_rounds(fast, ref, [(move, 5)], prefix="M")
    assert len(calls) == levelled
    master = fast.ctl.axis(1).processes[0]
    assert master.lane is lanes.scurves
    # 10 ms into its first jerk phase (1000 / 50,000 s long) the axis moves at
    # 50,000 * 0.01² / 2 = 2.5 mm/s: a move at 1 mm/s that replaces it from there must
    # first brake into its velocity limit, which ruckig plans; its plan joins the S-curve
    # lane as well, so the followers keep their levels
    assert fast.ctl.axis(1).command_velocity == pytest.approx(2.5, rel=1e-9)
    slow: list[Command] = [("MC_MoveRelative", {**move[0][1], "Velocity": 1.0})]
    run_rounds(fast, ref, [(slow, 5)], prefix="N")
    assert len(calls) == levelled
    assert fast.ctl.axis(1).processes[0].lane is lanes.scurves
    # a superimposed move beside it: two processes, composed in Python, so its
    # followers are levelled again (and leave their lanes)
    over: list[Command] = [
        ("MC_MoveSuperimposed", {"Axis": 1, "Distance": 1.0, "VelocityDiff": 5.0,
                                 "Acceleration": 1000.0, "Deceleration": 1000.0})
    ]  # fmt: skip
    run_rounds(fast, ref, [(over, 5)], prefix="O")
    assert len(calls) > levelled


def test_gears_on_slaves_after_their_masters_keep_the_order_without_a_sort(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """MAG on every slave at rest, each listed after its master in the group: the
    composition order already has each master first, so it is kept (no sort of the
    whole group). A gear whose master is listed after its slave is sorted in: the
    master then composes first."""
    fast, ref = pair()
    sorts: list[int] = []
    original = Motion.sort

    def counted(self: Motion) -> None:
        if self is fast.ctl.motion:
            sorts.append(fast.ctl.tick)
        original(self)

    run_rounds(fast, ref, [([], 1)], prefix="I")  # sorted once at the first step
    monkeypatch.setattr(Motion, "sort", counted)
    gears: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "Clutch": 0,
                 "AccelRate": 100.0})
        for s in SLAVES
    ]  # fmt: skip
    # masters 2 to 6 jogging, master 1 at rest
    run_rounds(fast, ref, [(jog_all(50.0)[1:], 3), (gears, 30)], prefix="G")
    assert sorts == []
    g = fast.ctl.groups[0]
    assert [ax.number for ax in g.order] == [*MASTERS, *SLAVES]
    # axis 1, at rest, geared to axis 12, listed after it: sorted in
    late: list[Command] = [("MAG", {"SlaveAxis": 1, "MasterAxis": 12, "Ratio": 1.0})]
    run_rounds(fast, ref, [(late, 5)], prefix="L")
    assert len(sorts) == 1
    order = [ax.number for ax in g.order]
    assert order.index(12) < order.index(1)


def test_clutched_gears_lock_into_the_gear_lane_at_their_level_without_levelling(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """MAG with the clutch on five slaves of jogging masters and on a sixth slave that
    follows the first slave (level 1): each gear catches up in the catch-up lane and is
    handed, locked, to the lane of locked gears at the level it had
    (``GroupLanes._hand_over``): the followers are levelled once, when the gears start,
    never at a lock; the motion is the reference's after every cycle."""
    fast, ref = pair()
    lanes = fast.ctl.motion.lanes[1]
    calls: list[int] = []
    original = GroupLanes._order_command_followers

    def counted(self: GroupLanes, axes: Sequence[Axis]) -> None:
        if self is lanes:
            calls.append(fast.ctl.tick)
        original(self, axes)

    run_rounds(fast, ref, [([], 1)], prefix="I")  # sorted and levelled at the first step
    monkeypatch.setattr(GroupLanes, "_order_command_followers", counted)
    # 50 mm/s at 1000 mm/s²: at speed after 50 ms, 25 cycles
    run_rounds(fast, ref, [(jog_all(50.0), 30)], prefix="J")
    assert calls == []
    gears: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 0, "AccelRate": 100.0})
        for s in SLAVES[:-1]
    ] + [
        ("MAG", {"SlaveAxis": SLAVES[-1], "MasterAxis": SLAVES[0], "Ratio": 2.0,
                 "MasterReference": 1, "Clutch": 0, "AccelRate": 100.0})
    ]  # fmt: skip
    # the first slaves reach 25 mm/s at 100 mm/s² in 0.25 s (125 cycles); the last one
    # 25 mm/s behind its accelerating master, later
    run_rounds(fast, ref, [(gears, 300)], prefix="G")
    assert len(calls) == 1  # when the gears started, in the catch-up lane
    locked = [lane for lane in lanes.followers[MasterReference.COMMAND] if lane.members]
    assert [type(lane).__name__ for lane in locked] == ["GearLane"]
    assert locked[0].member_levels == [0] * 5 + [1]


def test_a_snapshot_taken_while_gears_are_handed_over_runs_on_as_the_reference() -> None:
    """A snapshot between the step in which gears lock in the catch-up lane and the
    rebuild that takes them into the lane of locked gears: the levels recorded by the
    processes' identity do not survive a copy, so the copy levels its followers again,
    and runs on as the reference does."""
    fast, ref = pair()
    run_rounds(fast, ref, [(jog_all(50.0), 30)], prefix="J")
    gears: list[Command] = [
        ("MAG", {"SlaveAxis": s, "MasterAxis": s - 6, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 0, "AccelRate": 100.0})
        for s in SLAVES
    ]  # fmt: skip
    run_rounds(fast, ref, [(gears, 1)], prefix="G")
    copies = 0
    for c in range(200):
        fast.cycle()
        ref.cycle()
        assert_same(fast, ref, f"cycle {c}")
        if fast.ctl.motion.lanes[1].handed:
            copy = statecodec.loads(statecodec.dumps(fast))
            assert copy.ctl.motion.lanes[1].dirty
            assert not copy.ctl.motion.lanes[1].handed
            fast = copy
            copies += 1
    assert copies >= 1
    assert laned(fast) == len(MASTERS) + len(SLAVES)


def test_jogs_at_speed_join_the_cruise_lane_as_columns(monkeypatch: pytest.MonkeyPatch) -> None:
    """Jogs the profile lane ends at their speed join the cruise lane with the columns
    the profile lane computed, not loaded one by one from their objects; the motion is
    the reference's after every cycle."""
    fast, ref = pair()
    loaded: list[int] = []
    original = CruiseLane._load

    def counted(self: CruiseLane, p: Process, ax: Axis) -> tuple[Any, ...]:
        loaded.append(ax.number)
        return original(self, p, ax)

    monkeypatch.setattr(CruiseLane, "_load", counted)
    # 80 mm/s at 1000 mm/s² takes 80 ms, 40 cycles of 2 ms: all at speed, then cruising
    run_rounds(fast, ref, [(jog_all(80.0), 60)], prefix="J")
    assert len(fast.ctl.motion.lanes[1].cruise.members) == len(MASTERS)
    assert loaded == []
