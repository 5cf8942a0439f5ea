"""MGS: the five programmed stop modes, a group mixing them, and the forced stop modes.

Numbers from first principles. Every axis jogs at V = 100 mm/s on an S-curve (jerk
20 000 mm/s^3) and has settled there. Maximum deceleration D = 2000 mm/s^2, coast
deceleration C = 500 mm/s^2, coarse update dt = 2 ms:

- a fast stop is a trapezoidal ramp: the command velocity drops by D*dt = 4 mm/s every
  cycle from the first one (no jerk ramp-in), the second difference of the command
  position is -D*dt^2 = -0.008 mm, the axis rests after V/D = 50 ms = 25 cycles, having
  travelled V^2/(2D) = 2.5 mm;
- a coasting axis loses C*dt = 1 mm/s of actual velocity per cycle from the actual
  velocity v it had when the drive went off, and rests after ceil(v/(C*dt)) cycles (v is
  the drive model's actual velocity, a little under V: at most 100 cycles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from motion_server.instructions import Instruction, LogixInstruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisState,
    AxisType,
    MotionStatusBit,
    ProgrammedStopMode,
)

from ..support import make_system, trigger

DT = 0.002
V = 100.0
D = 2000.0
C = 500.0
JERK = 20000.0
STOP_CYCLES = 25  # V / D / dt
STOPPING = 1 << MotionStatusBit.STOPPING


def axis(number: int, mode: ProgrammedStopMode) -> AxisConfig:
    return AxisConfig(
        number,
        f"Axis{number}",
        AxisType.SERVO,
        max_velocity=200.0,
        max_acceleration=1000.0,
        max_deceleration=D,
        programmed_stop_mode=mode,
        coast_deceleration=C,
        drive_bandwidth=40.0,
    )


def jogging(*modes: ProgrammedStopMode) -> MotionSystem:
    """One axis per mode, each enabled and jogging at V on an S-curve, settled."""
    system = make_system(*(axis(i + 1, m) for i, m in enumerate(modes)), period=DT)
    for n in range(1, len(modes) + 1):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
        maj = system.add(
            "MAJ",
            f"MAJ_{n}",
            {
                "Axis": n,
                "Speed": V,
                "AccelRate": 1000.0,
                "DecelRate": 1000.0,
                "Profile": 1,
                "AccelJerk": JERK,
                "DecelJerk": JERK,
                "JerkUnits": 0,
            },
        )
        trigger(system, maj)
    system.cycle(300)  # S-curve ramp 75 cycles, then the servo loop settles
    for n in range(1, len(modes) + 1):
        ax = system.ctl.axis(n)
        assert ax.command_velocity == pytest.approx(V, abs=1e-9)
        # critically damped: no overshoot (up to float rounding)
        assert 0.9 * V < ax.actual_velocity <= V * (1 + 1e-12)
    return system


@dataclass
class Trace:
    """Per cycle after the MGS edge: MGS bits and each axis's state and kinematics."""

    bits: list[tuple[bool, bool, bool]] = field(default_factory=list)
    cmd_pos: dict[int, list[float]] = field(default_factory=dict)
    cmd_vel: dict[int, list[float]] = field(default_factory=dict)
    act_vel: dict[int, list[float]] = field(default_factory=dict)
    state: dict[int, list[AxisState]] = field(default_factory=dict)
    status: dict[int, list[int]] = field(default_factory=dict)

    def pc_cycle(self) -> int:
        """1-based cycle in which PC was first set."""
        return next(k + 1 for k, (_, _, pc) in enumerate(self.bits) if pc)


def logix(inst: Instruction) -> LogixInstruction:
    assert isinstance(inst, LogixInstruction)
    return inst


def run_mgs(
    system: MotionSystem, cycles: int, stop_mode: int = 0
) -> tuple[LogixInstruction, Trace]:
    mgs = logix(system.add("MGS", "MGS_1", {"Group": 1, "StopMode": stop_mode}))
    mgs.inputs["Execute"] = True
    trace = Trace()
    axes = system.ctl.axes
    for ax in axes:
        trace.cmd_pos[ax.number] = []
        trace.cmd_vel[ax.number] = []
        trace.act_vel[ax.number] = []
        trace.state[ax.number] = []
        trace.status[ax.number] = []
    for _ in range(cycles):
        system.cycle()
        trace.bits.append((mgs.bit("DN"), mgs.bit("IP"), mgs.bit("PC")))
        for ax in axes:
            trace.cmd_pos[ax.number].append(ax.command_position_unwound)
            trace.cmd_vel[ax.number].append(ax.command_velocity)
            trace.act_vel[ax.number].append(ax.actual_velocity)
            trace.state[ax.number].append(ax.state)
            trace.status[ax.number].append(ax.motion_status)
    return mgs, trace


