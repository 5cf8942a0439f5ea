"""Instructions that fire in one scan and hand their commands to the kernel together
(``instructions/scan_pass.py``) against the same scans executed instance by instance.

Two systems get the same writes: one scans with batches (the default), the other with
``batch=False`` (every instance alone, as before the batches). MAJ, MAM, MAG, MAS,
MC_Stop, MC_Halt, MC_MoveVelocity, MC_MoveAbsolute, MC_MoveRelative and MC_GearIn
instances are mixed with MGS (which always executes alone, so it cuts a batch) in one fixed order;
random scans fire random subsets with random, partly invalid operands: two instances on
one axis, a MAG whose master is a slave geared in the same scan, loops of gears, Merge,
S-curve and master units (executed alone), a negative ratio, stops of some kinds or with
a jerk, buffered halts, jogs and moves, the current direction (executed alone), axes
that do not exist or cannot move, and rates so small that the kernel refuses the plan
of one jog, move or stop in the middle of a batch. After every cycle both systems must
show the same outputs on every instance, mark the same instances changed and command the
same position, velocity and acceleration, bit for bit, with the same processes (their
planned attributes and owners) on every axis, lanes on and off.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    PLCopenState,
)
from motion_server.kernel.processes import Process

from .test_instruction_fast_paths import digest

#: axes 1..6 servo (on), 7 feedback only, 8 servo off; 9 does not exist
AXES = [1, 2, 3, 4, 5, 6, 1, 2, 3, 7, 8, 9]
#: valid rates drawn more often; 1e-30 units/s² makes a jog's plan too long (refused by
#: the kernel when it plans it: inside the batch call)
RATES = [100.0, 250.0, 100.0, 1e-30, 0.0]
DYNAMICS: dict[str, list[Any]] = {
    "Speed": [5.0, 50.0, 50.0, 5000.0, 0.0, -0.0],
    "SpeedUnits": [0, 0, 1, 4],
    "AccelRate": RATES,
    "AccelUnits": [0, 0, 1],
    "DecelRate": RATES,
    "DecelUnits": [0, 0, 1],
    "Profile": [0, 0, 0, 1],
    "AccelJerk": [100.0, 50.0],
    "DecelJerk": [100.0],
    "JerkUnits": [2],
    "Merge": [0, 0, 0, 1],
    "MergeSpeed": [0, 1],
}
POOLS: dict[str, dict[str, list[Any]]] = {
    "MAJ": {"Axis": AXES, "Direction": [0, 1], **DYNAMICS},
    "MAM": {"Axis": AXES, "MoveType": [0, 1, 1, 2], "Position": [-10.0, 25.5, 0.0], **DYNAMICS},
    "MAG": {
        "SlaveAxis": AXES,
        "MasterAxis": AXES,
        "Direction": [0, 1, 2, 3],
        "Ratio": [0.5, 0.5, -1.25, 2.0, 0.0],
        "SlaveCounts": [1, 3],
        "MasterCounts": [1, 2],
        "MasterReference": [0, 1],
        "RatioFormat": [0, 0, 1],
        "Clutch": [0, 1],
        "AccelRate": [100.0, 50.0, 0.0],
        "AccelUnits": [0, 1],
    },
    "MAS": {
        "Axis": AXES,
        "StopType": [0, 0, 1, 2],
        "ChangeDecel": [0, 0, 1],
        "DecelRate": RATES,
        "DecelUnits": [0, 0, 1],
        "ChangeDecelJerk": [0, 0, 0, 1],
    },
    "MGS": {"Group": [1, 1, 2], "StopMode": [0, 1]},
    "MC_Stop": {"Axis": AXES, "Deceleration": RATES, "Jerk": [0.0, 0.0, 0.0, 100.0]},
    "MC_Halt": {
        "Axis": AXES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "BufferMode": [0, 0, 0, 1],
    },
    "MC_MoveVelocity": {
        "Axis": AXES,
        "Velocity": [5.0, 50.0, 50.0, 5000.0, 0.0, -0.0],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "Direction": [1, 1, 3, 4, 2],
        "BufferMode": [0, 0, 0, 1],
    },
    "MC_MoveRelative": {
        "Axis": AXES,
        "Distance": [10.0, -5.5, 10.0, 0.0, 1e9],
        "Velocity": [5.0, 50.0, 50.0, 5000.0],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "BufferMode": [0, 0, 0, 1],
    },
    "MC_MoveAbsolute": {
        "Axis": AXES,
        "Position": [10.0, -5.5, 10.0, 0.0],
        "Velocity": [5.0, 50.0, 50.0, 5000.0],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "Direction": [1, 2, 3, 4],
        "BufferMode": [0, 0, 0, 1],
    },
    "MC_GearIn": {
        "Slave": AXES,
        "Master": AXES,
        "RatioNumerator": [0.5, 0.5, -2.0, 0.0],
        "RatioDenominator": [1.0, 1.0, 3.0],
        "MasterValueSource": [0, 0, 1],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "BufferMode": [0, 0, 0, 1],
    },
}
#: the instances in scan order: runs of one type, cut by the others
ORDER = [
    ("MAJ1", "MAJ"), ("MAJ2", "MAJ"), ("MAJ3", "MAJ"), ("MAG1", "MAG"), ("MAG2", "MAG"),
    ("MAG3", "MAG"), ("MAJ4", "MAJ"), ("MAS1", "MAS"), ("MAS2", "MAS"), ("MC_Stop1", "MC_Stop"),
    ("MAS3", "MAS"), ("MC_Stop2", "MC_Stop"), ("MC_Halt1", "MC_Halt"), ("MC_Halt2", "MC_Halt"),
    ("MAJ5", "MAJ"), ("MAG4", "MAG"), ("MAM1", "MAM"), ("MAM2", "MAM"), ("MAM3", "MAM"),
    ("MC_Halt3", "MC_Halt"),
    ("MC_MoveVelocity1", "MC_MoveVelocity"), ("MC_MoveVelocity2", "MC_MoveVelocity"),
    ("MAJ6", "MAJ"), ("MAG5", "MAG"), ("MGS1", "MGS"), ("MC_MoveVelocity3", "MC_MoveVelocity"),
    ("MAJ7", "MAJ"), ("MAJ8", "MAJ"), ("MAM4", "MAM"), ("MC_MoveRelative1", "MC_MoveRelative"),
    ("MC_MoveRelative2", "MC_MoveRelative"), ("MC_MoveAbsolute1", "MC_MoveAbsolute"),
    ("MC_MoveAbsolute2", "MC_MoveAbsolute"), ("MC_MoveRelative3", "MC_MoveRelative"),
    ("MC_MoveAbsolute3", "MC_MoveAbsolute"), ("MC_GearIn1", "MC_GearIn"),
    ("MC_GearIn2", "MC_GearIn"), ("MC_GearIn3", "MC_GearIn"), ("MAJ9", "MAJ"),
    ("MC_GearIn4", "MC_GearIn"),
]  # fmt: skip


def servo_system(batch: bool, lanes: bool, axes: list[AxisConfig] | None = None) -> MotionSystem:
    """A system of ``axes`` in one group at 2 ms, the first six in Servo Control:
    unless given, servos 1..6, 7 feedback only, 8 a servo (left off); batched or one
    instance at a time."""
    if axes is None:
        axes = [
            AxisConfig(n, f"A{n}", AxisType.SERVO, max_velocity=1000.0, max_acceleration=500.0,
                       max_deceleration=400.0, max_jerk=20000.0)
            for n in range(1, 7)
        ] + [AxisConfig(7, "A7", AxisType.FEEDBACK_ONLY),
             AxisConfig(8, "A8", AxisType.SERVO)]  # fmt: skip
    group = GroupConfig(1, "Group1", tuple(a.number for a in axes), 0.002)
    system = MotionSystem(Controller(axes, [group], lanes=lanes), batch=batch)
    for ax in system.ctl.axes[:6]:
        system.ctl.servo_on(ax)
    return system


def build(batch: bool, lanes: bool) -> MotionSystem:
    system = servo_system(batch, lanes)
    for name, type_name in ORDER:
        system.add(type_name, name)
    return system


def scan_plans(
    order: list[tuple[str, str]], pools: dict[str, dict[str, list[Any]]], most: int
) -> st.SearchStrategy[list[list[tuple[str, dict[str, Any], bool]]]]:
    """Cycles of (instance, operands written, trigger): many instances each, so that
    runs of one type fire together; up to ``most`` operands of an instance's type's pool
    (``pools``) written at once."""
    types = dict(order)

    @st.composite
    def plans(draw: st.DrawFn) -> list[list[tuple[str, dict[str, Any], bool]]]:
        out = []
        for _ in range(draw(st.integers(1, 6))):
            names = draw(st.lists(st.sampled_from([n for n, _ in order]), unique=True))
            cycle = []
            for name in names:
                pool = pools[types[name]]
                keys = draw(st.lists(st.sampled_from(sorted(pool)), max_size=most, unique=True))
                values = {k: draw(st.sampled_from(pool[k])) for k in keys}
                cycle.append((name, values, draw(st.booleans())))
            out.append(cycle)
        return out

    return plans()


def scans() -> st.SearchStrategy[list[list[tuple[str, dict[str, Any], bool]]]]:
    return scan_plans(ORDER, POOLS, 5)


def write_scan(system: MotionSystem, cycle: list[tuple[str, dict[str, Any], bool]]) -> None:
    """One cycle of a plan (:func:`scan_plans`) written to ``system``'s instances before
    it runs, what changed before it forgotten."""
    for name, values, rung in cycle:
        inst = system[name]
        inst.inputs.update(values)
        inst.inputs[inst.TRIGGER] = rung
    system.changed_outputs.clear()


def bits(x: float) -> bytes:
    return struct.pack("<d", x)


def processes(p: list[Process]) -> list[list[tuple[str, str]]]:
    """Each process's digest, the lane it is in by its type: what a lane keeps of its
    own (a flag that a rebuild is due) depends on how it holds the process (a stop's
    ramps are rows of the stop lane when planned as a batch, members one by one), not
    on what the process commands."""
    out = []
    for q in p:
        kept = [(k, v) for k, v in digest(q) if not k.startswith("lane.")]
        out.append([*kept, ("lane", type(q.lane).__name__)])
    return out


def same_scan(batched: MotionSystem, alone: MotionSystem, when: object) -> None:
    """What a batched and a one-by-one scan must agree on, whatever the batch kind: every
    instance's outputs, what changed, the internal errors, and each axis's command (bit
    for bit) and processes."""
    for name, inst in batched.instances.items():
        assert inst.outputs == alone[name].outputs, (when, name)
    assert batched.changed_outputs == alone.changed_outputs, when
    assert [n for n, _ in batched.internal_errors] == [n for n, _ in alone.internal_errors]
    for a, b in zip(batched.ctl.axes, alone.ctl.axes, strict=True):
        for field in ("command_position", "command_velocity", "command_acceleration"):
            assert bits(getattr(a, field)) == bits(getattr(b, field)), (when, a.name, field)
        assert processes(a.processes) == processes(b.processes), (when, a.name)
        assert owners(a.processes) == owners(b.processes), (when, a.name)


def owners(p: list[Process]) -> list[str]:
    """Who owns each process: an instance by its name, anything else by its type."""
    return [getattr(q.owner, "name", type(q.owner).__name__) for q in p]


def same(batched: MotionSystem, alone: MotionSystem, when: object) -> None:
    same_scan(batched, alone, when)
    for a, b in zip(batched.ctl.axes, alone.ctl.axes, strict=True):
        assert a.gear_direction == b.gear_direction, (when, a.name)


def run_side_by_side(
    build: Callable[[bool, bool], MotionSystem],
    lanes: bool,
    plan: list[list[tuple[str, dict[str, Any], bool]]],
    check: Callable[[MotionSystem, MotionSystem, object], None] | None = None,
) -> None:
    """The cycles of ``plan`` (and three quiet ones) on a system ``build`` makes with
    batches and on one without, ``check`` (:func:`same` unless given) after every
    cycle."""
    batched, alone = build(True, lanes), build(False, lanes)
    for k, cycle in enumerate(plan + [[]] * 3):
        for system in (batched, alone):
            write_scan(system, cycle)
        batched.cycle()
        alone.cycle()
        (check or same)(batched, alone, (k, cycle))


@pytest.mark.parametrize("lanes", [True, False])
@settings(max_examples=150, deadline=None)
@given(plan=scans())
def test_a_scan_with_batches_acts_as_one_instance_at_a_time(
    lanes: bool, plan: list[list[tuple[str, dict[str, Any], bool]]]
) -> None:
    run_side_by_side(build, lanes, plan)


def test_jogs_and_gears_of_one_scan_reach_the_kernel_in_one_call_each() -> None:
    """Four MAJ on four axes and two MAG on two others, fired together: one
    ``start_jogs`` with the four jogs and one gear batch; the outputs and motion are
    those of the same instances scanned one by one."""
    systems = {batch: build(batch, True) for batch in (True, False)}
    calls: list[tuple[str, int]] = []
    ctl = systems[True].ctl
    start_jogs = ctl.start_jogs

    def spy(axes: Any, *args: Any, **kwargs: Any) -> Any:
        calls.append(("jogs", len(axes)))
        return start_jogs(axes, *args, **kwargs)

    ctl.start_jogs = spy  # type: ignore[method-assign]
    for system in systems.values():
        for k, name in enumerate(("MAJ1", "MAJ2", "MAJ3", "MAJ4")):
            system[name].inputs.update({"Axis": k + 1, "Speed": 50.0, "Execute": True})
        for name, slave, master in (("MAG1", 5, 1), ("MAG2", 6, 2)):
            system[name].inputs.update({"SlaveAxis": slave, "MasterAxis": master})
            system[name].inputs["Execute"] = True
    for _ in range(3):
        systems[True].cycle()
        systems[False].cycle()
        same(systems[True], systems[False], "cycle")
    # MAJ1..3 are a run; MAG1 and MAG2 another; MAJ4 comes after the MAGs: its own call
    assert calls == [("jogs", 3), ("jogs", 1)]
    for name in ("MAJ1", "MAJ2", "MAJ3", "MAJ4", "MAG1", "MAG2"):
        out = systems[True][name].outputs
        assert out["DN"] and out["IP"] and not out["ER"], name


def fire(system: MotionSystem, operands: dict[str, dict[str, Any]]) -> None:
    """Write ``operands`` to their instances with Execute high, run one cycle."""
    for name, values in operands.items():
        system[name].inputs.update({**values, "Execute": True})
    system.cycle()


def test_a_jog_refused_in_the_middle_of_a_batch_leaves_the_others_started() -> None:
    """Axis 2 jogs in reverse at 1,000 units/s (reached at 500 units/s²). Then MAJ1..3
    ask axes 1..3 for +1,000 units/s at 0.2 units/s² (the same limits: one kernel
    call): from rest that is a 5,000 s ramp, from -1,000 units/s a 10,000 s one, beyond
    the 7,600 s the kernel plans
    (``trapezoid.MAX_DURATION``). The kernel refuses axis 2's jog inside the batch call,
    after axis 1's started: MAJ2 shows the kernel's error and axis 2 keeps its jog; MAJ1
    and MAJ3 run; everything as one by one."""
    systems = [build(batch, True) for batch in (True, False)]
    slow = {"Speed": 1000.0, "AccelRate": 0.2, "DecelRate": 0.2, "AccelUnits": 0,
            "DecelUnits": 0}  # fmt: skip
    for system in systems:
        fire(system, {"MAJ2": {"Axis": 2, "Speed": 1000.0, "Direction": 1, "AccelRate": 500.0,
                               "AccelUnits": 0}})  # fmt: skip
        system["MAJ2"].inputs["Execute"] = False
        system.cycle(1100)  # 2.2 s: at speed after 1,000 / 500 = 2 s
        assert system.ctl.axis(2).command_velocity == -1000.0
        fire(system, {
            "MAJ1": {"Axis": 1, **slow},
            "MAJ2": {"Axis": 2, "Direction": 0, **slow},
            "MAJ3": {"Axis": 3, **slow},
        })  # fmt: skip
    same(systems[0], systems[1], "refused")
    out = {name: systems[0][name].outputs for name in ("MAJ1", "MAJ2", "MAJ3")}
    assert out["MAJ2"]["ER"] and out["MAJ2"]["ERR"] == ErrorCode.PROFILE_FAILED
    assert systems[0].ctl.axis(2).command_velocity == -1000.0
    for name in ("MAJ1", "MAJ3"):
        assert out[name]["DN"] and out[name]["IP"] and out[name]["ERR"] == 0, name


def test_moves_of_one_scan_reach_the_kernel_in_one_call_and_land_on_their_targets() -> None:
    """MAM1..3 on axes 1..3 (incremental 25.5, incremental 25.5, absolute -10: the same
    limits) and MAM4 on axis 4 later in the scan order, fired together from rest: one
    ``start_moves`` with the three moves, then MAM4's own; every output and the motion as
    one by one. 25.5 units at 50 units/s and 100 units/s² take 0.5 s up, 0.01 s at
    speed and 0.5 s down; 10 units, a triangle with a peak of sqrt(1,000) units/s, take
    0.63 s: after 1.2 s (600 cycles of 2 ms) every move is done (PC) exactly on its
    target."""
    systems = {batch: build(batch, True) for batch in (True, False)}
    calls: list[int] = []
    ctl = systems[True].ctl
    start_moves = ctl.start_moves

    def spy(axes: Any, *args: Any, **kwargs: Any) -> Any:
        calls.append(len(axes))
        return start_moves(axes, *args, **kwargs)

    ctl.start_moves = spy  # type: ignore[method-assign]
    dynamics = {"Speed": 50.0, "AccelRate": 100.0, "DecelRate": 100.0, "SpeedUnits": 0,
                "AccelUnits": 0, "DecelUnits": 0, "Merge": 0, "Profile": 0}  # fmt: skip
    targets = {"MAM1": (1, 1, 25.5), "MAM2": (2, 1, 25.5), "MAM3": (3, 0, -10.0),
               "MAM4": (4, 1, 25.5)}  # fmt: skip
    for system in systems.values():
        for name, (axis, kind, position) in targets.items():
            system[name].inputs.update(
                {"Axis": axis, "MoveType": kind, "Position": position, **dynamics}
            )
            system[name].inputs["Execute"] = True
    systems[True].cycle()
    systems[False].cycle()
    same(systems[True], systems[False], "started")
    assert calls == [3, 1]
    for name in targets:
        out = systems[True][name].outputs
        assert out["DN"] and out["IP"] and not out["PC"] and not out["ER"], name
    for k in range(600):
        systems[True].cycle()
        systems[False].cycle()
        same(systems[True], systems[False], k)
    for name, (axis, _, position) in targets.items():
        out = systems[True][name].outputs
        assert out["PC"] and not out["IP"], name
        assert ctl.axis(axis).command_position == position
        assert ctl.axis(axis).command_velocity == 0.0


def test_a_move_refused_in_the_middle_of_a_batch_leaves_the_others_started() -> None:
    """MAM1..3 from rest at 10^-6 units/s² up and down (the same limits: one kernel
    call), incremental 1, 100 and 1 units: a triangle of 2 sqrt(d / a) s, 2,000 s for
    one unit, 20,000 s for 100 units, beyond the 7,600 s the kernel plans
    (``trapezoid.MAX_DURATION``). The kernel refuses axis 2's move inside the batch
    call, after axis 1's started: MAM2 shows the kernel's error and axis 2 stays at
    rest; MAM1 and MAM3 run; everything as one by one."""
    systems = [build(batch, True) for batch in (True, False)]
    slow = {"MoveType": 1, "Speed": 1000.0, "AccelRate": 1e-6, "DecelRate": 1e-6,
            "SpeedUnits": 0, "AccelUnits": 0, "DecelUnits": 0, "Merge": 0,
            "Profile": 0}  # fmt: skip
    for system in systems:
        fire(system, {
            "MAM1": {"Axis": 1, "Position": 1.0, **slow},
            "MAM2": {"Axis": 2, "Position": 100.0, **slow},
            "MAM3": {"Axis": 3, "Position": 1.0, **slow},
        })  # fmt: skip
    same(systems[0], systems[1], "refused")
    out = {name: systems[0][name].outputs for name in ("MAM1", "MAM2", "MAM3")}
    assert out["MAM2"]["ER"] and out["MAM2"]["ERR"] == ErrorCode.PROFILE_FAILED
    assert not systems[0].ctl.axis(2).processes
    for name in ("MAM1", "MAM3"):
        assert out[name]["DN"] and out[name]["IP"] and out[name]["ERR"] == 0, name
    for k in range(5):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], k)


def test_a_gear_that_closes_a_loop_through_a_gear_of_the_same_scan_is_refused() -> None:
    """Axis 3 follows axis 2 (a MAG of an earlier scan). In one scan MAG1 gears 2 to 1,
    then MAG2 gears 1 to 3: 1 -> 3 -> 2 -> 1 is a loop once MAG1's gear exists, so MAG2
    is refused with ERR 10 (master axis conflict), as one by one."""
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        fire(system, {"MAG5": {"SlaveAxis": 3, "MasterAxis": 2, "Clutch": 1}})
        system["MAG5"].inputs["Execute"] = False
        fire(system, {
            "MAG1": {"SlaveAxis": 2, "MasterAxis": 1, "Clutch": 1},
            "MAG2": {"SlaveAxis": 1, "MasterAxis": 3, "Clutch": 1},
        })  # fmt: skip
    same(systems[0], systems[1], "loop")
    mag1, mag2 = (systems[0][name].outputs for name in ("MAG1", "MAG2"))
    assert mag1["DN"] and mag1["IP"] and not mag1["ER"]
    assert mag2["ER"] and mag2["ERR"] == ErrorCode.MASTER_AXIS_CONFLICT


def test_a_gear_whose_master_follows_a_slave_geared_in_the_same_scan_sees_that_gear() -> None:
    """Axis 3 follows axis 2 and axis 2 follows axis 4 (MAGs of earlier scans). In one
    scan MAG1 gears 2 to 1 (superseding its gear to 4), then MAG2 gears 4 to 3: once
    MAG1's gear exists, 3 -> 2 -> 1 does not reach 4, so MAG2 is accepted, as one by
    one (the links as they were, 3 -> 2 -> 4, would have been a loop)."""
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        fire(system, {"MAG5": {"SlaveAxis": 3, "MasterAxis": 2, "Clutch": 1}})
        fire(system, {"MAG4": {"SlaveAxis": 2, "MasterAxis": 4, "Clutch": 1}})
        for name in ("MAG4", "MAG5"):
            system[name].inputs["Execute"] = False
        fire(system, {
            "MAG1": {"SlaveAxis": 2, "MasterAxis": 1, "Clutch": 1},
            "MAG2": {"SlaveAxis": 4, "MasterAxis": 3, "Clutch": 1},
        })  # fmt: skip
    same(systems[0], systems[1], "no loop")
    for name in ("MAG1", "MAG2"):
        out = systems[0][name].outputs
        assert out["DN"] and out["IP"] and not out["ER"], name


def test_jogs_at_speeds_of_zero_and_minus_zero_keep_their_signs() -> None:
    """MAJ1 at Speed 0.0 and MAJ2 at -0.0, otherwise alike, in one batch: the two values
    are equal (one judge key) but one by one the jogs' targets are +0.0 and -0.0; the
    batch keeps them apart."""
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        fire(system, {"MAJ1": {"Axis": 1, "Speed": 0.0}, "MAJ2": {"Axis": 2, "Speed": -0.0}})
    same(systems[0], systems[1], "zeros")
    targets = [p.target_velocity for p in systems[0].ctl.axis(2).processes]
    assert [bits(t) for t in targets] == [bits(-0.0)]


def test_a_jog_after_a_group_stop_in_the_same_scan_is_refused() -> None:
    """MAJ1 jogs axis 1, MGS1 then stops group 1, MAJ7 asks axis 2 for a jog in the same
    scan: the group is stopping, so MAJ7 is refused with ERR 78 (not allowed while
    stopping), as one by one; MAJ1's jog had started before the stop."""
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        fire(system, {
            "MAJ1": {"Axis": 1, "Speed": 50.0},
            "MGS1": {"Group": 1, "StopMode": 1},
            "MAJ7": {"Axis": 2, "Speed": 50.0},
        })  # fmt: skip
    same(systems[0], systems[1], "group stop")
    out = {name: systems[0][name].outputs for name in ("MAJ1", "MAJ7")}
    assert out["MAJ1"]["DN"] and not out["MAJ1"]["ER"]
    assert out["MAJ7"]["ER"] and out["MAJ7"]["ERR"] == ErrorCode.NOT_ALLOWED_WHILE_STOPPING


