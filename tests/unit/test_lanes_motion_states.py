"""Every motion state in the fast lanes gives the reference's motion bit for bit: random
mixes of starts, stops, reversals, catch-ups, gears, additive and superimposed moves and
overrides re-planning them (trapezoidal profiles, stop ramps of every kind, clutch and
PLCopen catch-up ramps, real and fraction gears on command and actual positions),
compared with ``Controller(lanes=False)`` after every cycle."""

from __future__ import annotations

from collections import Counter

from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.instructions.schema import Kind, Operand

from .test_lanes import PREAMBLE, assert_same, pair, run_pair, value

Script = list[tuple[str, dict[str, object], int]]

RATES = st.sampled_from([200.0, 1000.0, 5000.0, 20_000.0])
OVERRIDES: dict[str, st.SearchStrategy[object]] = {
    "Speed": st.sampled_from([10.0, 50.0, 100.0, 250.0]) | st.floats(1.0, 300.0),
    "Velocity": st.sampled_from([10.0, 50.0, 100.0, 250.0]) | st.floats(1.0, 300.0),
    "AccelRate": RATES,
    "DecelRate": RATES,
    "Acceleration": RATES,
    "Deceleration": RATES,
    "Jerk": st.sampled_from([0.0, 0.0, 0.0, 1e5]),
    "Profile": st.sampled_from([0, 0, 0, 1]),
    "Position": st.floats(-150.0, 150.0),
    "Distance": st.floats(-150.0, 150.0),
    "VelocityDiff": st.sampled_from([10.0, 50.0, 100.0]) | st.floats(1.0, 150.0),
    "Ratio": st.sampled_from([0.5, 1.0, -2.0, 0.3, 1.7]),
    "RatioNumerator": st.sampled_from([1.0, -1.0, 2.0, 0.5]),
    "RatioDenominator": st.sampled_from([1.0, 2.0, 3.0]),
    "SlaveCounts": st.integers(1, 9),
    "MasterCounts": st.integers(1, 9),
    "RatioFormat": st.sampled_from([0, 1]),
    "Clutch": st.sampled_from([0, 1]),
    "MasterReference": st.sampled_from([0, 1]),
    "MasterValueSource": st.sampled_from([0, 1]),
    "SpeedUnits": st.sampled_from([0, 0, 0, 1]),
    "AccelUnits": st.sampled_from([0, 0, 0, 1]),
    "DecelUnits": st.sampled_from([0, 0, 0, 1]),
    "StopType": st.integers(0, 3),
    "StopMode": st.integers(0, 2),
    "ChangeDecel": st.sampled_from([0, 1]),
    "Merge": st.sampled_from([0, 0, 1]),
    "BufferMode": st.sampled_from([0, 0, 1]),
    "MoveType": st.sampled_from([0, 1]),
    "VelFactor": st.sampled_from([0.0, 0.25, 0.5, 1.0]) | st.floats(0.0, 1.0),
    "AccFactor": st.sampled_from([0.5, 1.0, 0.1]) | st.floats(0.01, 1.0),
    "JerkFactor": st.sampled_from([1.0, 0.5]),
}

TYPES = (
    "MAJ", "MAJ", "MAJ", "MAM", "MAM", "MAS", "MGS", "MAG", "MAG", "MCD", "MSO",
    "MC_GearIn", "MC_Halt", "MC_Stop", "MC_MoveVelocity", "MC_MoveAbsolute", "MC_MoveRelative",
    "MC_MoveAdditive", "MC_MoveSuperimposed", "MC_SetOverride", "MC_SetOverride",
)  # fmt: skip


def operand(op: Operand) -> st.SearchStrategy[object]:
    if op.kind == Kind.AXIS:
        return st.integers(1, 6) if "Master" in op.name else st.integers(1, 5)
    return OVERRIDES.get(op.name, value(op))


@st.composite
def command(draw: st.DrawFn) -> tuple[str, dict[str, object], int]:
    type_name = draw(st.sampled_from(TYPES))
    cls = instruction_type(type_name)
    ops = {op.name: draw(operand(op)) for op in cls.OPERANDS}
    if "Group" in ops:
        ops["Group"] = 1
    if type_name == "MAJ":
        ops["Direction"] = draw(st.sampled_from([0, 1]))  # reversals
    return type_name, ops, draw(st.integers(1, 80))


@settings(max_examples=120, deadline=None)
@given(script=st.lists(command(), min_size=1, max_size=10))
def test_random_starts_stops_reversals_catch_ups_and_gears_match_the_reference(
    script: Script,
) -> None:
    fast, ref = pair()
    run_pair(fast, ref, PREAMBLE, prefix="P")
    run_pair(fast, ref, script)


def run_recording(fast: MotionSystem, ref: MotionSystem, script: Script) -> Counter[str]:
    """``run_pair``, counting the lanes the fast system's processes were in."""
    seen: Counter[str] = Counter()
    for i, (type_name, ops, cycles) in enumerate(script):
        for s in (fast, ref):
            inst = s.add(type_name, f"R{i}", {})
            inst.inputs.update(ops)
            inst.inputs[inst.TRIGGER] = True
        for k in range(cycles + 1):
            if k == 1:
                for s in (fast, ref):
                    s.instances[f"R{i}"].inputs[s.instances[f"R{i}"].TRIGGER] = False
            fast.cycle()
            ref.cycle()
            assert_same(fast, ref, f"R{i} ({type_name}), cycle {k}")
            for ax in fast.ctl.axes:
                for p in ax.processes:
                    if p.lane is not None:
                        seen[type(p.lane).__name__] += 1
    return seen