def assert_dn_ip_pc(trace: Trace, pc_cycle: int) -> None:
    """DN and IP from the first cycle, IP alone (with DN) until PC, then PC without IP."""
    assert pc_cycle > 10  # several cycles, not one
    assert trace.bits[0] == (True, True, False)
    for k in range(pc_cycle - 1):
        assert trace.bits[k] == (True, True, False), k
    assert trace.pc_cycle() == pc_cycle
    assert all(b == (True, False, True) for b in trace.bits[pc_cycle - 1 :])


def assert_fast_ramp(trace: Trace, n: int, v0: float = V) -> None:
    """The command decelerates at D from the first cycle: trapezoidal, no jerk limit."""
    vel = np.array(trace.cmd_vel[n][:STOP_CYCLES])
    expected = v0 - D * DT * np.arange(1, STOP_CYCLES + 1)
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    pos = np.array(trace.cmd_pos[n][:STOP_CYCLES])
    np.testing.assert_allclose(np.diff(pos, 2), -D * DT * DT, atol=1e-9)
    # at rest after V/D, V^2/(2D) beyond where the stop began
    start = trace.cmd_pos[n][0] - (v0 * DT - D * DT * DT / 2)
    assert trace.cmd_pos[n][STOP_CYCLES - 1] - start == pytest.approx(v0 * v0 / (2 * D), abs=1e-9)
    assert all(v == 0.0 for v in trace.cmd_vel[n][STOP_CYCLES - 1 :])


def assert_coasting(trace: Trace, n: int, v0: float) -> int:
    """Actual velocity falls by C*dt per cycle from the first cycle; returns the cycle
    (1-based) in which the axis came to rest."""
    act = np.array(trace.act_vel[n])
    rest = int(np.argmax(act == 0.0)) + 1
    assert rest == math.ceil(v0 / (C * DT) - 1e-9)
    np.testing.assert_allclose(act[: rest - 1], v0 - C * DT * np.arange(1, rest), atol=1e-9)
    # with the drive off the command follows the actual position
    np.testing.assert_allclose(trace.cmd_vel[n][: rest - 1], act[: rest - 1], atol=1e-9)
    return rest


def test_fast_stop_decelerates_at_max_deceleration_and_keeps_servo_control() -> None:
    system = jogging(ProgrammedStopMode.FAST_STOP)
    _, trace = run_mgs(system, 60)
    assert_fast_ramp(trace, 1)
    assert set(trace.state[1]) == {AxisState.SERVO_CONTROL}
    assert_dn_ip_pc(trace, STOP_CYCLES)
    # StoppingStatus while the ramp runs, cleared at rest
    assert all(s & STOPPING for s in trace.status[1][: STOP_CYCLES - 1])
    assert not trace.status[1][STOP_CYCLES - 1] & STOPPING
    assert not logix(system["MAJ_1"]).bit("IP")


def test_fast_disable_ramps_then_disables_the_drive_once_at_rest() -> None:
    system = jogging(ProgrammedStopMode.FAST_DISABLE)
    ax = system.ctl.axis(1)
    _, trace = run_mgs(system, 120)
    assert_fast_ramp(trace, 1)
    states = trace.state[1]
    # Servo Control through the whole ramp, Axis Ready afterwards
    assert all(s == AxisState.SERVO_CONTROL for s in states[:STOP_CYCLES])
    disabled = states.index(AxisState.AXIS_READY) + 1
    assert disabled > STOP_CYCLES
    # the drive is disabled only once it moves less than one count (1 um) per cycle
    assert abs(trace.act_vel[1][disabled - 1]) * DT < 1e-3
    assert abs(trace.act_vel[1][disabled - 2]) * DT >= 1e-3
    assert states[-1] == AxisState.AXIS_READY and not ax.drive_enabled
    assert_dn_ip_pc(trace, trace.pc_cycle())
    assert trace.pc_cycle() >= disabled


def test_hard_disable_turns_the_drive_off_at_once_and_the_axis_coasts() -> None:
    system = jogging(ProgrammedStopMode.HARD_DISABLE)
    v0 = system.ctl.axis(1).actual_velocity
    _, trace = run_mgs(system, 130)
    assert set(trace.state[1]) == {AxisState.AXIS_READY}
    rest = assert_coasting(trace, 1, v0)
    assert_dn_ip_pc(trace, rest)
    # StoppingStatus while coasting under the group stop, cleared at rest
    assert all(s & STOPPING for s in trace.status[1][: rest - 1])
    assert not trace.status[1][rest - 1] & STOPPING


