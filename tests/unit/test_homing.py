"""MAH and MC_Home: the homing modes and sequences of MOTION-RM002/RM003, with numbers
from first principles.

The bench: a virtual axis (actual = command, so the sensors see the command exactly),
2 ms cycles, home speed 10 mm/s, return speed 2 mm/s, home acceleration and deceleration
100 mm/s², a home switch cam on [25.01, 30.01] mm and a marker every 1 mm from 0.505 mm.

A trapezoidal ramp at 100 mm/s² changes the speed by 0.2 mm/s per cycle and covers
v²/2a: 0.5 mm from 10 mm/s, 0.02 mm from 2 mm/s. The sensors latch their edge exactly;
the controller reacts one cycle later: a switch met during the cycle that ends at x
stops the axis at x + 0.5 mm.
"""

from __future__ import annotations

from typing import Any

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, ErrorCode, MotionStatusBit, PLCopenState
from motion_server.kernel.enums import HomeDirection, HomeMode, HomeSequence
from motion_server.kernel.homing import HomePhase, HomeProcess

from ..support import make_system, trigger

HOMING = 1 << MotionStatusBit.HOMING
HOMED = 1 << MotionStatusBit.HOMED

BENCH: dict[str, Any] = {
    "home_speed": 10.0,
    "home_return_speed": 2.0,
    "home_acceleration": 100.0,
    "home_deceleration": 100.0,
    "home_switch": 25.01,
    "home_switch_width": 5.0,
    "marker_interval": 1.0,
    "marker_offset": 0.505,
    "home_position": 100.0,
}


def bench(axis_type: AxisType = AxisType.VIRTUAL, **homing: Any) -> MotionSystem:
    cfg = AxisConfig(1, "Axis1", axis_type, **{**BENCH, **homing})
    wheel = AxisConfig(
        2,
        "Wheel",
        AxisType.FEEDBACK_ONLY,
        home_mode=HomeMode.PASSIVE,
        home_sequence=HomeSequence.MARKER,
        marker_interval=10.0,
        marker_offset=3.0,
        home_position=50.0,
    )
    system = make_system(cfg, wheel)
    system.add("MSO", "MSO_1", {"Axis": 1})
    system.add("MAH", "MAH_1", {"Axis": 1})
    trigger(system, system["MSO_1"])
    return system


def raw(system: MotionSystem, axis: int = 1) -> float:
    """Where the load is on the machine (the sensors' coordinates)."""
    ax = system.ctl.axis(axis)
    return ax.command_position_unwound - ax.position_offset


def home(system: MotionSystem, cycles: int = 40000) -> list[tuple[int, HomePhase, float]]:
    """Trigger MAH_1 and run until its IP clears; the (cycle, phase, command position)
    at each phase change."""
    mah = system["MAH_1"]
    trigger(system, mah)
    ax = system.ctl.axis(1)
    proc = next(p for p in ax.processes if isinstance(p, HomeProcess))
    phases = [(0, proc.phase, ax.command_position_unwound)]
    for k in range(1, cycles):
        if not mah.outputs["IP"]:
            return phases
        assert ax.plcopen_state == PLCopenState.HOMING
        assert ax.motion_status & HOMING
        system.cycle()
        if proc.phase != phases[-1][1]:
            phases.append((k, proc.phase, ax.command_position_unwound))
    raise AssertionError(f"homing did not end: {phases}")


def test_active_bidirectional_home_to_switch() -> None:
    """MOTION-RM003: on at the home speed until the switch, stop, back off at the return
    speed until the switch clears, assign the home position there, stop, move back to
    it at the return speed."""
    system = bench(home_sequence=HomeSequence.SWITCH)
    ax = system.ctl.axis(1)
    mah = system["MAH_1"]
    phases = home(system)
    names = [p for _, p, _ in phases]
    assert names == [
        HomePhase.SEEK,
        HomePhase.BRAKE,
        HomePhase.BACK_OFF,
        HomePhase.HOMED_BRAKE,
        HomePhase.RETURN,
        HomePhase.DONE,
    ]
    # 0.5 mm reaching 10 mm/s, then 10 mm/s: the cycle ending at 25.02 mm meets the
    # switch at 25.01; the brake starts in the next and takes 0.5 mm
    back_off = phases[2][2]
    assert back_off == pytest.approx(25.02 + 0.5, abs=1e-9)
    # the home event: the switch clears at 25.01 (raw), which now reads 100
    assert ax.position_offset == pytest.approx(100.0 - 25.01, abs=1e-9)
    # the sequence ends exactly on the home position, on the switch's edge
    assert ax.command_position == 100.0
    assert ax.actual_position == 100.0
    assert raw(system) == pytest.approx(25.01, abs=1e-9)
    assert ax.homed and ax.motion_status & HOMED
    assert mah.outputs["DN"] and mah.outputs["PC"] and not mah.outputs["ER"]
    assert ax.plcopen_state == PLCopenState.STANDSTILL


