"""MC_SetOverride (PLCopen Part 1, TwinCAT Tc2_MC2, CODESYS SM3_Basic): the factors
scale the running moves and jogs of an axis, re-planned from where they are.

Kinematics (trapezoid, 2 ms cycles): a velocity change of dv at acceleration a takes
|dv|/a; a move of D at velocity v with acceleration and deceleration a ramps for v/a each
way, covering v^2/(2a) each, and cruises (D - v^2/a)/v.
"""

from __future__ import annotations

from typing import Any

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import ErrorCode, Override, PLCopenState

from .test_plcopen_single_axis import execute
from .test_plcopen_superimposed import DT, block, plant


def override(system: MotionSystem, axis: int = 2, **factors: float) -> Any:
    ovr = system.add("MC_SetOverride", "Override", {"Axis": axis, **factors})
    ovr.inputs["Enable"] = True
    return ovr


def cycles_while(system: MotionSystem, cond: Any, limit: int = 5000) -> int:
    """Cycle while ``cond()`` holds; the number of cycles run."""
    n = 0
    while cond():
        system.cycle()
        n += 1
        assert n < limit
    return n


def jog100(system: MotionSystem) -> Any:
    """MC_MoveVelocity at 100 u/s, 1000 u/s^2, at speed."""
    mv = block(system, "MC_MoveVelocity", "Jog", Velocity=100.0, Acceleration=1000.0,
               Deceleration=1000.0)  # fmt: skip
    execute(system, mv, True)
    ax = system.ctl.axis(2)
    cycles_while(system, lambda: ax.command_velocity != pytest.approx(100.0))
    return mv


def test_velocity_factor_halves_a_jog_after_a_ramp_of_known_duration() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog100(system)
    ovr = override(system, VelFactor=0.5)
    # 100 -> 50 u/s at the programmed 1000 u/s^2: 0.05 s
    n = cycles_while(system, lambda: ax.command_velocity != pytest.approx(50.0))
    assert abs(n * DT - 0.05) <= DT * (1 + 1e-9)
    for _ in range(10):
        system.cycle()
    assert ax.command_velocity == pytest.approx(50.0)
    assert ovr.outputs["Enabled"] and ovr.outputs["Busy"] and not ovr.outputs["Error"]
    assert mv.outputs["Busy"] and mv.outputs["Active"] and not mv.outputs["CommandAborted"]
    assert ax.plcopen_state == PLCopenState.CONTINUOUS_MOTION
    # back to 100 u/s with half the acceleration: 50 / 500 = 0.1 s
    ovr.inputs["VelFactor"] = 1.0
    ovr.inputs["AccFactor"] = 0.5
    n = cycles_while(system, lambda: ax.command_velocity != pytest.approx(100.0))
    assert abs(n * DT - 0.1) <= DT * (1 + 1e-9)


def test_move_under_override_takes_the_trapezoid_time_of_the_scaled_limits() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    ovr = override(system, VelFactor=0.5, AccFactor=0.25)
    system.cycle()
    assert ax.override == Override(0.5, 0.25, 1.0)
    mv = block(system, "MC_MoveRelative", "Move", Distance=100.0, Velocity=100.0,
               Acceleration=1000.0, Deceleration=1000.0)  # fmt: skip
    execute(system, mv, True)
    peak = 0.0
    n = 1
    while not mv.outputs["Done"]:
        system.cycle()
        peak = max(peak, ax.command_velocity)
        n += 1
        assert n < 5000
    # v = 50, a = 250: 0.2 s each ramp (5 u each), 90 u at 50 u/s (1.8 s): 2.2 s
    assert abs(n * DT - 2.2) <= 2 * DT
    assert peak == pytest.approx(50.0)
    assert ax.command_position == pytest.approx(100.0, abs=1e-9)
    assert ovr.outputs["Enabled"]