def test_fast_shutdown_ramps_then_shuts_the_axis_down() -> None:
    system = jogging(ProgrammedStopMode.FAST_SHUTDOWN)
    _, trace = run_mgs(system, 120)
    assert_fast_ramp(trace, 1)
    states = trace.state[1]
    assert all(s == AxisState.SERVO_CONTROL for s in states[:STOP_CYCLES])
    assert states[-1] == AxisState.AXIS_SHUTDOWN
    assert AxisState.AXIS_READY not in states
    assert_dn_ip_pc(trace, trace.pc_cycle())
    assert trace.pc_cycle() > STOP_CYCLES


def test_hard_shutdown_shuts_down_at_once_and_the_axis_coasts() -> None:
    system = jogging(ProgrammedStopMode.HARD_SHUTDOWN)
    v0 = system.ctl.axis(1).actual_velocity
    _, trace = run_mgs(system, 130)
    assert set(trace.state[1]) == {AxisState.AXIS_SHUTDOWN}
    rest = assert_coasting(trace, 1, v0)
    assert_dn_ip_pc(trace, rest)


def test_a_group_mixing_the_five_modes_stops_together() -> None:
    modes = list(ProgrammedStopMode)
    system = jogging(*modes)
    v0 = {n: system.ctl.axis(n).actual_velocity for n in range(1, 6)}
    _, trace = run_mgs(system, 130)
    final = {n: trace.state[n][-1] for n in range(1, 6)}
    assert final == {
        1: AxisState.SERVO_CONTROL,  # fast stop
        2: AxisState.AXIS_READY,  # fast disable
        3: AxisState.AXIS_READY,  # hard disable
        4: AxisState.AXIS_SHUTDOWN,  # fast shutdown
        5: AxisState.AXIS_SHUTDOWN,  # hard shutdown
    }
    for n in (1, 2, 4):
        assert_fast_ramp(trace, n)
    rests = [assert_coasting(trace, n, v0[n]) for n in (3, 5)]
    # the coasting axes are the last to rest: PC waits for them, IP holds until then
    assert_dn_ip_pc(trace, max(rests))
    assert max(rests) > STOP_CYCLES


@pytest.mark.parametrize("configured", list(ProgrammedStopMode))
def test_mgs_fast_stop_forces_a_fast_stop_whatever_the_configuration(
    configured: ProgrammedStopMode,
) -> None:
    system = jogging(configured)
    _, trace = run_mgs(system, 40, stop_mode=1)
    assert_fast_ramp(trace, 1)
    assert set(trace.state[1]) == {AxisState.SERVO_CONTROL}
    assert_dn_ip_pc(trace, STOP_CYCLES)


@pytest.mark.parametrize("configured", list(ProgrammedStopMode))
def test_mgs_fast_disable_forces_a_fast_disable_whatever_the_configuration(
    configured: ProgrammedStopMode,
) -> None:
    system = jogging(configured)
    _, trace = run_mgs(system, 120, stop_mode=2)
    assert_fast_ramp(trace, 1)
    states = trace.state[1]
    assert all(s == AxisState.SERVO_CONTROL for s in states[:STOP_CYCLES])
    assert states[-1] == AxisState.AXIS_READY
    assert AxisState.AXIS_SHUTDOWN not in states
    assert_dn_ip_pc(trace, trace.pc_cycle())


def test_fast_stop_during_an_s_curve_acceleration_has_no_jerk_limit() -> None:
    """Stopping while the S-curve still accelerates: the acceleration jumps to -D in one
    cycle (the ramp is trapezoidal), it is not ramped down at the jerk limit."""
    system = make_system(axis(1, ProgrammedStopMode.FAST_STOP), period=DT)
    trigger(system, system.add("MSO", "MSO_1", {"Axis": 1}))
    maj = system.add(
        "MAJ",
        "MAJ_1",
        {
            "Axis": 1,
            "Speed": V,
            "AccelRate": 1000.0,
            "DecelRate": 1000.0,
            "Profile": 1,
            "AccelJerk": JERK,
            "DecelJerk": JERK,
            "JerkUnits": 0,
        },
    )
    trigger(system, maj)
    system.cycle(49)  # 50 cycles = 0.1 s in: constant-acceleration phase at 1000 mm/s^2
    ax = system.ctl.axis(1)
    assert ax.command_acceleration == pytest.approx(1000.0)
    v0 = ax.command_velocity
    _, trace = run_mgs(system, 40)
    n = math.ceil(v0 / (D * DT) - 1e-9)
    vel = np.array(trace.cmd_vel[1][:n])
    np.testing.assert_allclose(vel[:-1], v0 - D * DT * np.arange(1, n), atol=1e-9)
    assert vel[-1] == 0.0
    assert_dn_ip_pc(trace, n)
