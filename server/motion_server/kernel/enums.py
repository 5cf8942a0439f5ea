"""States and enumerations of the kernel, with the numbers clients see in registers.

Code that runs every cycle binds the members it compares with to module constants
(``_ACTIVE = ProcessState.ACTIVE``): on Python 3.11 reading a member through its class
costs about 150 ns, ten times a plain attribute, because ``EnumType`` defines
``__getattr__`` and so loses the interpreter's fast attribute path (3.12 dropped it).
"""

from __future__ import annotations

from enum import IntEnum


class AxisType(IntEnum):
    SERVO = 0
    VIRTUAL = 1
    FEEDBACK_ONLY = 2


class AxisState(IntEnum):
    """Logix AxisState (the power state)."""

    AXIS_READY = 0
    SERVO_CONTROL = 2
    AXIS_FAULTED = 3
    AXIS_SHUTDOWN = 4


class PLCopenState(IntEnum):
    UNDEFINED = 0
    DISABLED = 1
    STANDSTILL = 2
    ERRORSTOP = 3
    STOPPING = 4
    HOMING = 5
    DISCRETE_MOTION = 6
    CONTINUOUS_MOTION = 7
    SYNCHRONIZED_MOTION = 8


class MotionStatusBit(IntEnum):
    """Bit numbers of the Logix MotionStatus word."""

    ACCEL = 0
    DECEL = 1
    MOVE = 2
    JOG = 3
    GEARING = 4
    HOMING = 5
    STOPPING = 6
    HOMED = 7
    POSITION_CAM = 8
    TIME_CAM = 9
    POSITION_CAM_PENDING = 10
    TIME_CAM_PENDING = 11
    GEARING_LOCK = 12
    POSITION_CAM_LOCK = 13
    TIME_CAM_LOCK = 14
    #: MDS direct control (not simulated: always clear); MGS clears them (the seed's table)
    DIRECT_VELOCITY_CONTROL = 19
    DIRECT_TORQUE_CONTROL = 20


class ProgrammedStopMode(IntEnum):
    """Per-axis programmed stop action (the order is ours, see DESIGN.md)."""

    FAST_STOP = 0
    FAST_DISABLE = 1
    HARD_DISABLE = 2
    FAST_SHUTDOWN = 3
    HARD_SHUTDOWN = 4


class ProcessKind(IntEnum):
    """Kinds of superimposed motion process; MAS stop types refer to these."""

    JOG = 1
    MOVE = 2
    GEAR = 3
    STOP = 4
    #: an active homing sequence (MAH, MC_Home): the PLCopen Homing state
    HOME = 5
    #: a cam on a master's position (MAPC, MC_CamIn) or on time (MATC)
    POSITION_CAM = 6
    TIME_CAM = 7


class ProcessState(IntEnum):
    ACTIVE = 0
    DONE = 1
    ABORTED = 2
    ERROR = 3


class AbortReason(IntEnum):
    NONE = 0
    SUPERSEDED = 1
    STOPPED = 2
    SHUTDOWN = 3
    FAULTED = 4
    DISABLED = 5
    MERGED = 6


class FeedbackSignal(IntEnum):
    """Source of a feedback-only axis's actual position."""

    INPUT = 0
    CONSTANT_VELOCITY = 1
    SINE = 2


class AxisFault(IntEnum):
    """Bits of the AxisFault word."""

    NONE = 0
    #: |command - actual| beyond the axis's following error limit
    POSITION_ERROR = 1 << 0
    PROFILE = 1 << 1
    #: a watchdog trip (communication loss), set by the safety layer
    WATCHDOG = 1 << 2
    #: a value of this axis became infinite or NaN, or overflowed, in its commanded
    #: motion, its drive model or its feedback sample: the axis is faulted instead
    NUMERIC = 1 << 3
    #: the drive reported a fault (injected: :mod:`.faults`)
    DRIVE = 1 << 4
    #: the feedback (encoder) was lost
    FEEDBACK = 1 << 5
    #: the positive / negative hardware limit switch was reached
    POS_HARD_OVERTRAVEL = 1 << 6
    NEG_HARD_OVERTRAVEL = 1 << 7
    #: the axis travelled beyond its positive / negative soft travel limit
    POS_SOFT_OVERTRAVEL = 1 << 8
    NEG_SOFT_OVERTRAVEL = 1 << 9


class MasterReference(IntEnum):
    """Which position of a master a follower reads (numbered as Logix MasterReference;
    PLCopen MC_Source numbers the two the other way round)."""

    ACTUAL = 0
    COMMAND = 1


class AfterStop(IntEnum):
    """What happens to the power state once a stop ramp has brought the axis to rest."""

    NOTHING = 0
    DISABLE = 1
    SHUTDOWN = 2


class HomeMode(IntEnum):
    """Logix Home Mode of an axis (MOTION-RM003: passive 0, active 1; absolute 2 as the
    MAH instruction reference names it for axes with absolute feedback)."""

    PASSIVE = 0
    ACTIVE = 1
    ABSOLUTE = 2


class HomeSequence(IntEnum):
    """Logix Home Sequence (MOTION-RM003; the torque sequences 4 and 5 need a torque
    model the simulated drive does not have)."""

    IMMEDIATE = 0
    SWITCH = 1
    MARKER = 2
    SWITCH_THEN_MARKER = 3


class HomeDirection(IntEnum):
    """Logix Home Direction (MOTION-RM003)."""

    UNIDIRECTIONAL_FORWARD = 0
    BIDIRECTIONAL_FORWARD = 1
    UNIDIRECTIONAL_REVERSE = 2
    BIDIRECTIONAL_REVERSE = 3

    @property
    def sign(self) -> int:
        """+1 forward, -1 reverse."""
        return (
            1
            if self in (HomeDirection.UNIDIRECTIONAL_FORWARD, HomeDirection.BIDIRECTIONAL_FORWARD)
            else -1
        )

    @property
    def bidirectional(self) -> bool:
        return self in (HomeDirection.BIDIRECTIONAL_FORWARD, HomeDirection.BIDIRECTIONAL_REVERSE)