def test_each_motion_state_runs_in_its_lane_and_matches_the_reference() -> None:
    """A scripted tour of every lane: accelerating and reversing jogs, moves, catch-ups on
    both references, fraction gears, a MAS and a group stop."""
    fast, ref = pair()
    slow = {"AccelRate": 500.0, "DecelRate": 800.0}
    script: Script = [
        ("MAJ", {"Axis": 1, "Speed": 100.0, **slow}, 60),  # from rest: ProfileLane
        ("MAJ", {"Axis": 2, "Direction": 1, "Speed": 60.0, **slow}, 30),
        ("MAG", {"SlaveAxis": 3, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 0, "AccelRate": 300.0, "AccelUnits": 0}, 80),  # CatchUpLane
        ("MAG", {"SlaveAxis": 4, "MasterAxis": 2, "RatioFormat": 1, "SlaveCounts": 3,
                 "MasterCounts": 7, "MasterReference": 0, "Clutch": 1}, 40),  # FractionLane
        ("MC_GearIn", {"Master": 1, "Slave": 5, "RatioNumerator": -2.0,
                       "RatioDenominator": 3.0, "MasterValueSource": 1,
                       "Acceleration": 400.0, "Deceleration": 600.0}, 120),
        ("MAJ", {"Axis": 1, "Direction": 1, "Speed": 80.0, **slow}, 150),  # reversal
        ("MAM", {"Axis": 2, "MoveType": 1, "Position": 12.5, "Speed": 40.0, **slow}, 90),
        ("MAS", {"Axis": 1, "StopType": 0, "ChangeDecel": 1, "DecelRate": 700.0}, 60),
        ("MAJ", {"Axis": 1, "Speed": 100.0, **slow}, 60),
        ("MGS", {"Group": 1, "StopMode": 1}, 200),  # StopLane for every axis
    ]  # fmt: skip
    seen = run_recording(fast, ref, script)
    for lane in ("ProfileLane", "CruiseLane", "StopLane", "CatchUpLane", "FractionLane",
                 "GearLane"):  # fmt: skip
        assert seen[lane] > 10, (lane, seen)
    for name, inst in fast.instances.items():
        assert not inst.outputs.get("ER", False), name
        assert not inst.outputs.get("Error", False), name


#: jerk-limited variants of the operands: every profile an S-curve, jerks in units/s³
S_CURVE: dict[str, st.SearchStrategy[object]] = {
    "Profile": st.just(1),
    "Jerk": st.sampled_from([2e4, 1e5, 1e6]) | st.floats(1e3, 1e6),
    "AccelJerk": st.sampled_from([2e4, 1e5]) | st.floats(1e3, 1e6),
    "DecelJerk": st.sampled_from([2e4, 1e5]) | st.floats(1e3, 1e6),
    "JerkUnits": st.just(0),
    "ChangeDecelJerk": st.sampled_from([0, 1]),
    "ChangeAccelJerk": st.sampled_from([0, 1]),
}


@st.composite
def s_curve_command(draw: st.DrawFn) -> tuple[str, dict[str, object], int]:
    type_name, ops, cycles = draw(command())
    cls = instruction_type(type_name)
    for op in cls.OPERANDS:
        if op.name in S_CURVE:
            ops[op.name] = draw(S_CURVE[op.name])
    return type_name, ops, cycles


@settings(max_examples=60, deadline=None)
@given(script=st.lists(s_curve_command(), min_size=1, max_size=10))
def test_random_jerk_limited_commands_match_the_reference(script: Script) -> None:
    """The same mixes with every profile jerk-limited: jogs, speed changes, MCD, paused
    moves and jerk-limited stops on their closed-form S-curves (``SCurveLane``)."""
    fast, ref = pair()
    run_pair(fast, ref, PREAMBLE, prefix="P")
    run_pair(fast, ref, script)


def test_jerk_limited_ramps_run_in_their_lane_and_match_the_reference() -> None:
    """A scripted tour of the S-curve lane: jogs from rest and reversing, a speed change by
    MCD in the middle of a ramp, a jerk-limited MAS, MC_MoveVelocity and MC_Halt, a
    follower geared to an S-curve master (it stays in its lane)."""
    fast, ref = pair()
    s_curve = {"Profile": 1, "AccelJerk": 20_000.0, "DecelJerk": 10_000.0, "JerkUnits": 0}
    slow = {"AccelRate": 500.0, "DecelRate": 800.0, **s_curve}
    script: Script = [
        ("MAJ", {"Axis": 1, "Speed": 100.0, **slow}, 40),
        ("MAG", {"SlaveAxis": 3, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 1}, 60),
        ("MAJ", {"Axis": 2, "Direction": 1, "Speed": 60.0, **slow}, 20),
        ("MCD", {"Axis": 2, "MotionType": 0, "ChangeSpeed": 1, "Speed": 150.0,
                 "ChangeAccel": 1, "AccelRate": 900.0}, 80),
        ("MAJ", {"Axis": 1, "Direction": 1, "Speed": 80.0, **slow}, 150),  # reversal
        ("MAS", {"Axis": 2, "StopType": 0, "ChangeDecel": 1, "DecelRate": 700.0,
                 "ChangeDecelJerk": 1, "DecelJerk": 5_000.0, "JerkUnits": 0}, 120),
        ("MC_MoveVelocity", {"Axis": 5, "Velocity": 40.0, "Acceleration": 400.0,
                             "Deceleration": 600.0, "Jerk": 8_000.0}, 80),
        ("MC_Halt", {"Axis": 5, "Deceleration": 300.0, "Jerk": 4_000.0}, 150),
    ]  # fmt: skip
    seen = run_recording(fast, ref, script)
    assert seen["SCurveLane"] > 100, seen
    assert seen["GearLane"] > 10, seen
    for name, inst in fast.instances.items():
        assert not inst.outputs.get("ER", False), name
        assert not inst.outputs.get("Error", False), name
