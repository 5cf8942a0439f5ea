"""MC_MoveAdditive and MC_MoveSuperimposed (PLCopen Part 1), and their interplay with
MC_Halt, MC_Stop and aborting moves.

Kinematics (trapezoid, 2 ms cycles): a move of D at velocity v with acceleration and
deceleration a ramps for v/a each way, covering v^2/(2a) each, and cruises (D - v^2/a)/v;
a superimposed move adds its distance to whatever the underlying motion covers meanwhile.
"""

from __future__ import annotations

from typing import Any

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, ErrorCode, PLCopenState

from ..support import make_system
from .test_plcopen_single_axis import check_outputs, execute

DT = 0.002


def plant() -> MotionSystem:
    """Axis1 a virtual master, Axis2 a servo (powered by MC_Power)."""
    servo = dict(max_velocity=500.0, max_acceleration=5000.0, max_deceleration=5000.0)
    system = make_system(
        AxisConfig(1, "Master", AxisType.VIRTUAL, **servo),
        AxisConfig(2, "Axis2", AxisType.SERVO, **servo),
    )
    system.ctl.servo_on(system.ctl.axis(1))
    power = system.add("MC_Power", "MC_Power_2", {"Axis": 2})
    power.inputs["Enable"] = True
    system.cycle()
    assert power.outputs["Status"]
    return system


def block(system: MotionSystem, type_name: str, name: str, **ops: Any) -> Any:
    return system.add(type_name, name, {"Axis": 2, **ops})


def superimposed(system: MotionSystem, name: str = "Super", **ops: Any) -> Any:
    defaults = {"Distance": 10.0, "VelocityDiff": 20.0, "Acceleration": 200.0,
                "Deceleration": 200.0}  # fmt: skip
    defaults.update(ops)
    return block(system, "MC_MoveSuperimposed", name, **defaults)


def cycles_until(system: MotionSystem, blk: Any, output: str, limit: int = 5000) -> int:
    """Cycle (Execute held) until ``output`` is set; the number of cycles it took."""
    n = 0
    while not blk.outputs[output]:
        execute(system, blk, True)
        n += 1
        assert n < limit, (blk.name, blk.outputs)
    return n


def jog(system: MotionSystem, velocity: float = 40.0) -> Any:
    """MC_MoveVelocity to ``velocity`` at 400 u/s^2, until InVelocity."""
    mv = block(system, "MC_MoveVelocity", "Jog", Velocity=velocity, Acceleration=400.0,
               Deceleration=400.0)  # fmt: skip
    execute(system, mv, True)
    cycles_until(system, mv, "InVelocity")
    return mv


# -- MC_MoveSuperimposed --------------------------------------------------------------------
def test_superimposed_on_a_jog_adds_its_distance_and_keeps_the_jog() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog(system)
    start = ax.command_position
    sup = superimposed(system)
    execute(system, sup, True)
    assert sup.outputs["Busy"] and sup.outputs["Active"]
    # 10 u at 20 u/s, 200 u/s^2: 0.1 s up (1 u), 0.4 s at 20 u/s (8 u), 0.1 s down (1 u)
    n = 1 + cycles_until(system, sup, "Done")
    assert abs(n * DT - 0.6) <= DT * (1 + 1e-9)
    assert sup.outputs["CoveredDistance"] == pytest.approx(10.0, abs=1e-9)
    # the jog went on at 40 u/s meanwhile: 40 x n DT, plus the 10 superimposed
    assert ax.command_position == pytest.approx(start + 40.0 * n * DT + 10.0, abs=1e-9)
    assert ax.command_velocity == pytest.approx(40.0)
    assert mv.outputs["Busy"] and mv.outputs["InVelocity"] and not mv.outputs["CommandAborted"]
    assert ax.plcopen_state == PLCopenState.CONTINUOUS_MOTION


