"""MAM, MC_MoveAbsolute and MC_MoveRelative instances that fire in one scan and hand their
moves to the kernel together (``instructions/scan_pass.py``,
``Controller.start_moves``) against the same scans executed instance by instance
(``MotionSystem(batch=False)``).

The operands are mostly valid, so that runs of one type fire together: random scans fire
random subsets of the moves, mixed with MAJ (moving some axes, whose moves then inherit
their velocity or superimpose on the jog) and MAS (which cut a batch), on a linear and a
rotary axis (the ways round, a target outside the turn), with incremental, absolute and
rotary MAM, Merge (executed alone), S-curve profiles (not copied), buffered blocks
(executed alone), slow rates that the kernel refuses to plan for the long moves, axes
that cannot move. After every cycle both systems must show the same outputs on every
instance, mark the same instances changed and command the same position, velocity and
acceleration, bit for bit, with the same processes on every axis, lanes on and off.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType

from .test_scan_batch import run_side_by_side, scan_plans, servo_system

#: axes 1..5 linear servos, 6 a rotary servo (360 units a turn), 8 off; 9 does not exist
AXES = [1, 2, 3, 4, 5, 6, 1, 2, 3, 4, 6, 8, 9]
#: 1e-6 units/s² up and down: one unit is a 2,000 s triangle, 100 units one of 20,000 s
#: (refused: longer than the kernel plans)
RATES = [100.0, 100.0, 250.0, 1e-6]
POOLS: dict[str, dict[str, list[Any]]] = {
    "MAM": {
        "Axis": AXES,
        "MoveType": [1, 1, 0, 2, 3, 4],
        "Position": [1.0, 100.0, 25.5, 25.5, -10.0, 400.0],
        "Speed": [50.0, 50.0, 200.0],
        "AccelRate": RATES,
        "DecelRate": RATES,
        "Profile": [0, 0, 0, 1],
        "AccelJerk": [100.0],
        "DecelJerk": [100.0],
        "JerkUnits": [2],
        "Merge": [0, 0, 0, 1],
    },
    "MC_MoveRelative": {
        "Axis": AXES,
        "Distance": [1.0, 100.0, 25.5, 25.5, -10.0],
        "Velocity": [50.0, 50.0, 200.0],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "BufferMode": [0, 0, 0, 1],
    },
    "MC_MoveAbsolute": {
        "Axis": AXES,
        "Position": [1.0, 100.0, 25.5, 25.5, -10.0, 400.0],
        "Velocity": [50.0, 50.0, 200.0],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "Direction": [1, 2, 2, 3, 4],
        "BufferMode": [0, 0, 0, 1],
    },
    "MAJ": {"Axis": AXES, "Direction": [0, 1], "Speed": [5.0, 50.0], "AccelRate": [100.0]},
    "MAS": {"Axis": AXES, "StopType": [0, 1, 2]},  # all, jog, move
}
#: what every instance holds before the scans write to it
START: dict[str, dict[str, Any]] = {
    "MAM": {"MoveType": 1, "Position": 25.5, "Speed": 50.0, "AccelRate": 100.0,
            "DecelRate": 100.0},
    "MC_MoveRelative": {"Distance": 25.5, "Velocity": 50.0, "Acceleration": 100.0,
                        "Deceleration": 100.0},
    "MC_MoveAbsolute": {"Position": 25.5, "Velocity": 50.0, "Acceleration": 100.0,
                        "Deceleration": 100.0},
    "MAJ": {"Speed": 50.0, "AccelRate": 100.0},
    "MAS": {"StopType": 0},
}  # fmt: skip
ORDER = [
    ("MAJ1", "MAJ"), ("MAM1", "MAM"), ("MAM2", "MAM"), ("MAM3", "MAM"),
    ("MC_MoveRelative1", "MC_MoveRelative"), ("MC_MoveRelative2", "MC_MoveRelative"),
    ("MC_MoveAbsolute1", "MC_MoveAbsolute"), ("MC_MoveRelative3", "MC_MoveRelative"),
    ("MC_MoveAbsolute2", "MC_MoveAbsolute"), ("MC_MoveAbsolute3", "MC_MoveAbsolute"),
    ("MAS1", "MAS"), ("MAM4", "MAM"), ("MAM5", "MAM"), ("MAJ2", "MAJ"),
    ("MC_MoveAbsolute4", "MC_MoveAbsolute"), ("MC_MoveAbsolute5", "MC_MoveAbsolute"),
]  # fmt: skip


def build(batch: bool, lanes: bool) -> MotionSystem:
    axes = [
        AxisConfig(n, f"A{n}", AxisType.SERVO, max_velocity=1000.0, max_acceleration=500.0,
                   max_deceleration=400.0, max_jerk=20000.0,
                   rollover=360.0 if n == 6 else 0.0)
        for n in range(1, 7)
    ] + [AxisConfig(8, "A8", AxisType.SERVO)]  # fmt: skip
    system = servo_system(batch, lanes, axes)
    for k, (name, type_name) in enumerate(ORDER):
        inst = system.add(type_name, name)
        # valid operands to start from, each instance on an axis of its own in its run
        inst.inputs.update(START[type_name])
        inst.inputs["Axis"] = 1 + k % 6
    return system


@pytest.mark.parametrize("lanes", [True, False])
@settings(max_examples=150, deadline=None)
@given(plan=scan_plans(ORDER, POOLS, 6))
def test_a_scan_with_move_batches_acts_as_one_instance_at_a_time(
    lanes: bool, plan: list[list[tuple[str, dict[str, Any], bool]]]
) -> None:
    run_side_by_side(build, lanes, plan)