def test_a_group_stop_after_a_refused_jog_is_seen_by_the_next_jog() -> None:
    """MAJ1 gives its speed in master units and its rates per second: refused with ERR
    105 (MDSC invalid mode) when planned, after its axis checks found the group not
    stopping; MGS1 stops the group; MAJ7 in the same scan is refused with ERR 78, as one
    by one (what MAJ1 learnt about the group is not kept past the stop)."""
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        fire(system, {
            "MAJ1": {"Axis": 1, "Speed": 50.0, "SpeedUnits": 4, "AccelUnits": 0},
            "MGS1": {"Group": 1, "StopMode": 1},
            "MAJ7": {"Axis": 2, "Speed": 50.0},
        })  # fmt: skip
    same(systems[0], systems[1], "group stop")
    out = {name: systems[0][name].outputs for name in ("MAJ1", "MAJ7")}
    assert out["MAJ1"]["ER"]
    assert out["MAJ1"]["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
    assert out["MAJ7"]["ER"] and out["MAJ7"]["ERR"] == ErrorCode.NOT_ALLOWED_WHILE_STOPPING


class _Broken(Exception):
    """An unexpected exception (a bug), raised by the instance below."""


def test_an_instance_that_raises_while_writing_its_status_is_contained() -> None:
    """MAJ2 raises as it follows the jog it started (a bug in its status code): it shows
    ERR 1005 (internal error) and its axis is stopped; MAJ1 and MAJ3, batched with it,
    show their jogs; everything as one by one, where the same instance is contained."""
    maj = instruction_type("MAJ")

    def raising(self: Any, *args: Any, **kwargs: Any) -> None:
        raise _Broken(self.name)

    broken = type("BrokenMAJ", (maj,), {"started": raising, "started_active": raising})
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        old = system.instances["MAJ2"]
        inst = broken("MAJ2", system.ctl)
        inst.inputs.woken = old.inputs.woken
        inst.outputs.changed = old.outputs.changed
        system.instances["MAJ2"] = inst
        fire(system, {f"MAJ{k}": {"Axis": k, "Speed": 50.0} for k in (1, 2, 3)})
        assert [name for name, _ in system.internal_errors] == ["MAJ2"]
        for _ in range(5):
            system.cycle()
    same(systems[0], systems[1], "contained")
    out = {name: systems[0][name].outputs for name in ("MAJ1", "MAJ2", "MAJ3")}
    assert out["MAJ2"]["ER"] and out["MAJ2"]["ERR"] == ErrorCode.INTERNAL_ERROR
    for name in ("MAJ1", "MAJ3"):
        assert out[name]["DN"] and out[name]["IP"] and not out[name]["ER"], name


def set_moving(systems: list[MotionSystem], jog: dict[str, Any]) -> None:
    """MAJ1..3 jog axes 1..3 at 50 units/s (with ``jog``'s operands too), MAG1 gears
    axis 5 to axis 1; 60 cycles, the batched and the one-by-one system compared after
    each."""
    for system in systems:
        for k, name in enumerate(("MAJ1", "MAJ2", "MAJ3")):
            system[name].inputs.update({"Axis": k + 1, "Speed": 50.0, **jog, "Execute": True})
        system["MAG1"].inputs.update({"SlaveAxis": 5, "MasterAxis": 1, "Execute": True})
    for k in range(60):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("start", k))


