"""PLCopen single-axis blocks: output rules, MC_Stop / MC_Halt, MC_MoveVelocity,
buffered commands, MC_Reset, preconditions.

The output rules (PLCopen Part 1, DESIGN.md): inputs are latched on the rising edge of
Execute; Done, Error and CommandAborted are mutually exclusive, each held until Execute
falls and shown for at least one cycle even when Execute fell earlier.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from motion_server.instructions import MotionSystem, PLCopenBlock
from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisType,
    ErrorCode,
    PLCopenState,
)

from ..support import make_system, sample

DT = 0.002
TERMINAL = ("Done", "Error", "CommandAborted")


def plant() -> MotionSystem:
    """Axis1 linear servo (powered by MC_Power_1), Axis4 feedback only."""
    system = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.SERVO,
            max_velocity=100.0,
            max_acceleration=1000.0,
            max_deceleration=1000.0,
        ),
        AxisConfig(4, "Axis4", AxisType.FEEDBACK_ONLY, conversion_constant=100.0),
    )
    power = system.add("MC_Power", "MC_Power_1", {"Axis": 1})
    power.inputs["Enable"] = True
    system.cycle()
    assert power.outputs["Status"]
    return system


def execute(system: MotionSystem, block: Any, value: bool, cycles: int = 1) -> None:
    block.inputs["Execute"] = value
    for _ in range(cycles):
        system.cycle()
        check_outputs(system)


def check_outputs(system: MotionSystem) -> None:
    """The exclusivity rules, on every block of the system."""
    for inst in system.instances.values():
        if not isinstance(inst, PLCopenBlock) or "Done" not in inst.outputs:
            continue
        o = inst.outputs
        assert sum(bool(o.get(k)) for k in TERMINAL) <= 1, (inst.name, o)
        if o["Busy"]:
            assert not any(o.get(k) for k in TERMINAL), (inst.name, o)
        if o.get("Active"):
            assert o["Busy"], (inst.name, o)
        assert bool(o["ErrorID"]) == bool(o["Error"]), (inst.name, o)


def move_relative(system: MotionSystem, name: str = "MC_MoveRelative_1", **ops: Any) -> Any:
    defaults = {"Axis": 1, "Distance": 10.0, "Velocity": 50.0, "Acceleration": 500.0,
                "Deceleration": 500.0}  # fmt: skip
    defaults.update(ops)
    return system.add("MC_MoveRelative", name, defaults)


# -- output rules ---------------------------------------------------------------------------
def test_done_is_held_until_execute_falls() -> None:
    system = plant()
    mv = move_relative(system)  # 10 mm, a triangle-free trapezoid: 0.3 s
    execute(system, mv, True)
    assert mv.outputs["Busy"] and mv.outputs["Active"]
    execute(system, mv, True, 160)
    assert mv.outputs["Done"] and not mv.outputs["Busy"]
    assert system.ctl.axis(1).command_position == 10.0
    execute(system, mv, True, 50)  # held while Execute stays high
    assert mv.outputs["Done"]
    execute(system, mv, False)
    assert not any(mv.outputs[k] for k in ("Done", "Busy", "Active"))


def test_done_shown_one_cycle_when_execute_fell_before_completion() -> None:
    system = plant()
    mv = move_relative(system)
    execute(system, mv, True)
    seen = []
    execute(system, mv, False)  # dropped at once; the move goes on
    for _ in range(200):
        seen.append(mv.outputs["Done"])
        system.cycle()
        check_outputs(system)
    assert sum(seen) == 1  # shown exactly once
    assert system.ctl.axis(1).command_position == 10.0


@pytest.mark.parametrize("hold", [True, False])
def test_error_held_while_execute_high_and_shown_once_otherwise(hold: bool) -> None:
    system = plant()
    mv = move_relative(system, Velocity=-1.0)
    execute(system, mv, True)
    assert mv.outputs["Error"] and mv.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    execute(system, mv, hold, 3)
    assert mv.outputs["Error"] == hold
    assert mv.outputs["ErrorID"] == (ErrorCode.PARAMETER_OUT_OF_RANGE if hold else 0)
    assert system.ctl.axis(1).command_position == 0.0


def test_command_aborted_by_an_aborting_successor() -> None:
    system = plant()
    first = system.add(
        "MC_MoveAbsolute", "MC_MoveAbsolute_1", {"Axis": 1, "Position": 50.0, "Velocity": 50.0,
        "Acceleration": 500.0, "Deceleration": 500.0},
    )  # fmt: skip
    second = move_relative(system, Distance=-5.0)
    execute(system, first, True, 50)
    v = system.ctl.axis(1).command_velocity
    execute(system, second, True)
    assert first.outputs["CommandAborted"]
    assert not first.outputs["Busy"] and not first.outputs["Active"]
    assert second.outputs["Busy"] and second.outputs["Active"]
    # aborting mode inherits the velocity: no jump in the first cycle
    assert abs(system.ctl.axis(1).command_velocity - v) <= 500.0 * DT * (1 + 1e-9)
    execute(system, first, True, 5)
    assert first.outputs["CommandAborted"]  # held while Execute is high
    first.inputs["Execute"] = False
    execute(system, second, True, 400)
    assert not first.outputs["CommandAborted"]
    assert second.outputs["Done"]


def test_command_aborted_shown_once_when_execute_already_low() -> None:
    system = plant()
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 20.0})
    execute(system, vel, True)
    execute(system, vel, False, 5)  # the motion goes on with Execute low
    assert vel.outputs["Busy"]
    halt = system.add("MC_Halt", "MC_Halt_1", {"Axis": 1, "Deceleration": 500.0})
    execute(system, halt, True)
    assert vel.outputs["CommandAborted"]
    execute(system, halt, True)
    assert not vel.outputs["CommandAborted"]


# -- MC_Stop --------------------------------------------------------------------------------
def test_mc_stop_holds_the_axis_in_stopping_while_execute_is_high() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 50.0,
                     "Acceleration": 1000.0})  # fmt: skip
    stop = system.add("MC_Stop", "MC_Stop_1", {"Axis": 1, "Deceleration": 500.0})
    mv = move_relative(system)
    execute(system, vel, True, 100)
    execute(system, stop, True)
    assert vel.outputs["CommandAborted"]
    assert stop.outputs["Busy"] and ax.plcopen_state == PLCopenState.STOPPING
    execute(system, stop, True, 60)  # 50 mm/s at 500 mm/s^2: 0.1 s
    assert ax.command_velocity == 0.0
    assert stop.outputs["Done"]
    assert ax.plcopen_state == PLCopenState.STOPPING  # at rest, still Stopping
    rest = ax.command_position
    execute(system, mv, True)  # refused meanwhile
    assert mv.outputs["Error"] and mv.outputs["ErrorID"] == ErrorCode.NOT_ALLOWED_WHILE_STOPPING
    halt = system.add("MC_Halt", "MC_Halt_1", {"Axis": 1})
    execute(system, halt, True)
    assert halt.outputs["ErrorID"] == ErrorCode.NOT_ALLOWED_WHILE_STOPPING
    execute(system, mv, False, 10)
    assert ax.command_position == rest and stop.outputs["Done"]
    execute(system, stop, False)  # released
    assert not stop.outputs["Done"]
    assert ax.plcopen_state == PLCopenState.STANDSTILL
    execute(system, mv, True, 200)
    assert mv.outputs["Done"] and ax.command_position == rest + 10.0


def test_mc_stop_with_execute_pulse_releases_once_at_rest() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 50.0,
                     "Acceleration": 1000.0})  # fmt: skip
    stop = system.add("MC_Stop", "MC_Stop_1", {"Axis": 1, "Deceleration": 500.0})
    execute(system, vel, True, 100)
    execute(system, stop, True)
    execute(system, stop, False)
    states = []
    for _ in range(80):
        states.append(ax.plcopen_state)
        system.cycle()
    assert set(states[:40]) == {PLCopenState.STOPPING}
    assert ax.plcopen_state == PLCopenState.STANDSTILL


# -- MC_Halt --------------------------------------------------------------------------------
def test_mc_halt_decelerates_to_rest_in_discrete_motion() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 50.0,
                     "Acceleration": 1000.0})  # fmt: skip
    halt = system.add("MC_Halt", "MC_Halt_1", {"Axis": 1, "Deceleration": 250.0})
    execute(system, vel, True, 100)
    before = ax.command_position
    execute(system, halt, True)
    assert ax.plcopen_state == PLCopenState.DISCRETE_MOTION  # not Stopping
    p = np.concatenate([[before, ax.command_position], sample(system, 1, 120)])
    a = np.diff(p, 2) / DT**2
    assert np.abs(a).max() <= 250.0 * (1 + 1e-9)
    v = np.diff(p) / DT
    k = next(i for i, x in enumerate(v) if x == 0.0)
    assert abs(k * DT - 50.0 / 250.0) <= DT * (1 + 1e-9)
    assert halt.outputs["Done"]
    assert ax.plcopen_state == PLCopenState.STANDSTILL
    assert ax.command_position - before == pytest.approx(50.0**2 / 500.0, abs=1e-9)


def test_mc_halt_is_aborted_by_a_following_motion_command() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 50.0,
                     "Acceleration": 1000.0})  # fmt: skip
    halt = system.add("MC_Halt", "MC_Halt_1", {"Axis": 1, "Deceleration": 100.0})
    absolute = system.add(
        "MC_MoveAbsolute", "MC_MoveAbsolute_1", {"Axis": 1, "Position": 20.0, "Velocity": 50.0,
        "Acceleration": 500.0, "Deceleration": 500.0},
    )  # fmt: skip
    execute(system, vel, True, 60)
    execute(system, halt, True, 10)
    assert halt.outputs["Busy"]
    execute(system, absolute, True)
    assert halt.outputs["CommandAborted"] and absolute.outputs["Active"]
    execute(system, absolute, True, 600)
    assert absolute.outputs["Done"] and ax.command_position == 20.0


def test_mc_halt_at_rest_is_done_at_once() -> None:
    system = plant()
    halt = system.add("MC_Halt", "MC_Halt_1", {"Axis": 1})
    execute(system, halt, True)
    assert halt.outputs["Done"]


def test_a_profile_ruckig_cannot_compute_is_refused_without_touching_motion() -> None:
    """Deceleration 1.6e-157 is > 0 but no profile can be computed (ruckig raises): the
    block answers Error 1001 and the running motion goes on unchanged."""
    systems = [plant(), plant()]
    for s in systems:
        v = s.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 4.0})
        execute(s, v, True, 30)
        s.add("MC_Halt", "MC_Halt_1", {"Axis": 1, "Deceleration": 1.6e-157})
    halt = systems[0]["MC_Halt_1"]
    execute(systems[0], halt, True)
    systems[1].cycle()
    assert halt.outputs["Error"] and halt.outputs["ErrorID"] == ErrorCode.PROFILE_FAILED
    assert systems[0]["MC_MoveVelocity_1"].outputs["Busy"]
    for _ in range(20):
        a, b = (s.ctl.axis(1) for s in systems)
        assert (a.command_position, a.command_velocity) == (b.command_position, b.command_velocity)
        for s in systems:
            s.cycle()


# -- MC_MoveVelocity ------------------------------------------------------------------------
def test_move_velocity_in_velocity_busy_and_active_never_done() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 40.0,
                     "Acceleration": 400.0, "Deceleration": 400.0})  # fmt: skip
    execute(system, vel, True)
    n = 1
    while not vel.outputs["InVelocity"]:
        assert vel.outputs["Busy"] and vel.outputs["Active"]
        execute(system, vel, True)
        n += 1
    assert abs(n * DT - 40.0 / 400.0) <= DT * (1 + 1e-9)  # v/a
    assert ax.command_velocity == 40.0
    assert ax.plcopen_state == PLCopenState.CONTINUOUS_MOTION
    execute(system, vel, True, 500)
    assert vel.outputs["Busy"] and vel.outputs["Active"] and vel.outputs["InVelocity"]
    assert not vel.outputs["Done"]
    execute(system, vel, False)  # InVelocity reset by the falling edge; the motion goes on
    assert not vel.outputs["InVelocity"]
    assert vel.outputs["Busy"] and vel.outputs["Active"]
    execute(system, vel, False, 10)
    assert ax.command_velocity == 40.0


def test_in_velocity_shown_once_when_execute_fell_before() -> None:
    system = plant()
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 40.0,
                     "Acceleration": 400.0})  # fmt: skip
    execute(system, vel, True)
    execute(system, vel, False)
    seen = []
    for _ in range(100):
        system.cycle()
        seen.append(vel.outputs["InVelocity"])
    assert sum(seen) == 1
    assert vel.outputs["Busy"]


@pytest.mark.parametrize(
    ("first", "direction", "expected"),
    [(0.0, 1, 30.0), (0.0, 3, -30.0), (-10.0, 4, -30.0), (10.0, 4, 30.0), (0.0, 4, 30.0)],
)
def test_move_velocity_direction(first: float, direction: int, expected: float) -> None:
    system = plant()
    ax = system.ctl.axis(1)
    if first:
        jog = system.add("MC_MoveVelocity", "Before", {"Axis": 1, "Velocity": abs(first),
                         "Direction": 1 if first > 0 else 3, "Acceleration": 1000.0})  # fmt: skip
        execute(system, jog, True, 20)
        assert ax.command_velocity == first
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 30.0,
                     "Direction": direction, "Acceleration": 1000.0,
                     "Deceleration": 1000.0})  # fmt: skip
    execute(system, vel, True, 100)
    assert ax.command_velocity == expected


def test_move_velocity_zero_stays_in_continuous_motion() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 0.0})
    execute(system, vel, True, 3)
    assert vel.outputs["InVelocity"] and vel.outputs["Busy"]
    assert ax.plcopen_state == PLCopenState.CONTINUOUS_MOTION
    assert ax.command_velocity == 0.0


@pytest.mark.parametrize(
    "operands",
    [{"Direction": 2}, {"Direction": 0}, {"Velocity": -1.0}, {"Velocity": math.nan},
     {"Acceleration": 0.0}, {"Jerk": -1.0}, {"BufferMode": 5}],
)  # fmt: skip
def test_move_velocity_bad_operands(operands: dict[str, Any]) -> None:
    system = plant()
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, **operands})
    execute(system, vel, True, 5)
    assert vel.outputs["Error"] and vel.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert system.ctl.axis(1).command_position == 0.0
    assert system.ctl.axis(1).processes == []


# -- buffered commands ----------------------------------------------------------------------
def test_buffered_move_starts_when_the_active_one_is_done() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    first = system.add(
        "MC_MoveAbsolute", "MC_MoveAbsolute_1", {"Axis": 1, "Position": 12.5, "Velocity": 50.0,
        "Acceleration": 500.0, "Deceleration": 500.0},
    )  # fmt: skip
    second = move_relative(system, Distance=-2.25, BufferMode=1)
    execute(system, first, True)
    execute(system, second, True)
    assert second.outputs["Busy"] and not second.outputs["Active"]
    while not first.outputs["Done"]:
        assert not second.outputs["Active"]
        system.cycle()
        check_outputs(system)
    assert ax.command_position == 12.5
    system.cycle()
    assert second.outputs["Active"]
    execute(system, second, True, 200)
    assert second.outputs["Done"] and ax.command_position == 10.25
    assert first.outputs["Done"]  # never aborted


def test_buffered_move_after_move_velocity_starts_at_velocity() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 40.0,
                     "Acceleration": 400.0, "Deceleration": 400.0})  # fmt: skip
    mv = move_relative(system, Distance=30.0, Velocity=40.0, Acceleration=400.0,
                       Deceleration=400.0, BufferMode=1)  # fmt: skip
    execute(system, vel, True)
    execute(system, mv, True)
    n = 1
    while not mv.outputs["Active"]:
        assert vel.outputs["Busy"] and mv.outputs["Busy"]
        system.cycle()
        check_outputs(system)
        n += 1
    # handed over in the cycle the velocity was reached (v/a = 0.1 s), at that velocity
    assert abs(n * DT - 40.0 / 400.0) <= DT * (1 + 1e-9)
    assert vel.outputs["CommandAborted"]
    assert ax.command_velocity == 40.0
    start = ax.command_position
    # 30 mm entered at 40 mm/s: cruise 28 mm (0.7 s), 2 mm to rest (0.1 s)
    k = 0
    while not mv.outputs["Done"]:
        execute(system, mv, True)
        k += 1
    assert abs(k * DT - 0.8) <= DT * (1 + 1e-9)
    assert ax.command_position == pytest.approx(start + 30.0, abs=1e-9)


# -- MC_MoveAbsolute, MC_MoveRelative -------------------------------------------------------
def test_move_absolute_done_exactly_on_target_on_that_cycle() -> None:
    system = plant()
    ax = system.ctl.axis(1)
    mv = system.add(
        "MC_MoveAbsolute", "MC_MoveAbsolute_1", {"Axis": 1, "Position": -52.407, "Velocity": 100.0,
        "Acceleration": 1000.0, "Deceleration": 1000.0},
    )  # fmt: skip
    execute(system, mv, True)
    while not mv.outputs["Done"]:
        assert ax.command_position != -52.407
        execute(system, mv, True)
    assert ax.command_position == -52.407
    mv.inputs["Position"] = 8.846  # -52.407 + (8.846 + 52.407) != 8.846 in floating point
    execute(system, mv, False)
    execute(system, mv, True, 400)  # 61.253 mm at 100 mm/s: 0.61 s + v/a = 0.71 s
    assert mv.outputs["Done"] and ax.command_position == 8.846


# -- MC_Reset -------------------------------------------------------------------------------
def test_mc_reset_clears_a_following_error_fault() -> None:
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.SERVO, following_error_limit=0.2, drive_bandwidth=20.0)
    )
    ax = system.ctl.axis(1)
    power = system.add("MC_Power", "MC_Power_1", {"Axis": 1})
    vel = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, "Velocity": 200.0,
                     "Acceleration": 5000.0})  # fmt: skip
    reset = system.add("MC_Reset", "MC_Reset_1", {"Axis": 1})
    assert set(reset.outputs) == {"Done", "Busy", "Error", "ErrorID"}
    power.inputs["Enable"] = True
    execute(system, vel, True, 100)  # lag 2v/w = 3.2 mm > 0.2 mm: faults
    assert ax.plcopen_state == PLCopenState.ERRORSTOP
    assert ax.fault & AxisFault.POSITION_ERROR
    assert power.outputs["Error"] and power.outputs["ErrorID"] == ErrorCode.AXIS_FAULTED
    assert not vel.outputs["Busy"]
    mv = move_relative(system)
    execute(system, mv, True)
    assert mv.outputs["ErrorID"] == ErrorCode.AXIS_FAULTED
    power.inputs["Enable"] = False
    execute(system, reset, True)
    assert reset.outputs["Done"] and not reset.outputs["Busy"]
    assert ax.fault == 0 and ax.plcopen_state == PLCopenState.DISABLED
    power.inputs["Enable"] = True
    system.cycle()
    assert ax.plcopen_state == PLCopenState.STANDSTILL and not power.outputs["Error"]
    execute(system, reset, False)
    assert not reset.outputs["Done"]


# -- preconditions --------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("state", "code"),
    [
        ("servo_off", ErrorCode.SERVO_OFF_STATE),
        ("shutdown", ErrorCode.SHUTDOWN_STATE),
        ("faulted", ErrorCode.AXIS_FAULTED),
        ("feedback_only", ErrorCode.WRONG_AXIS_TYPE),
        ("unconfigured", ErrorCode.AXIS_NOT_CONFIGURED),
    ],
)
@pytest.mark.parametrize(
    "type_name",
    ["MC_MoveAbsolute", "MC_MoveRelative", "MC_MoveVelocity", "MC_Halt", "MC_Stop"],
)
def test_motion_blocks_refused_by_axis_state(type_name: str, state: str, code: int) -> None:
    system = plant()
    ax = system.ctl.axis(1)
    power = system["MC_Power_1"]
    n = 1
    if state == "servo_off":
        power.inputs["Enable"] = False
    elif state == "shutdown":
        power.inputs["Enable"] = False
        system.ctl.shutdown(ax)
    elif state == "faulted":
        system.ctl.fault(ax, AxisFault.POSITION_ERROR)
    elif state == "feedback_only":
        n = 4
    else:
        n = 7
    system.cycle()
    block = system.add(type_name, f"{type_name}_1", {"Axis": n})
    execute(system, block, True, 10)
    assert block.outputs["Error"] and block.outputs["ErrorID"] == code
    assert ax.command_position == 0.0 and ax.processes == []
