"""MC_Power: level-sensitive as PLCopen Part 1 states it ("As long as 'Enable' is true,
power is being enabled"; called with Enable = true in Disabled, the axis goes to
StandStill), so a reset under a held Enable re-enables the axis; a deliberate disable by
another instruction (MSF, an MGS Fast Disable) is not undone."""

from __future__ import annotations

import pytest

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    ErrorCode,
    PLCopenState,
)

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


def enabled_and_faulted() -> tuple[MotionSystem, Instruction]:
    """Enable held high, then a drive fault: ErrorStop, Status FALSE, Error 20."""
    system, power = system_with_power()
    power.inputs["Enable"] = True
    system.cycle()
    ax = system.ctl.axis(1)
    assert ax.plcopen_state == PLCopenState.STANDSTILL and power.outputs["Status"]
    system.ctl.fault(ax, AxisFault.POSITION_ERROR)
    system.cycle()
    assert ax.plcopen_state == PLCopenState.ERRORSTOP
    assert not power.outputs["Status"]
    assert power.outputs["Error"] and power.outputs["ErrorID"] == ErrorCode.AXIS_FAULTED
    return system, power


@pytest.mark.parametrize("reset_type", ["MC_Reset", "MAFR", "MASR", "MGSR"])
def test_a_reset_under_a_held_enable_brings_the_axis_to_standstill(reset_type: str) -> None:
    system, power = enabled_and_faulted()
    ax = system.ctl.axis(1)
    operands = {"Group": 1} if reset_type == "MGSR" else {"Axis": 1}
    reset = system.add(reset_type, f"{reset_type}_1", operands)
    reset.inputs["Execute"] = True
    # MC_Power is scanned before the reset block: it acts in the next scan at the latest
    system.cycle(2)
    assert ax.state == AxisState.SERVO_CONTROL
    assert ax.plcopen_state == PLCopenState.STANDSTILL
    assert power.outputs["Status"] and power.outputs["Valid"] and power.outputs["Busy"]
    assert not power.outputs["Error"] and power.outputs["ErrorID"] == 0


def test_a_shutdown_reset_under_a_held_enable_re_enables() -> None:
    system, power = system_with_power()
    power.inputs["Enable"] = True
    system.cycle()
    ax = system.ctl.axis(1)
    system.ctl.shutdown(ax)
    system.cycle()
    assert ax.state == AxisState.AXIS_SHUTDOWN and not power.outputs["Status"]
    masr = system.add("MASR", "MASR_1", {"Axis": 1})
    masr.inputs["Execute"] = True
    system.cycle(2)
    assert ax.state == AxisState.SERVO_CONTROL and power.outputs["Status"]


def test_a_reset_with_enable_low_leaves_the_axis_disabled() -> None:
    system, power = enabled_and_faulted()
    power.inputs["Enable"] = False
    system.cycle()
    reset = system.add("MC_Reset", "MC_Reset_1", {"Axis": 1})
    reset.inputs["Execute"] = True
    system.cycle(5)
    ax = system.ctl.axis(1)
    assert ax.plcopen_state == PLCopenState.DISABLED and not power.outputs["Status"]


def test_a_held_enable_does_not_undo_msf() -> None:
    system, power = system_with_power()
    power.inputs["Enable"] = True
    system.cycle()
    msf = system.add("MSF", "MSF_1", {"Axis": 1})
    trigger(system, msf)
    system.cycle(5)
    assert system.ctl.axis(1).state == AxisState.AXIS_READY and not power.outputs["Status"]


def test_a_held_enable_wakes_with_the_sleeping_optimisation_off_and_on() -> None:
    """The same trace whether idle instances sleep or not (the reference)."""
    states = []
    for sleep in (True, False):
        system, power = enabled_and_faulted()
        system.sleep = sleep
        reset = system.add("MC_Reset", "MC_Reset_1", {"Axis": 1})
        reset.inputs["Execute"] = True
        seen = []
        for _ in range(4):
            system.cycle()
            seen.append((int(system.ctl.axis(1).state), bool(power.outputs["Status"])))
        states.append(seen)
    assert states[0] == states[1]
    assert states[0][-1] == (int(AxisState.SERVO_CONTROL), True)
