"""MGS status: cleared MotionStatus bits, instructions losing IP, PLCopen blocks aborted,
errors, DN timing on a slower group, and the stop applied when leaving run mode.

Axis: max deceleration D = 2000 mm/s^2, dt = 2 ms. A jog at 60 mm/s and an incremental
move cruising at 40 mm/s superimpose to 100 mm/s; the group stop ramps that sum down by
D*dt = 4 mm/s per cycle and rests after 100/2000 s = 25 cycles.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_server.instructions import Instruction, LogixInstruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisState,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    MotionStatusBit,
    ProgrammedStopMode,
)
from motion_server.kernel.group import GroupState, OperatingMode

from ..support import make_system, trigger

DT = 0.002
D = 2000.0

#: the seed's table: bits MGS clears (StoppingStatus is set instead)
CLEARED = (
    MotionStatusBit.MOVE,
    MotionStatusBit.JOG,
    MotionStatusBit.GEARING,
    MotionStatusBit.HOMING,
    MotionStatusBit.POSITION_CAM,
    MotionStatusBit.TIME_CAM,
    MotionStatusBit.POSITION_CAM_PENDING,
    MotionStatusBit.TIME_CAM_PENDING,
    MotionStatusBit.GEARING_LOCK,
    MotionStatusBit.POSITION_CAM_LOCK,
)


def bit(word: int, b: MotionStatusBit) -> bool:
    return bool(word >> b & 1)


def logix(inst: Instruction) -> LogixInstruction:
    assert isinstance(inst, LogixInstruction)
    return inst


def servo(number: int, mode: ProgrammedStopMode = ProgrammedStopMode.FAST_STOP) -> AxisConfig:
    return AxisConfig(
        number,
        f"Axis{number}",
        AxisType.SERVO,
        max_velocity=200.0,
        max_acceleration=1000.0,
        max_deceleration=D,
        programmed_stop_mode=mode,
    )


def enable(system: MotionSystem, *axes: int) -> None:
    for n in axes:
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))


def superimposed(system: MotionSystem) -> tuple[LogixInstruction, LogixInstruction]:
    """MAJ at 60 mm/s and an incremental MAM cruising at 40 mm/s on axis 1."""
    maj = logix(system.add("MAJ", "MAJ_1", {"Axis": 1, "Speed": 60.0, "AccelRate": 1000.0}))
    mam = logix(
        system.add(
            "MAM",
            "MAM_1",
            {"Axis": 1, "MoveType": 1, "Position": 1000.0, "Speed": 40.0, "AccelRate": 1000.0},
        )
    )
    trigger(system, maj)
    trigger(system, mam)
    system.cycle(100)
    return maj, mam


def test_mgs_on_a_jog_and_an_incremental_move_superimposed() -> None:
    system = make_system(servo(1), servo(2))
    enable(system, 1, 2)
    maj, mam = superimposed(system)
    ax = system.ctl.axis(1)
    assert ax.command_velocity == pytest.approx(100.0, abs=1e-9)
    before = ax.motion_status
    assert bit(before, MotionStatusBit.JOG) and bit(before, MotionStatusBit.MOVE)

    # a PLCopen move on the other axis of the group
    mc = system.add("MC_MoveAbsolute", "MC_1", {"Axis": 2, "Position": 500.0, "Velocity": 50.0})
    trigger(system, mc)
    assert mc.outputs["Busy"] and not mc.outputs["CommandAborted"]

    mgs = logix(system.add("MGS", "MGS_1", {"Group": 1}))
    trigger(system, mgs)
    # the stop replaced both processes: their instructions lose IP, the move gets no PC
    assert not maj.bit("IP") and not mam.bit("IP") and not mam.bit("PC")
    assert maj.bit("DN") and mam.bit("DN")
    assert mc.outputs["CommandAborted"] and not mc.outputs["Busy"]
    assert not mc.outputs["Active"] and not mc.outputs["Done"]
    word = ax.motion_status
    assert bit(word, MotionStatusBit.STOPPING)
    assert not any(bit(word, b) for b in CLEARED)
    # one ramp from the summed velocity at the axis maximum deceleration
    vel = [ax.command_velocity]
    for _ in range(30):
        system.cycle()
        vel.append(ax.command_velocity)
    expected = np.maximum(100.0 - D * DT * np.arange(1, 32), 0.0)
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert mgs.bit("PC") and not mgs.bit("IP")
    assert not bit(ax.motion_status, MotionStatusBit.STOPPING)
    assert ax.state == AxisState.SERVO_CONTROL


def test_stopping_status_clears_with_each_axis_at_rest() -> None:
    """StoppingStatus is per axis: a slow axis keeps it after a fast one has rested."""
    system = make_system(servo(1), servo(2))
    enable(system, 1, 2)
    for n, speed in ((1, 20.0), (2, 100.0)):
        maj = system.add("MAJ", f"MAJ_{n}", {"Axis": n, "Speed": speed, "AccelRate": 1000.0})
        trigger(system, maj)
    system.cycle(100)
    mgs = logix(system.add("MGS", "MGS_1", {"Group": 1}))
    trigger(system, mgs)
    system.cycle(5)  # 20 mm/s rests after 5 cycles, 100 mm/s after 25
    a1, a2 = system.ctl.axis(1), system.ctl.axis(2)
    assert not bit(a1.motion_status, MotionStatusBit.STOPPING)
    assert bit(a2.motion_status, MotionStatusBit.STOPPING)
    assert mgs.bit("IP") and system.ctl.groups[0].state == GroupState.STOPPING
    system.cycle(19)
    assert mgs.bit("PC") and system.ctl.groups[0].state == GroupState.NORMAL


def test_motion_is_refused_while_the_group_stops_and_accepted_after() -> None:
    system = make_system(servo(1))
    enable(system, 1)
    superimposed(system)
    mgs = logix(system.add("MGS", "MGS_1", {"Group": 1}))
    trigger(system, mgs)
    maj = logix(system.add("MAJ", "MAJ_2", {"Axis": 1, "Speed": 10.0}))
    trigger(system, maj)
    assert maj.bit("ER") and maj.outputs["ERR"] == ErrorCode.NOT_ALLOWED_WHILE_STOPPING
    maj.inputs["Execute"] = False
    system.cycle(30)
    assert mgs.bit("PC")
    trigger(system, maj)
    assert maj.bit("IP") and not maj.bit("ER")


def test_mgs_errors_leave_the_axes_moving() -> None:
    system = make_system(servo(1))
    enable(system, 1)
    superimposed(system)
    ax = system.ctl.axis(1)
    bad_group = logix(system.add("MGS", "MGS_1", {"Group": 7}))
    trigger(system, bad_group)
    assert bad_group.bit("ER") and bad_group.outputs["ERR"] == ErrorCode.GROUP_NOT_CONFIGURED
    bad_mode = logix(system.add("MGS", "MGS_2", {"Group": 1, "StopMode": 3}))
    trigger(system, bad_mode)
    # StopMode is the third operand of MGS(Group, MotionControl, StopMode)
    assert bad_mode.bit("ER") and bad_mode.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert bad_mode.outputs["EXERR"] == 2
    assert ax.command_velocity == pytest.approx(100.0, abs=1e-9)
    assert not ax.stopping


def test_mgs_on_a_group_at_rest_completes_in_one_update() -> None:
    system = make_system(servo(1))
    enable(system, 1)
    mgs = logix(system.add("MGS", "MGS_1", {"Group": 1}))
    trigger(system, mgs)
    assert mgs.bit("DN") and mgs.bit("PC") and not mgs.bit("IP")


def test_dn_waits_for_the_coarse_update_of_a_slower_group() -> None:
    """The stop is initiated by the group's coarse update: on a 4 ms group scanned every
    2 ms, DN is not set in the scan of the rising edge but after the next update."""
    ctl = Controller(
        [servo(1), servo(2)],
        [GroupConfig(1, "Fast", (1,), 0.002), GroupConfig(2, "Slow", (2,), 0.004)],
    )
    system = MotionSystem(ctl)
    enable(system, 2)
    maj = system.add("MAJ", "MAJ_2", {"Axis": 2, "Speed": 40.0, "AccelRate": 1000.0})
    trigger(system, maj)
    system.cycle(50)
    if ctl.tick % 2 == 1:
        system.cycle()  # make the next tick one where the slow group does not update
    mgs = logix(system.add("MGS", "MGS_1", {"Group": 2}))
    trigger(system, mgs)
    assert mgs.bit("EN") and mgs.bit("IP") and not mgs.bit("DN")
    assert ctl.axis(2).command_velocity == 40.0
    system.cycle()
    assert mgs.bit("DN") and mgs.bit("IP")
    # each 4 ms update takes D * 4 ms = 8 mm/s off; nothing changes between updates
    ax = ctl.axis(2)
    vel = [ax.command_velocity]
    while not mgs.bit("PC") and len(vel) < 20:
        system.cycle()
        vel.append(ax.command_velocity)
        assert mgs.bit("DN")
    expected = [max(32.0 - 8.0 * (k // 2), 0.0) for k in range(len(vel))]
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert mgs.bit("PC") and not mgs.bit("IP")
    assert ctl.tick % 2 == 0  # PC is set by an update of the slow group
    assert len(vel) >= 9  # at rest after 40 / 8 = 5 updates, the fifth 8 cycles on


def test_leaving_run_mode_runs_the_programmed_stop_and_stops_scanning() -> None:
    system = make_system(
        servo(1, ProgrammedStopMode.FAST_DISABLE), servo(2, ProgrammedStopMode.HARD_SHUTDOWN)
    )
    ctl = system.ctl
    enable(system, 1, 2)
    for n in (1, 2):
        trigger(system, system.add("MAJ", f"MAJ_{n}", {"Axis": n, "Speed": 50.0}))
    system.cycle(100)
    stops = ctl.set_mode(OperatingMode.PROGRAM)
    assert len(stops) == 1 and not ctl.run_mode
    # no instruction executes in program mode
    late = logix(system.add("MAJ", "MAJ_late", {"Axis": 1, "Speed": 10.0}))
    late.inputs["Execute"] = True
    system.cycle(200)
    assert not late.bit("EN") and not late.bit("ER")
    assert stops[0].complete
    assert ctl.axis(1).state == AxisState.AXIS_READY
    assert ctl.axis(2).state == AxisState.AXIS_SHUTDOWN
    # back in run mode the held rung is seen rising (prescan) and the MAJ executes
    assert ctl.set_mode(OperatingMode.RUN) == []
    system.cycle()
    assert late.bit("EN") and late.bit("ER")
    assert late.outputs["ERR"] == ErrorCode.SERVO_OFF_STATE
