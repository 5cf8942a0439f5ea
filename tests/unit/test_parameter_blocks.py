"""MC_ReadParameter, MC_ReadBoolParameter, MC_WriteParameter, MC_WriteBoolParameter: the
PLCopen parameter
numbers (Part 1; TwinCAT MC_AxisParameter numbers them the same, 1 CommandedPosition
... 17 MaxJerkAppl) as our axes hold them.

The servo's drive follows its command with bandwidth ω = 2π · 40 rad/s: at a steady
velocity v the following error is 2v/ω (0.796 mm at 100 mm/s), so a MaxPositionLag of
0.5 mm faults the axis during a 100 mm/s jog and one of 1.2 mm does not.
"""

from __future__ import annotations

import math

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisFault, AxisState, AxisType, ErrorCode

from ..support import make_system, trigger
from .test_lanes import PREAMBLE, pair, run_pair

JERK = 50000.0


def rig(fe_limit: float = 0.0) -> MotionSystem:
    system = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.SERVO,
            max_velocity=250.0,
            max_acceleration=2000.0,
            max_deceleration=3000.0,
            max_jerk=JERK,
            following_error_limit=fe_limit,
        )
    )
    for name in ("MSO", "MAJ"):
        system.add(name, f"{name}_1", {"Axis": 1})
    system.add("MC_ReadParameter", "Read", {"Axis": 1})
    system.add("MC_ReadBoolParameter", "ReadBool", {"Axis": 1})
    system.add("MC_WriteParameter", "Write", {"Axis": 1})
    system.add("MC_WriteBoolParameter", "WriteBool", {"Axis": 1})
    trigger(system, system["MSO_1"])
    return system


def read(system: MotionSystem, number: int, block: str = "Read") -> dict[str, object]:
    inst = system[block]
    inst.inputs.update(Enable=True, ParameterNumber=number)
    system.cycle()
    return dict(inst.outputs)


def write(system: MotionSystem, number: int, value: float) -> dict[str, object]:
    inst = system["Write"]
    inst.inputs["Execute"] = False
    system.cycle()
    trigger(system, inst, ParameterNumber=number, Value=value)
    return dict(inst.outputs)


@pytest.mark.parametrize(
    ("number", "value"),
    [(8, 250.0), (9, 250.0), (12, 2000.0), (13, 2000.0), (14, 3000.0), (15, 3000.0),
     (16, JERK), (17, JERK), (7, 0.0)],
)  # fmt: skip
def test_the_axis_limits_read_as_configured(number: int, value: float) -> None:
    out = read(rig(), number)
    assert out["Valid"] and not out["Error"] and out["Value"] == value


