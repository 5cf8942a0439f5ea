"""MC_Power switches the power stage on the edges of Enable and never fights other
instructions over it between edges."""

from __future__ import annotations

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import AxisConfig, AxisState, AxisType

from ..support import make_system, trigger


def system_with_power() -> tuple[MotionSystem, Instruction]:
    system = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.SERVO,
            max_velocity=100.0,
            max_acceleration=1000.0,
            max_deceleration=1000.0,
        )
    )
    power = system.add("MC_Power", "MC_Power_1", {"Axis": 1})
    return system, power


def test_an_idle_mc_power_leaves_an_axis_enabled_by_mso_alone() -> None:
    system, power = system_with_power()
    mso = system.add("MSO", "MSO_1", {"Axis": 1})
    trigger(system, mso)
    system.cycle(10)  # Enable stays low the whole time
    assert system.ctl.axis(1).state == AxisState.SERVO_CONTROL
    assert not power.outputs["Error"] and power.outputs["Status"]


def test_a_held_enable_does_not_undo_a_fast_disable_stop() -> None:
    system, power = system_with_power()
    power.inputs["Enable"] = True
    system.cycle()
    assert system.ctl.axis(1).state == AxisState.SERVO_CONTROL
    mgs = system.add("MGS", "MGS_1", {"Group": 1, "StopMode": 2})  # fast disable
    trigger(system, mgs)
    system.cycle(20)
    assert mgs.outputs["PC"]
    assert system.ctl.axis(1).state == AxisState.AXIS_READY
    assert not power.outputs["Status"]
    power.inputs["Enable"] = False
    system.cycle()
    power.inputs["Enable"] = True
    system.cycle()
    assert system.ctl.axis(1).state == AxisState.SERVO_CONTROL and power.outputs["Status"]


def test_a_falling_edge_switches_the_drive_off() -> None:
    system, power = system_with_power()
    power.inputs["Enable"] = True
    system.cycle()
    power.inputs["Enable"] = False
    system.cycle()
    assert system.ctl.axis(1).state == AxisState.AXIS_READY
    assert not power.outputs["Busy"] and not power.outputs["Status"]