def test_superimposed_on_a_gear_is_a_phase_shift() -> None:
    """As an incremental MAM on a geared slave: the gear stays in gear."""
    system = plant()
    ax = system.ctl.axis(2)
    master = system.add("MC_MoveVelocity", "MasterJog", {"Axis": 1, "Velocity": 100.0,
                        "Acceleration": 5000.0, "Deceleration": 5000.0})  # fmt: skip
    execute(system, master, True, 30)
    gear = system.add("MC_GearIn", "Gear", {"Master": 1, "Slave": 2, "RatioNumerator": 1.0,
                      "RatioDenominator": 2.0, "Acceleration": 5000.0,
                      "Deceleration": 5000.0})  # fmt: skip
    execute(system, gear, True)
    cycles_until(system, gear, "InGear")
    execute(system, gear, True, 5)
    assert ax.command_velocity == pytest.approx(50.0)
    start = ax.command_position
    sup = superimposed(system, Distance=-5.0, VelocityDiff=25.0, Acceleration=250.0,
                       Deceleration=250.0)  # fmt: skip
    execute(system, sup, True)
    # -5 u at 25 u/s, 250 u/s^2: 0.1 s each ramp (1.25 u each), 2.5 u at 25 u/s (0.1 s)
    n = 1 + cycles_until(system, sup, "Done")
    assert abs(n * DT - 0.3) <= DT * (1 + 1e-9)
    assert ax.command_position == pytest.approx(start + 50.0 * n * DT - 5.0, abs=1e-9)
    assert ax.command_velocity == pytest.approx(50.0)
    assert gear.outputs["InGear"] and not gear.outputs["CommandAborted"]
    assert sup.outputs["CoveredDistance"] == pytest.approx(-5.0, abs=1e-9)


def test_superimposed_at_standstill_is_a_relative_move() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    sup = superimposed(system)
    execute(system, sup, True)
    assert ax.plcopen_state == PLCopenState.DISCRETE_MOTION
    n = 1 + cycles_until(system, sup, "Done")
    assert abs(n * DT - 0.6) <= DT * (1 + 1e-9)
    assert ax.command_position == pytest.approx(10.0, abs=1e-9)
    assert ax.command_velocity == 0.0
    execute(system, sup, True)
    assert ax.plcopen_state == PLCopenState.STANDSTILL


@pytest.mark.parametrize("stopper", ["MC_Halt", "MC_Stop"])
def test_halt_and_stop_abort_the_superimposed_and_the_underlying_motion(stopper: str) -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog(system)
    sup = superimposed(system)
    execute(system, sup, True, 100)  # 0.2 s in: cruising at 40 + 20 u/s
    assert ax.command_velocity == pytest.approx(60.0)
    stop = block(system, stopper, "Stop", Deceleration=600.0)
    execute(system, stop, True)
    assert sup.outputs["CommandAborted"] and mv.outputs["CommandAborted"]
    # 60 u/s to rest at 600 u/s^2: 0.1 s
    n = 1 + cycles_until(system, stop, "Done")
    assert abs(n * DT - 0.1) <= DT * (1 + 1e-9)
    assert ax.command_velocity == 0.0
    assert not ax.processes or all(not p.active for p in ax.processes)


def test_an_aborting_move_aborts_the_superimposed_move_too() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    jog(system)
    sup = superimposed(system)
    execute(system, sup, True, 20)
    rel = block(system, "MC_MoveRelative", "Rel", Distance=5.0, Velocity=60.0,
                Acceleration=1000.0, Deceleration=1000.0)  # fmt: skip
    execute(system, rel, True)
    assert sup.outputs["CommandAborted"]
    cycles_until(system, rel, "Done")
    assert ax.command_velocity == 0.0


def test_a_second_superimposed_move_replaces_the_first_only() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog(system)
    start = ax.command_position
    first = superimposed(system, "Super1")
    execute(system, first, True, 150)
    covered = first.outputs["CoveredDistance"]
    # 0.3 s in: 1 u of ramp and 0.2 s at 20 u/s
    assert covered == pytest.approx(5.0, abs=1e-9)
    second = superimposed(system, "Super2", Distance=3.0)
    execute(system, second, True)
    assert first.outputs["CommandAborted"] and second.outputs["Busy"]
    assert mv.outputs["Busy"] and not mv.outputs["CommandAborted"]
    # it takes over at 20 u/s: 3 u to cover, 1 u of them ramping down
    n = 1 + cycles_until(system, second, "Done")
    assert abs(n * DT - 0.2) <= DT * (1 + 1e-9)
    elapsed = (150 + n) * DT
    assert ax.command_position == pytest.approx(start + 40.0 * elapsed + 5.0 + 3.0, abs=1e-9)
    assert first.outputs["CoveredDistance"] == pytest.approx(5.0, abs=1e-9)