def test_halts_of_one_scan_are_planned_in_one_call() -> None:
    """MAJ1..3 jog axes 1..3 at 50 units/s (reached at 500 units/s² in 100 ms), MAG1
    gears axis 5 to axis 1. Then MC_Halt1
    and MC_Halt2 halt axes 1 and 2 in one scan (Deceleration 250, and 500 limited to
    the axes' maximum of 400 units/s²): one ``stop_many`` with both halts, planned as
    one batch, and outputs and motion as one by one. The axes halt in DiscreteMotion,
    not Stopping. 50 units/s at 250 and 400 units/s² take 200 and 125 ms: after 110
    cycles of 2 ms both halts are Done and the axes rest; axis 5 stays geared to axis
    1; a new MAJ on axis 1 is accepted (nothing holds it Stopping)."""
    systems = [build(batch, True) for batch in (True, False)]
    calls: list[tuple[int, bool]] = []
    ctl = systems[0].ctl
    stop_many = ctl.stop_many

    def spy(axes: Any, decelerations: Any, owners: Any, halt: bool = False) -> Any:
        calls.append((len(axes), ctl._stops_as_batch(axes, decelerations)))
        assert halt
        return stop_many(axes, decelerations, owners, halt=halt)

    ctl.stop_many = spy  # type: ignore[method-assign]
    set_moving(systems, {"AccelRate": 500.0})
    halts = {
        "MC_Halt1": {"Axis": 1, "Deceleration": 250.0},
        "MC_Halt2": {"Axis": 2, "Deceleration": 500.0},
    }
    for system in systems:
        fire(system, halts)
    same(systems[0], systems[1], "the cycle of the halts")
    assert calls == [(2, True)]
    for name, n in (("MC_Halt1", 1), ("MC_Halt2", 2)):
        out = systems[0][name].outputs
        assert out["Busy"] and out["Active"] and not out["Done"], name
        ax = systems[0].ctl.axis(n)
        assert ax.plcopen_state == PLCopenState.DISCRETE_MOTION and not ax.stopping, n
    for k in range(110):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("halting", k))
    for name, n in (("MC_Halt1", 1), ("MC_Halt2", 2)):
        out = systems[0][name].outputs
        assert out["Done"] and not out["Busy"], name
        ax = systems[0].ctl.axis(n)
        assert ax.command_velocity == 0.0 and ax.plcopen_state == PLCopenState.STANDSTILL
    assert systems[0].ctl.axis(3).command_velocity == 50.0  # not halted
    assert systems[0].ctl.axis(5).plcopen_state == PLCopenState.SYNCHRONIZED_MOTION
    for system in systems:
        system["MAJ1"].inputs["Execute"] = False
        system.cycle()
        fire(system, {"MAJ1": {"Axis": 1, "Speed": 20.0}})
    same(systems[0], systems[1], "a jog after the halts")
    assert systems[0]["MAJ1"].outputs["IP"] and not systems[0]["MAJ1"].outputs["ER"]


