"""MC_GearIn instances that fire in one scan and hand their gears to the kernel together
(``instructions/scan_pass.py``, ``Controller.start_gears`` replacing every process)
against the same scans executed instance by instance (``MotionSystem(batch=False)``).

The operands start valid, so that runs of gears fire together: random scans fire random
subsets of MC_GearIn, mixed with MAG (another kind of gear batch), MAJ (moving masters
and slaves, whose jogs the gears abort) and MC_Stop (which cuts a batch), with random
operands: two gears on one slave, a gear whose master is a slave geared in the same
scan, loops of masters (refused), a feedback-only master on its set value, ratios of
zero, catch-up rates too small or beyond the slave's maximum, jerk-limited catch-ups and
buffered blocks (executed alone), slaves that cannot move. After every cycle both
systems must show the same outputs on every instance, mark the same instances changed
and command the same position, velocity and acceleration, bit for bit, with the same
processes on every axis, lanes on and off.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings

from motion_server.instructions import MotionSystem

from .test_scan_batch import run_side_by_side, scan_plans, servo_system

#: axes 1..6 servo (on), 7 feedback only, 8 servo off; 9 does not exist
AXES = [1, 2, 3, 4, 5, 6, 1, 2, 3, 4, 5, 6, 7, 8, 9]
RATES = [100.0, 100.0, 250.0, 1e-30, 600.0]  # 600 is beyond the slaves' maximum
POOLS: dict[str, dict[str, list[Any]]] = {
    "MC_GearIn": {
        "Slave": AXES,
        "Master": AXES,
        "RatioNumerator": [0.5, 0.5, -2.0, 1.0, 0.0],
        "RatioDenominator": [1.0, 1.0, 3.0],
        "MasterValueSource": [0, 0, 1],
        "Acceleration": RATES,
        "Deceleration": RATES,
        "Jerk": [0.0, 0.0, 0.0, 100.0],
        "BufferMode": [0, 0, 0, 1],
    },
    "MAG": {"SlaveAxis": AXES, "MasterAxis": AXES, "Ratio": [0.5, 2.0], "Clutch": [0, 1]},
    "MAJ": {"Axis": AXES, "Direction": [0, 1], "Speed": [5.0, 50.0], "AccelRate": [100.0]},
    "MC_Stop": {"Axis": AXES, "Deceleration": [100.0]},
}
#: what every instance holds before the scans write to it (its axes set in ``build``)
START: dict[str, dict[str, Any]] = {
    "MC_GearIn": {"RatioNumerator": 0.5, "Acceleration": 100.0, "Deceleration": 100.0},
    "MAG": {"Ratio": 0.5, "Clutch": 0},
    "MAJ": {"Speed": 50.0, "AccelRate": 100.0},
    "MC_Stop": {"Deceleration": 100.0},
}
ORDER = [
    ("MAJ1", "MAJ"), ("MAJ2", "MAJ"), ("MC_GearIn1", "MC_GearIn"),
    ("MC_GearIn2", "MC_GearIn"), ("MC_GearIn3", "MC_GearIn"), ("MAG1", "MAG"),
    ("MC_GearIn4", "MC_GearIn"), ("MC_GearIn5", "MC_GearIn"), ("MC_Stop1", "MC_Stop"),
    ("MC_GearIn6", "MC_GearIn"),
]  # fmt: skip
#: (slave, master) each gear starts with: slaves 3..6 on masters 1 and 2
PAIRS = [(3, 1), (4, 2), (5, 1), (6, 2), (3, 2), (4, 1)]


def build(batch: bool, lanes: bool) -> MotionSystem:
    system = servo_system(batch, lanes)
    gears = iter(PAIRS)
    for k, (name, type_name) in enumerate(ORDER):
        inst = system.add(type_name, name)
        inst.inputs.update(START[type_name])
        if type_name == "MC_GearIn":
            inst.inputs["Slave"], inst.inputs["Master"] = next(gears)
        elif type_name == "MAG":
            inst.inputs.update({"SlaveAxis": 5, "MasterAxis": 2})
        else:
            inst.inputs["Axis"] = 1 + k % 2
    return system


@pytest.mark.parametrize("lanes", [True, False])
@settings(max_examples=150, deadline=None)
@given(plan=scan_plans(ORDER, POOLS, 5))
def test_a_scan_with_gear_in_batches_acts_as_one_instance_at_a_time(
    lanes: bool, plan: list[list[tuple[str, dict[str, Any], bool]]]
) -> None:
    run_side_by_side(build, lanes, plan)