def test_commanded_position_and_velocities_follow_the_axis_every_cycle() -> None:
    system = rig()
    ax = system.ctl.axis(1)
    trigger(system, system["MAJ_1"], Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    for number, attr in ((1, "command_position"), (11, "command_velocity")):
        for _ in range(3):
            out = read(system, number)
            assert out["Valid"] and out["Value"] == getattr(ax, attr)
    for _ in range(200):
        system.cycle()
    assert read(system, 11)["Value"] == 100.0  # at speed
    v = read(system, 10)["Value"]
    assert isinstance(v, float) and v == ax.actual_velocity
    assert v == pytest.approx(100.0, abs=1e-6)


def test_bool_parameters_and_the_kinds_kept_apart() -> None:
    system = rig(fe_limit=2.0)
    assert read(system, 6, "ReadBool")["Value"] is True
    for number in (4, 5):  # no software limits on a simulated axis
        out = read(system, number, "ReadBool")
        assert out["Valid"] and out["Value"] is False
    for number, block in ((6, "Read"), (7, "ReadBool"), (2, "Read"), (3, "Read"), (99, "Read")):
        out = read(system, number, block)
        assert out["Error"] and not out["Valid"] and out["Busy"]
        assert out["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE


def test_write_max_position_lag_faults_a_jog_beyond_it() -> None:
    system = rig(fe_limit=0.0)
    assert read(system, 6, "ReadBool")["Value"] is False
    out = write(system, 7, 0.5)
    assert out["Done"] and not out["Error"]
    assert read(system, 7)["Value"] == 0.5
    assert read(system, 6, "ReadBool")["Value"] is True
    ax = system.ctl.axis(1)
    trigger(system, system["MAJ_1"], Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    for _ in range(500):
        system.cycle()
        if ax.state == AxisState.AXIS_FAULTED:
            break
    assert ax.state == AxisState.AXIS_FAULTED and ax.fault & AxisFault.POSITION_ERROR


def test_a_limit_above_the_steady_error_lets_the_jog_run() -> None:
    system = rig(fe_limit=0.0)
    assert write(system, 7, 1.2)["Done"]
    ax = system.ctl.axis(1)
    trigger(system, system["MAJ_1"], Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    for _ in range(500):
        system.cycle()
    assert ax.state == AxisState.SERVO_CONTROL and ax.fault == 0
    assert ax.position_error == pytest.approx(2 * 100.0 / (2 * math.pi * 40.0), rel=1e-3)


@pytest.mark.parametrize(("number", "value"), [(8, 100.0), (1, 5.0), (99, 1.0), (7, -1.0)])
def test_read_only_unknown_and_negative_writes_are_refused(number: int, value: float) -> None:
    system = rig(fe_limit=2.0)
    out = write(system, number, value)
    assert out["Error"] and not out["Done"]
    assert out["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert read(system, 7)["Value"] == 2.0  # unchanged
    assert system.ctl.axis(1).config.max_velocity == 250.0


def test_a_written_lag_limit_acts_the_same_with_and_without_lanes() -> None:
    """A laned slave (S3 geared 0.3 to a jog at 100 mm/s: 30 mm/s, a steady error of
    60/ω = 0.24 mm) gets a limit above its error, then one below it: it faults in the
    same cycle on both paths, and every array and output agrees after every cycle."""
    fast, ref = pair()
    run_pair(fast, ref, PREAMBLE, prefix="P")
    script: list[tuple[str, dict[str, object], int]] = [
        ("MC_ReadParameter", {"Axis": 3, "ParameterNumber": 7}, 1),
        ("MC_WriteParameter", {"Axis": 3, "ParameterNumber": 7, "Value": 0.5}, 200),
        ("MC_ReadActualVelocity", {"Axis": 3}, 1),
        ("MC_WriteParameter", {"Axis": 3, "ParameterNumber": 7, "Value": 0.05}, 50),
        ("MC_ReadAxisError", {"Axis": 3}, 5),
    ]
    run_pair(fast, ref, script)
    for s in (fast, ref):
        assert s.ctl.axis(3).fault & AxisFault.POSITION_ERROR
        assert s.ctl.axis(1).fault == 0  # the master jogs on


def write_bool(system: MotionSystem, number: int, value: bool) -> dict[str, object]:
    inst = system["WriteBool"]
    inst.inputs["Execute"] = False
    system.cycle()
    trigger(system, inst, ParameterNumber=number, Value=value)
    return dict(inst.outputs)


def test_lag_monitoring_switched_off_lets_the_jog_run_and_on_again_faults_it() -> None:
    """MaxPositionLag 0.5 mm is below the 0.796 mm a 100 mm/s jog lags by. With
    EnablePosLagMonitoring FALSE the jog runs (the limit is kept: 7 still reads 0.5);
    TRUE again and the axis faults within the cycle the error is checked in."""
    system = rig(fe_limit=0.5)
    assert read(system, 6, "ReadBool")["Value"] is True
    out = write_bool(system, 6, False)
    assert out["Done"] and not out["Error"]
    assert read(system, 6, "ReadBool")["Value"] is False
    assert read(system, 7)["Value"] == 0.5
    ax = system.ctl.axis(1)
    trigger(system, system["MAJ_1"], Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    for _ in range(300):  # at speed after 0.1 s: the steady error 2v/w
        system.cycle()
    assert ax.state == AxisState.SERVO_CONTROL and ax.fault == 0
    assert ax.position_error > 0.5
    assert write_bool(system, 6, True)["Done"]
    assert ax.state == AxisState.AXIS_FAULTED and ax.fault & AxisFault.POSITION_ERROR


def test_lag_monitoring_cannot_be_switched_on_without_a_limit() -> None:
    system = rig(fe_limit=0.0)
    out = write_bool(system, 6, True)
    assert out["Error"] and out["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert read(system, 6, "ReadBool")["Value"] is False
    # a limit written while the monitoring is off waits for it to be on again
    assert write_bool(system, 6, False)["Done"]
    assert write(system, 7, 0.5)["Done"]
    assert read(system, 6, "ReadBool")["Value"] is False
    assert write_bool(system, 6, True)["Done"]
    assert read(system, 6, "ReadBool")["Value"] is True


@pytest.mark.parametrize("number", [4, 5, 7, 99])
def test_other_bool_writes_are_refused(number: int) -> None:
    system = rig(fe_limit=2.0)
    out = write_bool(system, number, True)
    assert out["Error"] and not out["Done"]
    assert out["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert read(system, 6, "ReadBool")["Value"] is True  # unchanged


# -- the application limits (PLCopen's table: 9, 13, 15, 17 are R/W, 9 basic) -------------
@pytest.mark.parametrize(
    ("number", "system_number", "value"),
    [(9, 8, 100.0), (13, 12, 500.0), (15, 14, 750.0), (17, 16, 10000.0)],
)
def test_an_application_limit_is_written_and_read_back(
    number: int, system_number: int, value: float
) -> None:
    system = rig()
    before = read(system, system_number)["Value"]
    out = write(system, number, value)
    assert out["Done"] and not out["Error"] and out["ErrorID"] == 0
    assert read(system, number)["Value"] == value
    assert read(system, system_number)["Value"] == before  # the System limit stays


@pytest.mark.parametrize(
    ("number", "value"),
    [(9, 250.5), (9, 0.0), (9, -1.0), (9, math.nan), (9, math.inf), (13, 2000.5),
     (15, 3001.0), (17, 0.0), (17, JERK * 2)],
)  # fmt: skip
def test_an_application_limit_beyond_the_system_one_is_refused(number: int, value: float) -> None:
    system = rig()
    before = read(system, number)["Value"]
    out = write(system, number, value)
    assert out["Error"] and not out["Done"]
    assert out["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert read(system, number)["Value"] == before


@pytest.mark.parametrize(
    ("number", "value"),
    # the rig's 250 mm/s: stopping at 0.03 mm/s² takes 8,333 s, reaching it at 0.03 as
    # long; JERK's rates of 3000 and 2000 over a jerk of 0.3 take 10,000 s (the kernel
    # plans at most 7,600 s: a group stop from the Maximum Speed would be refused)
    [(15, 0.03), (13, 0.03), (17, 0.3)],
)
def test_an_application_limit_that_makes_a_ramp_too_long_is_refused(
    number: int, value: float
) -> None:
    system = rig()
    before = read(system, number)["Value"]
    out = write(system, number, value)
    assert out["Error"] and out["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert read(system, number)["Value"] == before
    # 250 / 0.0329 = 7,599 s: the longest stop the kernel plans, accepted
    out = write(system, 15, 0.0329)
    assert out["Done"] and not out["Error"]


def test_a_lowered_max_velocity_judges_the_next_plcopen_command() -> None:
    """MC_MoveVelocity at 150 mm/s: accepted under the System 250, refused (ErrorID 13)
    once MaxVelocityAppl is 100; 100 itself is accepted."""
    system = rig()
    vel = system.add(
        "MC_MoveVelocity",
        "Vel",
        {"Axis": 1, "Velocity": 150.0, "Acceleration": 1000.0, "Deceleration": 1000.0},
    )
    trigger(system, vel)
    assert vel.outputs["Busy"] and not vel.outputs["Error"]
    assert write(system, 9, 100.0)["Done"]
    vel.inputs["Execute"] = False
    system.cycle()
    trigger(system, vel)
    assert vel.outputs["Error"] and vel.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    vel.inputs["Execute"] = False
    system.cycle()
    trigger(system, vel, Velocity=100.0)
    assert vel.outputs["Busy"] and not vel.outputs["Error"]


def test_a_lowered_max_velocity_limits_a_logix_jog() -> None:
    """Logix limits a time-driven speed to the Maximum Speed: a MAJ at 200 mm/s runs at
    the written MaxVelocityAppl of 100 mm/s (reached after 100 / 1000 = 0.1 s)."""
    system = rig()
    assert write(system, 9, 100.0)["Done"]
    trigger(system, system["MAJ_1"], Speed=200.0, AccelRate=1000.0, DecelRate=1000.0)
    system.cycle(200)
    assert system.ctl.axis(1).command_velocity == pytest.approx(100.0, abs=1e-9)


def test_motion_already_running_keeps_its_profile_when_a_limit_is_lowered() -> None:
    """The documented choice: a jog at 200 mm/s started under the System 250 runs on at
    200 mm/s after MaxVelocityAppl drops to 100; an MC_Stop asked at 3000 mm/s² once
    MaxDecelerationAppl is 1000 brakes at 1000 mm/s² (a stop is limited, never refused):
    at rest after 200 / 1000 = 0.2 s = 100 cycles, not after 34."""
    system = rig()
    ax = system.ctl.axis(1)
    trigger(system, system["MAJ_1"], Speed=200.0, AccelRate=2000.0, DecelRate=2000.0)
    system.cycle(100)
    assert ax.command_velocity == pytest.approx(200.0)
    assert write(system, 9, 100.0)["Done"]
    assert write(system, 15, 1000.0)["Done"]
    system.cycle(50)
    assert ax.command_velocity == pytest.approx(200.0)
    stop = system.add("MC_Stop", "Stop", {"Axis": 1, "Deceleration": 3000.0})
    trigger(system, stop)
    assert stop.outputs["Busy"] and not stop.outputs["Error"]
    assert ax.command_velocity == pytest.approx(200.0 - 1000.0 * 0.002)
    system.cycle(98)
    assert ax.command_velocity == pytest.approx(2.0)
    system.cycle()
    assert ax.command_velocity == pytest.approx(0.0, abs=1e-9)
