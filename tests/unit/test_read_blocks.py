"""The Enable-style PLCopen read blocks: MC_ReadStatus, MC_ReadAxisError,
MC_ReadActualPosition, MC_ReadActualVelocity.

PLCopen Part 1: while Enable is high the block reads every cycle, Busy follows Enable,
Valid and Error are exclusive. Motion numbers from first principles on a virtual axis
(actual = command): a jog at a = 1000 mm/s² to v = 100 mm/s is at v = a·t for
t <= 0.1 s, x = a·t²/2 (5 mm at the end of the ramp), then x = 5 + 100 (t - 0.1).
"""

from __future__ import annotations

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisFault, AxisType, ErrorCode, PLCopenState
from motion_server.kernel.enums import HomeDirection, HomeMode, HomeSequence

from ..support import make_system, trigger

DT = 0.002
STATES = (
    "ErrorStop",
    "Disabled",
    "Stopping",
    "Homing",
    "Standstill",
    "DiscreteMotion",
    "ContinuousMotion",
    "SynchronizedMotion",
)


def rig() -> MotionSystem:
    system = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.VIRTUAL,
            max_velocity=100.0,
            max_acceleration=1000.0,
            max_deceleration=1000.0,
            home_mode=HomeMode.ACTIVE,
            home_sequence=HomeSequence.SWITCH,
            home_direction=HomeDirection.BIDIRECTIONAL_REVERSE,
            home_switch=25.0,
            home_switch_width=1.0,
            home_speed=10.0,
            home_return_speed=2.0,
        )
    )
    for name in ("MSO", "MAJ", "MAM", "MAS", "MAH", "MAFR", "MRP"):
        system.add(name, f"{name}_1", {"Axis": 1})
    for name in ("MC_ReadStatus", "MC_ReadAxisError", "MC_ReadActualPosition"):
        system.add(name, name, {"Axis": 1})
    system.add("MC_ReadActualVelocity", "MC_ReadActualVelocity", {"Axis": 1})
    return system


def enable(system: MotionSystem, *names: str) -> None:
    for name in names:
        system[name].inputs["Enable"] = True


def pulse(system: MotionSystem, name: str, **operands: object) -> None:
    trigger(system, system[name], **operands)
    system[name].inputs["Execute"] = False


def shown(system: MotionSystem) -> list[str]:
    out = system["MC_ReadStatus"].outputs
    return [s for s in STATES if out[s]]


