"""PLCopen stops, halts and gears against the axis maxima (docs/semantics.md).

Servo Axis1: max velocity 200 mm/s, max acceleration 2000 mm/s², max deceleration 1000
mm/s², dt 2 ms. A stop or halt asked steeper than the axis may brake is limited to the
maximum deceleration (never refused: refusing would leave the axis moving): from 100
mm/s it takes 100 / 1000 = 0.1 s = 50 cycles, not the 10 cycles 5000 mm/s² would give. A
gear's catch-up beyond the slave's maxima is refused (ErrorID 13), as every motion
command's dynamics are.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, ErrorCode

from ..support import make_system, trigger

DT = 0.002


def rig() -> MotionSystem:
    cfg = {"max_velocity": 200.0, "max_acceleration": 2000.0, "max_deceleration": 1000.0}
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.VIRTUAL, **cfg),  # type: ignore[arg-type]
        AxisConfig(2, "Axis2", AxisType.VIRTUAL, **cfg),  # type: ignore[arg-type]
        period=DT,
    )
    for n in (1, 2):
        power = system.add("MC_Power", f"Power{n}", {"Axis": n})
        power.inputs["Enable"] = True
    vel = system.add(
        "MC_MoveVelocity",
        "Vel",
        {"Axis": 1, "Velocity": 100.0, "Acceleration": 2000.0, "Deceleration": 1000.0},
    )
    trigger(system, vel)
    system.cycle(60)  # at 100 mm/s after 0.05 s
    assert system.ctl.axis(1).command_velocity == pytest.approx(100.0)
    return system


@pytest.mark.parametrize("type_name", ["MC_Stop", "MC_Halt"])
def test_a_stop_beyond_the_maximum_deceleration_brakes_at_the_maximum(type_name: str) -> None:
    system = rig()
    ax = system.ctl.axis(1)
    stop = system.add(type_name, "S", {"Axis": 1, "Deceleration": 5000.0})
    trigger(system, stop)
    assert stop.outputs["Busy"] and not stop.outputs["Error"]
    assert ax.command_velocity == pytest.approx(100.0 - 1000.0 * DT)
    system.cycle(48)
    assert ax.command_velocity == pytest.approx(2.0)
    system.cycle()
    assert ax.command_velocity == pytest.approx(0.0, abs=1e-9)
    system.cycle()
    assert stop.outputs["Done"]


@pytest.mark.parametrize(
    ("operand", "value"), [("Acceleration", 2000.5), ("Deceleration", 1500.0), ("Jerk", 1.0)]
)
def test_a_gear_in_beyond_the_slave_maxima_is_refused(operand: str, value: float) -> None:
    """max_jerk 0 is unlimited, so the Jerk case uses a slave whose maximum jerk is
    0.5 mm/s³ (Jerk 1 is beyond it)."""
    system = rig()
    if operand == "Jerk":
        slave = system.ctl.axis(2)
        slave.config = replace(slave.config, max_jerk=0.5)
        slave.system_config = slave.config
    gear = system.add(
        "MC_GearIn",
        "Gear",
        {"Master": 1, "Slave": 2, "RatioNumerator": 1.0, "RatioDenominator": 1.0,
         "Acceleration": 1000.0, "Deceleration": 1000.0, "Jerk": 0.0, operand: value},
    )  # fmt: skip
    trigger(system, gear)
    assert gear.outputs["Error"] and gear.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    system.cycle(10)
    assert system.ctl.axis(2).command_velocity == 0.0
    assert system.ctl.axis(2).command_position == 0.0


def test_a_gear_in_within_the_maxima_is_accepted() -> None:
    system = rig()
    gear = system.add(
        "MC_GearIn",
        "Gear",
        {"Master": 1, "Slave": 2, "RatioNumerator": 1.0, "RatioDenominator": 1.0,
         "Acceleration": 2000.0, "Deceleration": 1000.0},
    )  # fmt: skip
    trigger(system, gear)
    assert gear.outputs["Busy"] and not gear.outputs["Error"]
    system.cycle(60)  # catches up with 100 mm/s at 2000 mm/s² in 0.05 s
    assert gear.outputs["InGear"]