def test_the_home_offset_places_the_home_position_beyond_the_event() -> None:
    """The point of the home event reads home_position - home_offset (RA: "Home Offset
    10, Home Position 10" gives 0.0 at the marker): the return move ends home_offset
    beyond the switch's edge."""
    system = bench(home_sequence=HomeSequence.SWITCH, home_offset=3.0)
    home(system)
    ax = system.ctl.axis(1)
    assert ax.position_offset == pytest.approx(97.0 - 25.01, abs=1e-9)
    assert ax.command_position == 100.0
    assert raw(system) == pytest.approx(28.01, abs=1e-9)


def test_reverse_bidirectional_home_to_switch_uses_the_cams_other_edge() -> None:
    """Homing in reverse meets the cam [-20.01, -15.01] at its upper edge and takes the
    point where it clears going up again: -15.01."""
    system = bench(
        home_sequence=HomeSequence.SWITCH,
        home_direction=HomeDirection.BIDIRECTIONAL_REVERSE,
        home_switch=-20.01,
    )
    phases = home(system)
    # -15.02 is the first cycle end beyond the edge, then 0.5 mm of braking
    assert phases[2][2] == pytest.approx(-15.02 - 0.5, abs=1e-9)
    ax = system.ctl.axis(1)
    assert ax.position_offset == pytest.approx(100.0 + 15.01, abs=1e-9)
    assert ax.command_position == 100.0
    assert raw(system) == pytest.approx(-15.01, abs=1e-9)


def test_starting_on_the_switch_backs_off_it_first() -> None:
    """Bidirectional homing that starts on the cam goes straight to backing off it."""
    system = bench(home_sequence=HomeSequence.SWITCH)
    system.add("MAM", "MAM_1", {"Axis": 1})
    trigger(system, system["MAM_1"], Position=27.0, Speed=50.0, AccelRate=500.0, DecelRate=500.0)
    for _ in range(1000):
        system.cycle()
    ax = system.ctl.axis(1)
    assert ax.command_position == 27.0 and system.ctl.homing.switch(ax)
    phases = home(system)
    # at rest on the cam: the brake ends at once, the first step already backs off
    assert [p for _, p, _ in phases][:2] == [HomePhase.BACK_OFF, HomePhase.HOMED_BRAKE]
    assert ax.command_position == 100.0
    assert raw(system) == pytest.approx(25.01, abs=1e-9)


def test_active_bidirectional_home_to_marker() -> None:
    """The first marker in the home direction (0.505 mm) is the home event."""
    system = bench(home_sequence=HomeSequence.MARKER)
    phases = home(system)
    assert [p for _, p, _ in phases] == [
        HomePhase.SEEK,
        HomePhase.HOMED_BRAKE,
        HomePhase.RETURN,
        HomePhase.DONE,
    ]
    ax = system.ctl.axis(1)
    assert ax.position_offset == pytest.approx(100.0 - 0.505, abs=1e-9)
    assert ax.command_position == 100.0
    assert raw(system) == pytest.approx(0.505, abs=1e-9)


def test_active_bidirectional_home_to_switch_then_marker() -> None:
    """Back off the switch, then on to the first marker: below 25.01 going down that is
    24.505 mm."""
    system = bench(home_sequence=HomeSequence.SWITCH_THEN_MARKER)
    phases = home(system)
    assert HomePhase.FIND_MARKER in [p for _, p, _ in phases]
    ax = system.ctl.axis(1)
    assert ax.position_offset == pytest.approx(100.0 - 24.505, abs=1e-9)
    assert ax.command_position == 100.0
    assert raw(system) == pytest.approx(24.505, abs=1e-9)