def test_read_status_shows_the_one_plcopen_state_of_the_axis() -> None:
    system = rig()
    ax = system.ctl.axis(1)
    enable(system, "MC_ReadStatus")
    system.cycle()
    out = system["MC_ReadStatus"].outputs
    assert out["Valid"] and out["Busy"] and not out["Error"] and out["ErrorID"] == 0
    assert shown(system) == ["Disabled"]
    pulse(system, "MSO_1")
    assert shown(system) == ["Standstill"]
    pulse(system, "MAJ_1", Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    assert shown(system) == ["ContinuousMotion"]
    for _ in range(100):
        system.cycle()
    pulse(system, "MAS_1", StopType=0)  # 0 All: ramps to rest, Stopping meanwhile
    assert shown(system) == ["Stopping"]
    for _ in range(100):  # 100 mm/s at 1000 mm/s²: 0.1 s, 50 cycles
        system.cycle()
    assert shown(system) == ["Standstill"]
    pulse(system, "MAM_1", Position=50.0, Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    assert shown(system) == ["DiscreteMotion"]
    for _ in range(500):
        system.cycle()
    assert shown(system) == ["Standstill"] and ax.actual_position == pytest.approx(50.0)
    pulse(system, "MAH_1")  # back at 10 mm/s to the switch on [25, 26] mm
    assert shown(system) == ["Homing"] and ax.plcopen_state == PLCopenState.HOMING
    system.ctl.fault(ax, AxisFault.POSITION_ERROR)
    system.cycle()
    assert shown(system) == ["ErrorStop"]


def test_enable_low_clears_the_status_and_keeps_the_last_values() -> None:
    system = rig()
    enable(system, "MC_ReadStatus", "MC_ReadActualPosition")
    pulse(system, "MSO_1")
    pulse(system, "MRP_1", Position=12.5)  # the actual position becomes 12.5 mm
    pos = system["MC_ReadActualPosition"].outputs
    assert pos["Valid"] and pos["Position"] == 12.5
    system["MC_ReadActualPosition"].inputs["Enable"] = False
    system.cycle()
    assert not (pos["Valid"] or pos["Busy"] or pos["Error"]) and pos["ErrorID"] == 0
    assert pos["Position"] == 12.5
    pulse(system, "MRP_1", Position=-3.0)
    assert pos["Position"] == 12.5  # not read while disabled
    enable(system, "MC_ReadActualPosition")
    system.cycle()
    assert pos["Valid"] and pos["Position"] == -3.0


def test_an_axis_that_does_not_exist_is_error_11_until_the_operand_names_one() -> None:
    system = rig()
    block = system["MC_ReadActualVelocity"]
    block.inputs.update(Enable=True, Axis=9)
    for _ in range(3):
        system.cycle()
        out = block.outputs
        assert out["Error"] and out["Busy"] and not out["Valid"]
        assert out["ErrorID"] == ErrorCode.AXIS_NOT_CONFIGURED
    block.inputs["Axis"] = 1  # operands are read every cycle while enabled
    system.cycle()
    assert block.outputs["Valid"] and not block.outputs["Error"]
    assert block.outputs["ErrorID"] == 0 and block.outputs["Velocity"] == 0.0


def test_position_and_velocity_of_a_jog_every_cycle() -> None:
    system = rig()
    enable(system, "MC_ReadActualPosition", "MC_ReadActualVelocity")
    pulse(system, "MSO_1")
    ax = system.ctl.axis(1)
    x0 = ax.actual_position
    pulse(system, "MAJ_1", Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    pos = system["MC_ReadActualPosition"].outputs
    vel = system["MC_ReadActualVelocity"].outputs
    for n in range(1, 101):  # the jog's n-th cycle has just run
        t = n * DT
        if n > 1:
            system.cycle()
        v = 1000.0 * t if t <= 0.1 else 100.0
        x = 500.0 * t * t if t <= 0.1 else 5.0 + 100.0 * (t - 0.1)
        assert vel["Velocity"] == pytest.approx(v, abs=1e-9), n
        assert pos["Position"] - x0 == pytest.approx(x, abs=1e-9), n
        # the same reading as the axis tags after the cycle
        assert pos["Position"] == ax.actual_position
        assert vel["Velocity"] == ax.actual_velocity
    assert pos["Valid"] and vel["Valid"]


def test_read_axis_error_reports_the_fault_bits_as_the_kernel_holds_them() -> None:
    system = rig()
    ax = system.ctl.axis(1)
    enable(system, "MC_ReadAxisError")
    pulse(system, "MSO_1")
    out = system["MC_ReadAxisError"].outputs
    assert out["Valid"] and out["AxisErrorID"] == 0
    system.ctl.fault(ax, AxisFault.POSITION_ERROR)
    system.cycle()
    assert out["AxisErrorID"] == 1  # bit 0
    system.ctl.fault(ax, AxisFault.WATCHDOG)
    system.cycle()
    assert out["AxisErrorID"] == 1 | 4  # bits 0 and 2
    # any bit the kernel sets is passed through, named or not
    system.ctl.fault(ax, 1 << 20)
    system.cycle()
    assert out["AxisErrorID"] == 1 | 4 | 1 << 20
    # the block reads an axis error; it is not one itself
    assert out["Valid"] and not out["Error"] and out["ErrorID"] == 0
    pulse(system, "MAFR_1")
    assert out["AxisErrorID"] == 0


def test_a_read_block_that_raises_does_not_stop_the_axis() -> None:
    system = rig()
    enable(system, "MC_ReadActualPosition")
    pulse(system, "MSO_1")
    pulse(system, "MAJ_1", Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    block = system["MC_ReadActualPosition"]

    def broken() -> None:
        raise RuntimeError("injected")

    block.read = broken  # type: ignore[method-assign]
    system.cycle()
    assert block.outputs["Error"] and block.outputs["ErrorID"] == ErrorCode.INTERNAL_ERROR
    assert system.internal_errors and system.internal_errors[-1][0] == "MC_ReadActualPosition"
    for _ in range(100):
        system.cycle()
    assert system.ctl.axis(1).command_velocity == 100.0  # the jog runs on
