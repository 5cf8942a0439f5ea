"""The error table shared by both instruction dialects (the Logix ``.ERR`` numbering), and
the error every state table raises for an event it has no transition for.

PLCopen blocks report the same numbers in ``ErrorID``. Codes from 1000 up are ours and are
documented here, in one table.
"""

from __future__ import annotations

from enum import Enum, IntEnum


class ErrorCode(IntEnum):
    NONE = 0
    SERVO_ON_STATE = 4
    SERVO_OFF_STATE = 5
    SHUTDOWN_STATE = 7
    WRONG_AXIS_TYPE = 8
    MASTER_AXIS_CONFLICT = 10
    AXIS_NOT_CONFIGURED = 11
    PARAMETER_OUT_OF_RANGE = 13
    AXIS_FAULTED = 20
    GROUP_FAULTED = 21
    AXIS_IN_MOTION = 22
    ILLEGAL_DYNAMIC_CHANGE = 23
    ILLEGAL_CAM_LENGTH = 26
    ILLEGAL_CAM_PROFILE_LENGTH = 27
    ILLEGAL_CAM_TYPE = 28
    ILLEGAL_CAM_ORDER = 29
    CAM_PROFILE_BEING_CALCULATED = 30
    CAM_PROFILE_BEING_USED = 31
    CAM_PROFILE_NOT_CALCULATED = 32
    POSITION_CAM_NOT_ENABLED = 33
    NOT_ALLOWED_WHILE_STOPPING = 78
    MDSC_IDLE_MASTER_AND_SLAVE_MOVING = 97
    MDSC_INVALID_SLAVE_SPEED_REDUCTION = 103
    MDSC_INVALID_MODE_OR_MASTER_CHANGE = 105
    # ours (1000+)
    GROUP_NOT_CONFIGURED = 1000
    PROFILE_FAILED = 1001
    COMBINED_SLAVE_GEAR_OUT = 1002
    NOT_GEARED = 1003
    BUFFER_FULL = 1004
    INTERNAL_ERROR = 1005
    NOT_CAMMING = 1006
    OVERTRAVEL = 1010


ERROR_TEXT: dict[ErrorCode, str] = {
    ErrorCode.NONE: "no error",
    ErrorCode.SERVO_ON_STATE: "servo on state: the axis must be disabled for this instruction",
    ErrorCode.SERVO_OFF_STATE: "servo off state: the axis is not in Servo Control",
    ErrorCode.SHUTDOWN_STATE: "shutdown state: the axis is shut down (reset it with MASR/MGSR)",
    ErrorCode.WRONG_AXIS_TYPE: "illegal axis type for this instruction",
    ErrorCode.MASTER_AXIS_CONFLICT: "master axis conflict (the axes would be cross-coupled)",
    ErrorCode.AXIS_NOT_CONFIGURED: "axis not configured",
    ErrorCode.PARAMETER_OUT_OF_RANGE: "parameter out of range (EXERR names the operand)",
    ErrorCode.AXIS_FAULTED: "axis faulted (reset with MAFR/MC_Reset)",
    ErrorCode.GROUP_FAULTED: "group faulted",
    ErrorCode.AXIS_IN_MOTION: "axis in motion",
    ErrorCode.ILLEGAL_DYNAMIC_CHANGE: "illegal dynamic change: the axis is already camming "
    "(use the Pending schedule, or stop the cam first)",
    ErrorCode.ILLEGAL_CAM_LENGTH: "illegal cam length: fewer than 2 points, or beyond the "
    "cam table",
    ErrorCode.ILLEGAL_CAM_PROFILE_LENGTH: "illegal cam profile length: the profile holds fewer "
    "points than the cam",
    ErrorCode.ILLEGAL_CAM_TYPE: "illegal cam type: a SegmentType other than 0 (linear) or "
    "1 (cubic)",
    ErrorCode.ILLEGAL_CAM_ORDER: "illegal cam order: master values must strictly increase",
    ErrorCode.CAM_PROFILE_BEING_CALCULATED: "cam profile being calculated",
    ErrorCode.CAM_PROFILE_BEING_USED: "cam profile being used by a running cam: it cannot be "
    "recalculated",
    ErrorCode.CAM_PROFILE_NOT_CALCULATED: "cam profile not calculated (run MCCP or "
    "MC_CamTableSelect first)",
    ErrorCode.POSITION_CAM_NOT_ENABLED: "position cam not enabled",
    ErrorCode.NOT_ALLOWED_WHILE_STOPPING: "not allowed while the axis or group is stopping",
    ErrorCode.MDSC_IDLE_MASTER_AND_SLAVE_MOVING: "MDSC: new master idle while the slave moves",
    ErrorCode.MDSC_INVALID_SLAVE_SPEED_REDUCTION: "MDSC: slave speed would drop below 5 %",
    ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE: "MDSC: invalid mode or master change",
    ErrorCode.GROUP_NOT_CONFIGURED: "group not configured",
    ErrorCode.PROFILE_FAILED: "the motion profile could not be computed for these limits",
    ErrorCode.COMBINED_SLAVE_GEAR_OUT: "MC_GearOut is not allowed on a combined (two-master) slave",
    ErrorCode.NOT_GEARED: "the slave axis is not geared",
    ErrorCode.BUFFER_FULL: "a buffered command is already waiting on this axis",
    ErrorCode.NOT_CAMMING: "the slave axis is not camming",
    ErrorCode.INTERNAL_ERROR: "internal error in the server (logged with its traceback); "
    "its axes ramp to rest",
    ErrorCode.OVERTRAVEL: "overtravel: the axis is beyond its travel limit in this direction "
    "(move it back, or reset and move it back)",
}


def error_text(code: int) -> str:
    """Human-readable meaning of an error code (unknown codes are named as such)."""
    try:
        return ERROR_TEXT[ErrorCode(code)]
    except ValueError:
        return f"unknown error {code}"


class MotionError(Exception):
    """A command the kernel refuses. ``code`` is the shared error number."""

    def __init__(self, code: ErrorCode, message: str = "") -> None:
        self.code = code
        super().__init__(message or ERROR_TEXT.get(code, str(code)))


class TransitionError(RuntimeError):
    """An event that a state table has no transition for, in the current state.

    Every state table of the server (the power states in :mod:`.power`, the PLCopen block
    states, the watchdog) raises this one error; a missing pair is a bug, never bad input.
    The message names the machine, the state and the event.
    """

    def __init__(self, machine: str, state: Enum, event: Enum) -> None:
        self.machine = machine
        self.state = state
        self.event = event
        super().__init__(f"{machine}: no transition for {event.name} in state {state.name}")