def test_unidirectional_home_runs_on_to_the_home_position_beyond_the_stop() -> None:
    """MOTION-RM003: "by setting a Home Offset greater than the deceleration distance,
    unidirectional motion to the Home Position is insured". Offset 1 mm > 0.5 mm: the
    switch reads 99 and the axis moves on, never back, to 100 (raw 26.01)."""
    system = bench(
        home_sequence=HomeSequence.SWITCH,
        home_direction=HomeDirection.UNIDIRECTIONAL_FORWARD,
        home_offset=1.0,
    )
    ax = system.ctl.axis(1)
    trigger(system, system["MAH_1"])
    velocities = []
    while system["MAH_1"].outputs["IP"]:
        system.cycle()
        velocities.append(ax.command_velocity)
    assert min(velocities) >= 0.0  # unidirectional
    assert ax.position_offset == pytest.approx(99.0 - 25.01, abs=1e-9)
    assert ax.command_position == 100.0
    assert raw(system) == pytest.approx(26.01, abs=1e-9)
    assert system["MAH_1"].outputs["PC"]


def test_unidirectional_home_within_the_stopping_distance_just_stops() -> None:
    """ "If the Home Offset value is less than the deceleration distance, then the axis is
    simply decelerated to a stop ... the PC-bit leg is not set when the IP-bit leg is
    cleared." The switch reads 99.8 (offset 0.2 mm), the cycle ends 0.01 mm beyond it and
    the stop takes 0.5 mm: at rest at 100.31, homed, without PC."""
    system = bench(
        home_sequence=HomeSequence.SWITCH,
        home_direction=HomeDirection.UNIDIRECTIONAL_FORWARD,
        home_offset=0.2,
    )
    phases = home(system)
    assert [p for _, p, _ in phases] == [HomePhase.SEEK, HomePhase.HOMED_BRAKE, HomePhase.DONE]
    ax = system.ctl.axis(1)
    assert ax.command_position == pytest.approx(99.8 + 0.01 + 0.5, abs=1e-9)
    assert ax.homed
    mah = system["MAH_1"]
    assert mah.outputs["DN"] and not mah.outputs["PC"] and not mah.outputs["IP"]


def test_unidirectional_rotary_homing_adds_a_turn_to_stay_unidirectional() -> None:
    """A cyclic axis: "the control automatically adds one or more revolutions to the
    move distance". Home position 0 at the marker (10.005°): the axis runs on almost a
    full turn to read 0 again, on the same marker."""
    system = bench(
        units="deg",
        rollover=360.0,
        home_sequence=HomeSequence.MARKER,
        home_direction=HomeDirection.UNIDIRECTIONAL_FORWARD,
        home_position=0.0,
        home_switch=None,
        marker_interval=360.0,
        marker_offset=10.005,
    )
    home(system)
    ax = system.ctl.axis(1)
    assert ax.command_position == pytest.approx(0.0, abs=1e-9) or ax.command_position == (
        pytest.approx(360.0, abs=1e-9)
    )
    assert raw(system) == pytest.approx(10.005 + 360.0, abs=1e-9)
    assert system["MAH_1"].outputs["PC"]


def test_servo_axis_homes_on_its_actual_position() -> None:
    """A servo axis lags its command by 2v/ω; the switch sees the load, so the home
    event is where the actual position clears the cam, and the sequence still ends with
    the command on the home position."""
    system = bench(AxisType.SERVO, home_sequence=HomeSequence.SWITCH)
    home(system)
    ax = system.ctl.axis(1)
    assert ax.position_offset == pytest.approx(100.0 - 25.01, abs=1e-9)
    assert ax.command_position == 100.0
    for _ in range(200):
        system.cycle()
    assert ax.actual_position == pytest.approx(100.0, abs=1e-3)  # one encoder count


def test_immediate_homing_is_done_in_the_scan_of_the_edge() -> None:
    system = bench(home_sequence=HomeSequence.IMMEDIATE, home_position=12.5)
    trigger(system, system["MAH_1"])
    ax = system.ctl.axis(1)
    mah = system["MAH_1"]
    assert mah.outputs["DN"] and mah.outputs["PC"] and not mah.outputs["IP"]
    assert ax.actual_position == 12.5 and ax.command_position == 12.5
    assert ax.homed


def test_absolute_homing_needs_the_servo_loop_disabled() -> None:
    """MOTION-RM002: "prior to execution of the absolute homing process ... the axis must
    be in the Axis Ready state with the servo loop disabled"."""
    system = bench(home_mode=HomeMode.ABSOLUTE, home_position=7.0)
    mah = system["MAH_1"]
    trigger(system, mah)
    assert mah.outputs["ER"] and mah.outputs["ERR"] == ErrorCode.SERVO_ON_STATE
    mah.inputs["Execute"] = False
    system.cycle()
    system.add("MSF", "MSF_1", {"Axis": 1})
    trigger(system, system["MSF_1"])
    trigger(system, mah)
    assert mah.outputs["PC"] and not mah.outputs["ER"]
    assert system.ctl.axis(1).actual_position == 7.0