def test_velocity_blocks_of_one_scan_start_their_jogs_in_one_call() -> None:
    """MAM1 moves axis 2 towards 25.5 units. Then MC_MoveVelocity1 and 2 ask axes 1 and
    2 for 20 units/s, positive and negative, at 500 units/s² (aborting, the default): one
    ``start_jogs`` call with both jogs, replacing every process (``replace=None``): the
    move on axis 2 is aborted. Outputs and motion as one by one; InVelocity once both
    are at speed: 20 units/s at 500 units/s² from rest is 40 ms, from axis 2's velocity
    in the positive direction more, all within 100 cycles of 2 ms."""
    systems = [build(batch, True) for batch in (True, False)]
    calls: list[tuple[int, Any]] = []
    ctl = systems[0].ctl
    start_jogs = ctl.start_jogs

    def spy(axes: Any, *args: Any, **kwargs: Any) -> Any:
        calls.append((len(axes), kwargs.get("replace", "JOG")))
        return start_jogs(axes, *args, **kwargs)

    ctl.start_jogs = spy  # type: ignore[method-assign]
    for system in systems:
        system["MAM1"].inputs.update({"Axis": 2, "Position": 25.5, "Speed": 10.0})
        system["MAM1"].inputs["Execute"] = True
    for k in range(20):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("move", k))
    assert systems[0].ctl.axis(2).command_velocity > 0.0
    jog = {"Velocity": 20.0, "Acceleration": 500.0, "Deceleration": 400.0}
    for system in systems:
        fire(system, {
            "MC_MoveVelocity1": {"Axis": 1, "Direction": 1, **jog},
            "MC_MoveVelocity2": {"Axis": 2, "Direction": 3, **jog},
        })  # fmt: skip
    same(systems[0], systems[1], "the cycle of the jogs")
    assert calls == [(2, None)]
    assert systems[0]["MAM1"].outputs["IP"] is False
    for k in range(100):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("jogging", k))
    for name in ("MC_MoveVelocity1", "MC_MoveVelocity2"):
        out = systems[0][name].outputs
        assert out["Busy"] and out["Active"] and out["InVelocity"], name
    assert systems[0].ctl.axis(1).command_velocity == 20.0
    assert systems[0].ctl.axis(2).command_velocity == -20.0