def test_superimposed_refused_beyond_the_axis_maxima_and_while_stopping() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    sup = superimposed(system, VelocityDiff=600.0)
    execute(system, sup, True)
    assert sup.outputs["Error"] and sup.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert not ax.processes
    stop = block(system, "MC_Stop", "Stop", Deceleration=600.0)
    execute(system, stop, True)
    ok = superimposed(system, "Super2")
    execute(system, ok, True)
    assert ok.outputs["ErrorID"] == ErrorCode.NOT_ALLOWED_WHILE_STOPPING
    assert ax.command_position == 0.0


# -- MC_MoveAdditive ------------------------------------------------------------------------
def additive(system: MotionSystem, name: str = "Add", **ops: Any) -> Any:
    defaults = {"Distance": 10.0, "Velocity": 50.0, "Acceleration": 500.0,
                "Deceleration": 500.0}  # fmt: skip
    defaults.update(ops)
    return block(system, "MC_MoveAdditive", name, **defaults)


def test_additive_in_discrete_motion_adds_to_the_target() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    absolute = block(system, "MC_MoveAbsolute", "Abs", Position=50.0, Velocity=50.0,
                     Acceleration=500.0, Deceleration=500.0)  # fmt: skip
    execute(system, absolute, True, 100)  # 0.2 s: 0.1 s ramp (2.5 u), 0.1 s at 50 u/s
    assert ax.command_position == pytest.approx(7.5, abs=1e-9)
    add = additive(system)
    execute(system, add, True)
    assert absolute.outputs["CommandAborted"]
    # 42.5 u left + 10: 50 u at 50 u/s then 0.1 s down (2.5 u): 1.0 s + 0.1 s
    n = 1 + cycles_until(system, add, "Done")
    assert abs(n * DT - 1.1) <= DT * (1 + 1e-9)
    assert ax.command_position == 60.0  # on the target exactly, not 7.5 + 10


def test_additive_at_standstill_is_relative_to_the_set_position() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    add = additive(system, Distance=-12.5)
    execute(system, add, True)
    # 12.5 u at 50 u/s, 500 u/s^2: 0.1 s up, 0.15 s cruise, 0.1 s down
    n = 1 + cycles_until(system, add, "Done")
    assert abs(n * DT - 0.35) <= DT * (1 + 1e-9)
    assert ax.command_position == pytest.approx(-12.5, abs=1e-9)
    add.inputs["Distance"] = 2.5  # again: from the last target
    execute(system, add, False)
    execute(system, add, True)
    cycles_until(system, add, "Done")
    assert ax.command_position == pytest.approx(-10.0, abs=1e-9)


def test_additive_in_continuous_motion_starts_from_the_set_position() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    jog(system)
    add = additive(system, Distance=30.0, Velocity=40.0, Acceleration=400.0,
                   Deceleration=400.0)  # fmt: skip
    start = ax.command_position
    execute(system, add, True)
    # entered at 40 u/s: cruise 28 u (0.7 s), 2 u to rest (0.1 s)
    n = 1 + cycles_until(system, add, "Done")
    assert abs(n * DT - 0.8) <= DT * (1 + 1e-9)
    assert ax.command_position == pytest.approx(start + 30.0, abs=1e-9)


def test_buffered_additive_ends_distance_beyond_the_previous_target() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    absolute = block(system, "MC_MoveAbsolute", "Abs", Position=20.0, Velocity=50.0,
                     Acceleration=500.0, Deceleration=500.0)  # fmt: skip
    execute(system, absolute, True)
    add = additive(system, Distance=-5.0, BufferMode=1)
    execute(system, add, True)
    assert add.outputs["Busy"] and not add.outputs["Active"]
    cycles_until(system, add, "Done")
    assert absolute.outputs["Done"]
    assert ax.command_position == pytest.approx(15.0, abs=1e-9)


def test_additive_aborted_by_halt() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    add = additive(system, Distance=40.0)
    execute(system, add, True, 100)
    halt = block(system, "MC_Halt", "Halt", Deceleration=500.0)
    execute(system, halt, True)
    assert add.outputs["CommandAborted"]
    # 50 u/s to rest at 500 u/s^2: 0.1 s
    n = 1 + cycles_until(system, halt, "Done")
    assert abs(n * DT - 0.1) <= DT * (1 + 1e-9)
    assert ax.command_velocity == 0.0
    check_outputs(system)