def test_active_homing_needs_servo_control() -> None:
    system = bench(home_sequence=HomeSequence.SWITCH)
    mah = system["MAH_1"]
    system.add("MSF", "MSF_1", {"Axis": 1})
    trigger(system, system["MSF_1"])
    trigger(system, mah)
    assert mah.outputs["ER"] and mah.outputs["ERR"] == ErrorCode.SERVO_OFF_STATE
    assert not system.ctl.axis(1).processes


def test_active_homing_needs_the_sensor_of_its_sequence() -> None:
    """A sequence whose sensor the axis lacks is refused (ERR 13) and nothing moves."""
    system = bench(home_sequence=HomeSequence.SWITCH, home_switch=None)
    mah = system["MAH_1"]
    trigger(system, mah)
    assert mah.outputs["ER"] and mah.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    ax = system.ctl.axis(1)
    assert ax.command_position == 0.0 and not ax.processes


def test_passive_homing_on_a_hand_wheel_takes_the_next_marker() -> None:
    """MOTION-RM002: passive homing "re-defines the actual position ... on the next
    occurrence of the encoder marker"; the axis is moved by other means. The wheel's
    markers are every 10 mm from 3 mm: turned from 0 to 2 nothing happens, from 2 to 4
    it passes 3, which reads the home position 50; at 4 it reads 51."""
    system = bench()
    mah = system["MAH_1"]
    wheel = system.ctl.axis(2)
    trigger(system, mah, Axis=2)
    assert mah.outputs["DN"] and mah.outputs["IP"]
    assert wheel.motion_status & HOMING
    system.ctl.set_feedback_input(wheel, 2.0)
    system.cycle()
    assert mah.outputs["IP"] and not wheel.homed
    system.ctl.set_feedback_input(wheel, 4.0)
    system.cycle()
    assert mah.outputs["PC"] and not mah.outputs["IP"]
    assert wheel.actual_position == 51.0
    assert wheel.homed and not wheel.motion_status & HOMING
    # the wheel's readings follow the new coordinates
    system.ctl.set_feedback_input(wheel, 5.5)
    system.cycle()
    assert wheel.actual_position == 52.5


def test_passive_homing_of_an_axis_moved_by_a_jog() -> None:
    """Passive homing on a driven axis: a MAJ moves it past the switch (25.01), which
    then reads the home position; the jog goes on undisturbed."""
    system = bench(home_mode=HomeMode.PASSIVE, home_sequence=HomeSequence.SWITCH)
    system.add("MAJ", "MAJ_1", {"Axis": 1})
    trigger(system, system["MAH_1"])
    trigger(system, system["MAJ_1"], Speed=10.0, AccelRate=100.0, DecelRate=100.0)
    ax = system.ctl.axis(1)
    for _ in range(1400):
        system.cycle()
    assert system["MAH_1"].outputs["PC"]
    assert ax.position_offset == pytest.approx(100.0 - 25.01, abs=1e-9)
    assert ax.command_velocity == 10.0  # the jog runs on
    assert system["MAJ_1"].outputs["IP"]


def test_mas_home_stops_an_active_homing_without_pc() -> None:
    system = bench(home_sequence=HomeSequence.SWITCH)
    system.add("MAS", "MAS_1", {"Axis": 1, "StopType": 4})
    trigger(system, system["MAH_1"])
    for _ in range(100):
        system.cycle()
    trigger(system, system["MAS_1"])
    for _ in range(200):
        system.cycle()
    mah = system["MAH_1"]
    assert not mah.outputs["IP"] and not mah.outputs["PC"] and not mah.outputs["ER"]
    ax = system.ctl.axis(1)
    assert ax.command_velocity == 0.0 and not ax.homed
    assert system["MAS_1"].outputs["PC"]


def test_mas_home_ends_a_passive_homing() -> None:
    system = bench()
    system.add("MAS", "MAS_1", {"Axis": 2, "StopType": 4})
    trigger(system, system["MAH_1"], Axis=2)
    trigger(system, system["MAS_1"])
    assert system["MAS_1"].outputs["PC"]
    assert not system["MAH_1"].outputs["IP"]
    system.ctl.set_feedback_input(system.ctl.axis(2), 4.0)
    system.cycle()
    assert system.ctl.axis(2).actual_position == 4.0  # no home event any more


# -- MC_Home ----------------------------------------------------------------------------------


