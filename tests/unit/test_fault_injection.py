"""Injected faults in the kernel and the instructions: what each cause sets, how the axis
stops, and when MAFR / MC_Reset clear it (``kernel/faults.py``).

The numbers: the Logix ServoFaultBits of Rockwell MOTION-RM002 (0 PosSoftOvertravel,
1 NegSoftOvertravel, 2 PosHardOvertravel, 3 NegHardOvertravel, 4 Feedback, 8 PositionError,
9 DriveFault); AxisErrorID = 1 + that bit. Stops from first principles: a coasting axis
loses coast_deceleration x dt of speed per cycle; a planner stop ramps the command at the
maximum deceleration, so a jog at v reaches rest in v / (decel x dt) cycles.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    ErrorCode,
    MotionError,
    PLCopenState,
)
from motion_server.kernel.faults import (
    ERROR_PRIORITY,
    FaultCause,
    axis_error_id,
    axis_error_id_array,
    servo_fault,
    servo_fault_array,
)

from ..support import make_system, trigger

DT = 0.002
SPEED = 100.0  # mm/s
DECEL = 1000.0  # mm/s²: a planner stop from SPEED takes 100 / (1000 x 0.002) = 50 cycles
COAST = 500.0  # mm/s²: a coasting axis loses 1 mm/s per cycle


def system() -> MotionSystem:
    """Axis1 servo (linear), Axis2 virtual, Axis3 feedback only; MSO, MAJ, MAFR, MC_Reset."""
    sys_ = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.SERVO,
            max_velocity=1000.0,
            max_acceleration=DECEL,
            max_deceleration=DECEL,
            coast_deceleration=COAST,
            drive_bandwidth=40.0,
        ),
        AxisConfig(2, "Axis2", AxisType.VIRTUAL, max_deceleration=DECEL, max_acceleration=DECEL),
        AxisConfig(3, "Axis3", AxisType.FEEDBACK_ONLY),
    )
    for t in ("MSO", "MAJ", "MAFR", "MC_Reset"):
        sys_.add(t, f"{t}_1")
    return sys_


def enable(sys_: MotionSystem, axis: int) -> None:
    mso = sys_["MSO_1"]
    trigger(sys_, mso, Axis=axis)
    mso.inputs["Execute"] = False
    sys_.cycle()


def jog(sys_: MotionSystem, axis: int, speed: float = SPEED, direction: int = 0) -> None:
    maj = sys_["MAJ_1"]
    maj.inputs["Execute"] = False
    sys_.cycle()
    trigger(sys_, maj, Axis=axis, Speed=speed, Direction=direction, AccelRate=DECEL,
            DecelRate=DECEL)  # fmt: skip


def mafr(sys_: MotionSystem, axis: int) -> None:
    inst = sys_["MAFR_1"]
    inst.inputs["Execute"] = False
    sys_.cycle()
    trigger(sys_, inst, Axis=axis)


def at_speed(sys_: MotionSystem, axis: int, speed: float = SPEED) -> None:
    jog(sys_, axis, abs(speed), 0 if speed > 0 else 1)
    sys_.cycle(int(abs(speed) / (DECEL * DT)) + 5)
    assert sys_.ctl.axis(axis).command_velocity == speed


# -- the numbering -------------------------------------------------------------------------
def test_servo_fault_bits_are_the_logix_ones() -> None:
    expected = {
        AxisFault.POS_SOFT_OVERTRAVEL: 1 << 0,
        AxisFault.NEG_SOFT_OVERTRAVEL: 1 << 1,
        AxisFault.POS_HARD_OVERTRAVEL: 1 << 2,
        AxisFault.NEG_HARD_OVERTRAVEL: 1 << 3,
        AxisFault.FEEDBACK: 1 << 4,
        AxisFault.POSITION_ERROR: 1 << 8,
        AxisFault.DRIVE: 1 << 9,
        AxisFault.WATCHDOG: 0,
        AxisFault.NUMERIC: 0,
        AxisFault.PROFILE: 0,
    }
    for bit, word in expected.items():
        assert servo_fault(bit) == word, bit.name
    assert axis_error_id(AxisFault.DRIVE) == 10
    assert axis_error_id(AxisFault.POSITION_ERROR) == 9
    assert axis_error_id(AxisFault.WATCHDOG) == 1002
    assert axis_error_id(0) == 0
    # a drive fault outranks everything; a hard overtravel outranks a soft one
    assert axis_error_id(AxisFault.DRIVE | AxisFault.POS_SOFT_OVERTRAVEL) == 10
    assert axis_error_id(AxisFault.POS_SOFT_OVERTRAVEL | AxisFault.NEG_HARD_OVERTRAVEL) == 4


def test_the_array_forms_equal_the_scalar_ones() -> None:
    bits = [int(b) for b in ERROR_PRIORITY]
    words = [sum(c) for r in range(3) for c in itertools.combinations(bits, r)]
    fault = np.array(words, dtype=np.int64)
    assert servo_fault_array(fault).tolist() == [servo_fault(w) for w in words]
    assert axis_error_id_array(fault).tolist() == [axis_error_id(w) for w in words]


# -- Disable Drive: drive fault, feedback loss, excessive following error ---------------------
@pytest.mark.parametrize(
    ("cause", "bit", "servo_bit"),
    [
        (FaultCause.DRIVE, AxisFault.DRIVE, 9),
        (FaultCause.FEEDBACK_LOSS, AxisFault.FEEDBACK, 4),
        (FaultCause.FOLLOWING_ERROR, AxisFault.POSITION_ERROR, 8),
    ],
)
def test_a_disable_drive_fault_drops_the_drive_and_holds_until_removed(
    cause: FaultCause, bit: AxisFault, servo_bit: int
) -> None:
    sys_ = system()
    ctl = sys_.ctl
    ax = ctl.axis(1)
    enable(sys_, 1)
    at_speed(sys_, 1)
    v0 = ax.actual_velocity
    ctl.inject(ax, cause, True)
    assert ax.state == AxisState.AXIS_FAULTED
    assert ax.plcopen_state == PLCopenState.ERRORSTOP
    assert ax.fault == bit
    assert servo_fault(ax.fault) == 1 << servo_bit
    assert axis_error_id(ax.fault) == 1 + servo_bit
    assert sys_["MAJ_1"].outputs["IP"] is True  # until the scan sees the jog ended
    sys_.cycle()
    assert sys_["MAJ_1"].outputs["IP"] is False
    assert not ax.processes
    # the drive is off: the axis coasts, 1 mm/s less per cycle
    for k in range(1, 6):
        assert ax.actual_velocity == pytest.approx(v0 - COAST * DT * k, abs=1e-9)
        sys_.cycle()
    # MAFR while the cause is held: done, and faulted again at once
    mafr(sys_, 1)
    assert sys_["MAFR_1"].outputs["DN"] is True
    assert ax.state == AxisState.AXIS_FAULTED and ax.fault == bit
    # MC_Reset while it is held: Error 20
    reset = sys_["MC_Reset_1"]
    trigger(sys_, reset, Axis=1)
    assert reset.outputs["Error"] is True
    assert reset.outputs["ErrorID"] == ErrorCode.AXIS_FAULTED
    reset.inputs["Execute"] = False
    sys_.cycle()
    # removed: the fault stays latched until a reset clears it
    ctl.inject(ax, cause, False)
    sys_.cycle()
    assert ax.state == AxisState.AXIS_FAULTED and ax.fault == bit
    trigger(sys_, reset, Axis=1)
    assert reset.outputs["Done"] is True
    assert ax.state == AxisState.AXIS_READY and ax.fault == 0
    assert axis_error_id(ax.fault) == 0
    enable(sys_, 1)
    assert ax.state == AxisState.SERVO_CONTROL


def test_feedback_loss_on_a_feedback_only_axis() -> None:
    sys_ = system()
    ctl = sys_.ctl
    ax = ctl.axis(3)
    ctl.inject(ax, FaultCause.FEEDBACK_LOSS, True)
    assert ax.state == AxisState.AXIS_FAULTED
    assert servo_fault(ax.fault) == 1 << 4
    ctl.inject(ax, FaultCause.FEEDBACK_LOSS, False)
    mafr(sys_, 3)
    assert ax.state == AxisState.AXIS_READY and ax.fault == 0


def test_causes_an_axis_type_does_not_have_are_refused() -> None:
    sys_ = system()
    ctl = sys_.ctl
    for axis, cause in (
        (2, FaultCause.DRIVE),
        (2, FaultCause.POS_HARD_OVERTRAVEL),
        (3, FaultCause.NEG_SOFT_OVERTRAVEL),
        (3, FaultCause.FOLLOWING_ERROR),
    ):
        with pytest.raises(MotionError) as err:
            ctl.inject(ctl.axis(axis), cause, True)
        assert err.value.code == ErrorCode.WRONG_AXIS_TYPE
        assert ctl.axis(axis).fault == 0


# -- Stop Planner: overtravels ---------------------------------------------------------------
@pytest.mark.parametrize(
    ("axis", "cause", "speed", "bit", "servo_bit"),
    [
        (1, FaultCause.POS_SOFT_OVERTRAVEL, SPEED, AxisFault.POS_SOFT_OVERTRAVEL, 0),
        (1, FaultCause.NEG_SOFT_OVERTRAVEL, -SPEED, AxisFault.NEG_SOFT_OVERTRAVEL, 1),
        (1, FaultCause.POS_HARD_OVERTRAVEL, SPEED, AxisFault.POS_HARD_OVERTRAVEL, 2),
        (1, FaultCause.NEG_HARD_OVERTRAVEL, -SPEED, AxisFault.NEG_HARD_OVERTRAVEL, 3),
        (2, FaultCause.POS_SOFT_OVERTRAVEL, SPEED, AxisFault.POS_SOFT_OVERTRAVEL, 0),
    ],
)
def test_an_overtravel_stops_the_planner_and_allows_only_the_way_back(
    axis: int, cause: FaultCause, speed: float, bit: AxisFault, servo_bit: int
) -> None:
    sys_ = system()
    ctl = sys_.ctl
    ax = ctl.axis(axis)
    enable(sys_, axis)
    at_speed(sys_, axis, speed)
    limit = ax.actual_position_unwound
    ctl.inject(ax, cause, True)
    # Stop Planner: still in Servo Control, PLCopen ErrorStop, the command ramps to rest
    assert ax.state == AxisState.SERVO_CONTROL
    assert ax.plcopen_state == PLCopenState.ERRORSTOP
    assert ax.fault == bit and servo_fault(ax.fault) == 1 << servo_bit
    ramp = int(SPEED / (DECEL * DT))
    for k in range(1, ramp + 1):
        sys_.cycle()
        assert ax.command_velocity == pytest.approx(speed * (1 - k / ramp), abs=1e-9)
    assert ax.command_velocity == 0.0
    assert sys_["MAJ_1"].outputs["IP"] is False
    assert ctl.faults.holds(ax.index, cause)  # beyond the limit, at rest
    # faulted: motion is refused (ERR 20) until a reset
    jog(sys_, axis, SPEED, 1 if speed > 0 else 0)
    assert sys_["MAJ_1"].outputs["ER"] is True
    assert sys_["MAJ_1"].outputs["ERR"] == ErrorCode.AXIS_FAULTED
    # reset while still beyond: allowed (so that the axis can be moved back)
    mafr(sys_, axis)
    assert ax.fault == 0 and ax.plcopen_state == PLCopenState.STANDSTILL
    # further beyond: the jog ends with ERR OVERTRAVEL, the fault is set again
    jog(sys_, axis, SPEED, 0 if speed > 0 else 1)
    sys_.cycle(2)
    assert sys_["MAJ_1"].outputs["ER"] is True
    assert sys_["MAJ_1"].outputs["ERR"] == ErrorCode.OVERTRAVEL
    assert ax.fault == bit and ax.state == AxisState.SERVO_CONTROL
    sys_.cycle(10)
    assert ax.command_velocity == 0.0
    # back: reset, jog the other way; the cause ends once the axis is back inside
    mafr(sys_, axis)
    jog(sys_, axis, SPEED, 1 if speed > 0 else 0)
    for _ in range(500):
        sys_.cycle()
        if not ctl.faults.holds(ax.index, cause):
            break
    assert not ctl.faults.holds(ax.index, cause)
    assert (ax.actual_position_unwound - limit) * speed < 0.0
    assert sys_["MAJ_1"].outputs["IP"] is True and ax.fault == 0


def test_an_overtravel_of_an_axis_at_rest_only_faults_it() -> None:
    sys_ = system()
    ctl = sys_.ctl
    ax = ctl.axis(1)
    enable(sys_, 1)
    ctl.inject(ax, FaultCause.POS_HARD_OVERTRAVEL, True)
    assert ax.state == AxisState.SERVO_CONTROL and not ax.processes
    assert ax.fault == AxisFault.POS_HARD_OVERTRAVEL
    # removing the cause and resetting: the axis may move both ways again
    ctl.inject(ax, FaultCause.POS_HARD_OVERTRAVEL, False)
    mafr(sys_, 1)
    jog(sys_, 1, SPEED, 0)
    sys_.cycle(20)
    assert sys_["MAJ_1"].outputs["IP"] is True and ax.fault == 0


def test_an_overtravel_of_a_disabled_axis_faults_it() -> None:
    sys_ = system()
    ctl = sys_.ctl
    ax = ctl.axis(1)
    ctl.inject(ax, FaultCause.NEG_SOFT_OVERTRAVEL, True)
    assert ax.state == AxisState.AXIS_FAULTED
    mafr(sys_, 1)
    assert ax.state == AxisState.AXIS_READY and ax.fault == 0