def test_velocity_blocks_with_zero_and_minus_zero_keep_their_signs() -> None:
    """Two MC_MoveVelocity in one scan with equal operands but Velocity 0.0 and -0.0
    (equal values, one key for the judge): their jogs' targets are +0.0 and -0.0, as
    each block alone builds them (``sign * speed``), not one target worked out once."""
    systems = [build(batch, True) for batch in (True, False)]
    for system in systems:
        fire(system, {
            "MC_MoveVelocity1": {"Axis": 1, "Velocity": 0.0, "Direction": 1},
            "MC_MoveVelocity2": {"Axis": 2, "Velocity": -0.0, "Direction": 1},
        })  # fmt: skip
    same(systems[0], systems[1], "the cycle of the jogs")
    targets = [systems[0].ctl.axis(n).processes[0].target_velocity for n in (1, 2)]
    assert [struct.pack("<d", t) for t in targets] == [bits(0.0), bits(-0.0)]


def test_stops_of_one_scan_are_planned_in_one_call() -> None:
    """MAJ1..3 jog axes 1..3 at 50 units/s, MAG1 gears axis 5 to axis 1. Then MAS1, MAS2,
    MC_Stop1 and MAS3 stop all motion of axes 1, 2, 3 and 5 in one scan (MAS2 at 250
    units/s² of its own, MC_Stop1 at 300): one ``stop_many`` with the four, planned as
    one batch, and outputs and motion as one by one. 50 units/s at 400, 250 and 300
    units/s² take 125, 200 and 167 ms: after 100 cycles of 2 ms, every MAS has completed
    (PC), MC_Stop1 is Done and holds axis 3 Stopping (Execute high), the axes rest."""
    systems = [build(batch, True) for batch in (True, False)]
    calls: list[tuple[int, bool]] = []
    ctl = systems[0].ctl
    stop_many = ctl.stop_many

    def spy(axes: Any, decelerations: Any, owners: Any) -> Any:
        calls.append((len(axes), ctl._stops_as_batch(axes, decelerations)))
        return stop_many(axes, decelerations, owners)

    ctl.stop_many = spy  # type: ignore[method-assign]
    set_moving(systems, {})
    stops = {
        "MAS1": {"Axis": 1},
        "MAS2": {"Axis": 2, "ChangeDecel": 1, "DecelRate": 250.0},
        "MC_Stop1": {"Axis": 3, "Deceleration": 300.0},
        "MAS3": {"Axis": 5},
    }
    masses = ("MAS1", "MAS2", "MAS3")
    for system in systems:
        fire(system, stops)
    same(systems[0], systems[1], "the cycle of the stops")
    assert calls == [(4, True)]
    for name in masses:
        out = systems[0][name].outputs
        assert out["DN"] and out["IP"] and not out["PC"], name
    mc_stop = systems[0]["MC_Stop1"].outputs
    assert mc_stop["Busy"] and mc_stop["Active"] and not mc_stop["Done"]
    for k in range(100):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("stopping", k))
    for name in masses:
        assert systems[0][name].outputs["PC"] and not systems[0][name].outputs["IP"], name
    assert mc_stop["Done"] and not mc_stop["Busy"]
    assert systems[0].ctl.axis(3).stop_latch is systems[0]["MC_Stop1"]
    for n in (1, 2, 3, 5):
        ax = systems[0].ctl.axis(n)
        assert ax.command_velocity == 0.0 and not ax.processes, n