def plcopen_bench(**homing: Any) -> MotionSystem:
    system = bench(**homing)
    power = system.add("MC_Power", "Power", {"Axis": 1})
    power.inputs["Enable"] = True
    system.add("MC_Home", "Home", {"Axis": 1})
    system.cycle()
    return system


def run_block(system: MotionSystem, name: str, cycles: int = 5000, **operands: Any) -> None:
    block = system[name]
    trigger(system, block, **operands)
    for _ in range(cycles):
        if not block.outputs["Busy"]:
            return
        system.cycle()
    raise AssertionError(f"{name} still busy")


def test_mc_home_to_the_switch_ends_at_standstill_where_it_stopped() -> None:
    """HomingMode 1: the point where the switch clears reads Position, then the axis
    stops ("the standstill position deviates by the braking distance, nevertheless the
    calibration is exact", TwinCAT). Backing off at 2 mm/s from rest at 25.52 (0.02 mm to
    reach the speed, then 0.004 mm per cycle), the cycle ending at 25.008 passes 25.01;
    the stop takes 0.02 mm: at rest on raw 24.988, which reads -0.022."""
    system = plcopen_bench()
    ax = system.ctl.axis(1)
    trigger(system, system["Home"], HomingMode=1, Position=0.0)
    assert system["Home"].outputs["Active"] and ax.plcopen_state == PLCopenState.HOMING
    run_block(system, "Home")
    assert system["Home"].outputs["Done"]
    assert ax.position_offset == pytest.approx(-25.01, abs=1e-9)
    assert raw(system) == pytest.approx(24.988, abs=1e-9)
    assert ax.command_position == pytest.approx(-0.022, abs=1e-9)
    assert ax.command_velocity == 0.0 and ax.plcopen_state == PLCopenState.STANDSTILL
    assert ax.homed


def test_mc_home_to_the_marker_stops_past_it() -> None:
    """HomingMode 3: the marker at 0.505 reads Position 7. Accelerating at 100 mm/s² the
    axis is at 0.0002 k² mm after k cycles: 0.5 at k = 50 (10 mm/s), 0.52 one cycle on.
    That cycle passes the marker; the stop takes 0.5 mm: at rest on raw 1.02, which
    reads 7 + 0.515 = 7.515."""
    system = plcopen_bench()
    ax = system.ctl.axis(1)
    run_block(system, "Home", HomingMode=3, Position=7.0)
    assert ax.position_offset == pytest.approx(7.0 - 0.505, abs=1e-9)
    assert ax.command_position == pytest.approx(7.515, abs=1e-9)
    assert system["Home"].outputs["Done"]


def test_mc_home_direct_and_calibration_flags() -> None:
    system = plcopen_bench()
    ax = system.ctl.axis(1)
    run_block(system, "Home", HomingMode=4, Position=-3.25)
    assert ax.actual_position == -3.25 and ax.homed
    system["Home"].inputs["Execute"] = False
    system.cycle()
    run_block(system, "Home", HomingMode=8)
    assert not ax.homed and ax.actual_position == -3.25
    system["Home"].inputs["Execute"] = False
    system.cycle()
    run_block(system, "Home", HomingMode=7)
    assert ax.homed and ax.actual_position == -3.25


def test_mc_home_starts_from_standstill_only() -> None:
    system = plcopen_bench()
    system.add("MC_MoveVelocity", "Velocity", {"Axis": 1})
    trigger(system, system["Velocity"], Velocity=5.0)
    trigger(system, system["Home"], HomingMode=1)
    assert system["Home"].outputs["Error"]
    assert system["Home"].outputs["ErrorID"] == ErrorCode.AXIS_IN_MOTION
    # the refused homing changed nothing: the velocity block still runs
    assert system["Velocity"].outputs["Busy"] and not system["Velocity"].outputs["CommandAborted"]


def test_mc_home_is_aborted_by_mc_stop() -> None:
    system = plcopen_bench()
    system.add("MC_Stop", "Stop", {"Axis": 1})
    trigger(system, system["Home"], HomingMode=1)
    for _ in range(50):
        system.cycle()
    trigger(system, system["Stop"], Deceleration=100.0)
    assert system["Home"].outputs["CommandAborted"]
    assert not system.ctl.axis(1).homed


def test_mc_home_refuses_a_mode_that_is_not_simulated() -> None:
    system = plcopen_bench()
    trigger(system, system["Home"], HomingMode=6)  # TwinCAT MC_Block
    assert system["Home"].outputs["Error"]
    assert system["Home"].outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