def test_velocity_factor_zero_holds_the_move_in_its_state_and_resumes_it() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = block(system, "MC_MoveAbsolute", "Move", Position=200.0, Velocity=100.0,
               Acceleration=1000.0, Deceleration=1000.0)  # fmt: skip
    execute(system, mv, True, 300)  # cruising at 100 u/s
    assert ax.command_velocity == pytest.approx(100.0)
    ovr = override(system, VelFactor=0.0)
    # to rest at 1000 u/s^2: 0.1 s
    n = cycles_while(system, lambda: ax.command_velocity != 0.0)
    assert abs(n * DT - 0.1) <= DT * (1 + 1e-9)
    held = ax.command_position
    for _ in range(50):
        system.cycle()
    assert ax.command_position == held < 200.0
    assert ax.plcopen_state == PLCopenState.DISCRETE_MOTION
    assert mv.outputs["Busy"] and mv.outputs["Active"] and not mv.outputs["Done"]
    assert ovr.outputs["Enabled"]
    ovr.inputs["VelFactor"] = 1.0
    cycles_while(system, lambda: not mv.outputs["Done"])
    assert ax.command_position == pytest.approx(200.0, abs=1e-9)
    assert ax.plcopen_state == PLCopenState.STANDSTILL


@pytest.mark.parametrize(
    "factors",
    [{"VelFactor": 1.5}, {"VelFactor": -0.1}, {"AccFactor": 0.0}, {"JerkFactor": 0.0},
     {"AccFactor": 2.0}],
)  # fmt: skip
def test_out_of_range_factors_are_error_13_and_change_nothing(factors: dict[str, float]) -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog100(system)
    ovr = override(system, **factors)
    system.cycle()
    assert ovr.outputs["Error"] and not ovr.outputs["Enabled"] and ovr.outputs["Busy"]
    assert ovr.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert ax.override == Override()
    assert ax.command_velocity == pytest.approx(100.0)
    assert mv.outputs["Busy"]
    ovr.inputs["Enable"] = False
    system.cycle()
    assert not any(ovr.outputs[k] for k in ("Enabled", "Busy", "Error", "ErrorID"))


def test_missing_axis_is_error_11() -> None:
    system = plant()
    ovr = override(system, axis=9, VelFactor=0.5)
    system.cycle()
    assert ovr.outputs["Error"] and ovr.outputs["ErrorID"] == ErrorCode.AXIS_NOT_CONFIGURED


def test_enable_low_gives_the_jog_its_programmed_velocity_back() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    jog100(system)
    ovr = override(system, VelFactor=0.25)
    cycles_while(system, lambda: ax.command_velocity != pytest.approx(25.0))
    ovr.inputs["Enable"] = False
    # 25 -> 100 u/s at 1000 u/s^2: 0.075 s
    n = cycles_while(system, lambda: ax.command_velocity != pytest.approx(100.0))
    assert abs(n * DT - 0.075) <= DT * (1 + 1e-9)
    assert ax.override == Override()
    assert not ovr.outputs["Enabled"] and not ovr.outputs["Busy"]


def test_a_geared_slave_follows_its_master_unscaled() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    master = system.add("MC_MoveVelocity", "MasterJog", {"Axis": 1, "Velocity": 100.0,
                        "Acceleration": 5000.0, "Deceleration": 5000.0})  # fmt: skip
    execute(system, master, True, 30)
    gear = system.add("MC_GearIn", "Gear", {"Master": 1, "Slave": 2, "RatioNumerator": 1.0,
                      "RatioDenominator": 2.0, "Acceleration": 5000.0,
                      "Deceleration": 5000.0})  # fmt: skip
    execute(system, gear, True)
    cycles_while(system, lambda: not gear.outputs["InGear"])
    ovr = override(system, VelFactor=0.5)
    for _ in range(50):
        system.cycle()
    assert ovr.outputs["Enabled"]
    assert ax.command_velocity == pytest.approx(50.0)  # 1/2 of the master's 100 u/s
    assert gear.outputs["InGear"]
    # an override on the master slows the master, and the slave with it
    movr = system.add("MC_SetOverride", "MasterOverride", {"Axis": 1, "VelFactor": 0.5})
    movr.inputs["Enable"] = True
    for _ in range(50):
        system.cycle()
    assert system.ctl.axis(1).command_velocity == pytest.approx(50.0)
    assert ax.command_velocity == pytest.approx(25.0)