def test_plcopen_moves_of_one_scan_start_in_one_call_and_abort_every_process() -> None:
    """MAJ1 jogs axis 1 at 20 units/s. Then MC_MoveRelative1 and 2 ask axes 1 and 2 for
    10 units at 50 units/s and 100 units/s² up and down (aborting, the default): one
    ``start_moves`` call with both moves, replacing every process (``replace=None``):
    the jog on axis 1 is aborted and its move starts from 20 units/s. MC_MoveAbsolute1
    and 2, next in the scan order with the same limits, join that call: they send axes
    3 and 4 to -10 and 25.5. Outputs and motion as one by one; every block Done,
    exactly on its target, within 1.2 s: the longest, 25.5 units, takes 0.5 s up, 0.01 s
    at speed and 0.5 s down."""
    systems = [build(batch, True) for batch in (True, False)]
    calls: list[tuple[int, Any]] = []
    ctl = systems[0].ctl
    start_moves = ctl.start_moves

    def spy(axes: Any, *args: Any) -> Any:
        calls.append((len(axes), args[-1]))
        return start_moves(axes, *args)

    ctl.start_moves = spy  # type: ignore[method-assign]
    for system in systems:
        fire(system, {"MAJ1": {"Axis": 1, "Speed": 20.0, "AccelRate": 100.0, "AccelUnits": 0}})
    for k in range(150):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("jog", k))
    assert systems[0].ctl.axis(1).command_velocity == 20.0
    start = systems[0].ctl.axis(1).command_position
    dynamics = {"Velocity": 50.0, "Acceleration": 100.0, "Deceleration": 100.0}
    for system in systems:
        fire(system, {
            "MC_MoveRelative1": {"Axis": 1, "Distance": 10.0, **dynamics},
            "MC_MoveRelative2": {"Axis": 2, "Distance": 10.0, **dynamics},
            "MC_MoveAbsolute1": {"Axis": 3, "Position": -10.0, **dynamics},
            "MC_MoveAbsolute2": {"Axis": 4, "Position": 25.5, **dynamics},
        })  # fmt: skip
    same(systems[0], systems[1], "the cycle of the moves")
    assert calls == [(4, None)]
    assert systems[0]["MAJ1"].outputs["IP"] is False
    for k in range(600):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("moving", k))
    ends = {"MC_MoveRelative1": (1, start + 10.0), "MC_MoveRelative2": (2, 10.0),
            "MC_MoveAbsolute1": (3, -10.0), "MC_MoveAbsolute2": (4, 25.5)}  # fmt: skip
    for name, (axis, position) in ends.items():
        assert systems[0][name].outputs["Done"], name
        assert systems[0].ctl.axis(axis).command_position == position, name


def test_gear_in_blocks_of_one_scan_start_in_one_call_and_abort_every_process() -> None:
    """MAJ1 and MAJ2 jog axes 1 and 2 at 20 units/s, MAJ3 jogs axis 4 at -5 units/s.
    Then MC_GearIn1..3 gear axes 4, 5 and 6 to axes 1, 2 and 1 at 1/2 (aborting, the
    default, trapezoidal catch-up at 100 units/s²): one ``start_gears`` call with the
    three gears, replacing every process (``replace=None``): axis 4's jog is aborted and
    its gear catches up from -5 units/s. The slaves reach 10 units/s within 0.15 s (from
    rest 0.1 s); after 0.4 s every block shows InGear. Outputs and motion as one by
    one."""
    systems = [build(batch, True) for batch in (True, False)]
    calls: list[tuple[int, Any]] = []
    ctl = systems[0].ctl
    start_gears = ctl.start_gears

    def spy(axes: Any, *args: Any) -> Any:
        calls.append((len(axes), args[-1]))
        return start_gears(axes, *args)

    ctl.start_gears = spy  # type: ignore[method-assign]
    jog = {"AccelRate": 100.0, "DecelRate": 100.0, "AccelUnits": 0, "DecelUnits": 0}
    for system in systems:
        fire(system, {
            "MAJ1": {"Axis": 1, "Speed": 20.0, **jog},
            "MAJ2": {"Axis": 2, "Speed": 20.0, **jog},
            "MAJ3": {"Axis": 4, "Speed": 5.0, "Direction": 1, **jog},
        })  # fmt: skip
    for k in range(150):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("jogs", k))
    gear = {"RatioNumerator": 1.0, "RatioDenominator": 2.0, "Acceleration": 100.0,
            "Deceleration": 100.0}  # fmt: skip
    for system in systems:
        fire(system, {
            "MC_GearIn1": {"Slave": 4, "Master": 1, **gear},
            "MC_GearIn2": {"Slave": 5, "Master": 2, **gear},
            "MC_GearIn3": {"Slave": 6, "Master": 1, **gear},
        })  # fmt: skip
    same(systems[0], systems[1], "the cycle of the gears")
    assert calls == [(3, None)]
    assert systems[0]["MAJ3"].outputs["IP"] is False
    for k in range(200):
        for system in systems:
            system.cycle()
        same(systems[0], systems[1], ("gearing", k))
    for name, axis in (("MC_GearIn1", 4), ("MC_GearIn2", 5), ("MC_GearIn3", 6)):
        out = systems[0][name].outputs
        assert out["Busy"] and out["Active"] and out["InGear"], name
        assert systems[0].ctl.axis(axis).command_velocity == 10.0, name
