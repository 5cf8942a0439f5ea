"""Injected axis faults: a drive, an encoder or a limit switch failing on demand.

A test bench makes an axis fail the way hardware does, and the controller reacts as a
Logix servo axis does (the fault attributes of Rockwell publication MOTION-RM002, "Motion
Error Codes, faults, and attributes", and the CIP axis exception rules of MOTION-RM003).
Each cause (:class:`FaultCause`) is held by the bench until it removes it:

==================== ====================== ================== ==========================
cause                AxisFault bit (ours)   ServoFault bit     fault action
==================== ====================== ================== ==========================
DRIVE                4 DriveFault           9 DriveFault       Disable Drive
FEEDBACK_LOSS        5 FeedbackFault        4 FeedbackFault    Disable Drive
FOLLOWING_ERROR      0 PositionError        8 PositionError    Disable Drive
POS_HARD_OVERTRAVEL  6 PosHardOvertravel    2 PosHardOvertr.   Stop Planner
NEG_HARD_OVERTRAVEL  7 NegHardOvertravel    3 NegHardOvertr.   Stop Planner
POS_SOFT_OVERTRAVEL  8 PosSoftOvertravel    0 PosSoftOvertr.   Stop Planner
NEG_SOFT_OVERTRAVEL  9 NegSoftOvertravel    1 NegSoftOvertr.   Stop Planner
==================== ====================== ================== ==========================

Disable Drive: Axis Faulted at once, the drive off, the axis coasts at its coast
deceleration (what the kernel does when |error| exceeds the following error limit).
Stop Planner: every process is replaced by a ramp to rest at the axis's maximum
deceleration; the drive stays on (Servo Control, PLCopen ErrorStop). An axis that is not
in Servo Control is simply faulted.

Faults latch; MAFR / MC_Reset clear them. A Disable Drive cause that is still held faults
the axis again at once (MAFR "does not correct the condition that caused the error"). An
overtravel is the exception, as on a real axis: it may be reset while the axis is still
beyond its limit, so that it can be moved back. Until it is back inside, motion toward the
limit is refused: a process that moves the axis further ends with
:attr:`~.errors.ErrorCode.OVERTRAVEL` (the instruction's ER/Error), the axis ramps to
rest and the overtravel fault is set again; motion away from the limit is allowed, and
the cause ends by itself once the actual position is back inside. Injecting an
overtravel puts the limit at the axis's actual position at that moment.

What applies where: a servo axis has all seven; a virtual axis has no drive, encoder or
switches, only the soft travel limits of its planner; a feedback-only axis has only its
encoder.

For clients: ``ServoFault`` is the Logix ServoFaultBits attribute (its bit numbers), and
``AxisErrorID`` the code PLCopen's MC_ReadAxisError reports (vendor specific by the
standard): 1 + the ServoFault bit of the first fault in :data:`ERROR_PRIORITY`, or for
the faults ServoFault has no bit for, 1000 + their AxisFault bit; 0 without a fault.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from .enums import AxisFault, AxisType


class FaultCause(IntEnum):
    """What a bench can make fail on an axis (``<Axis>.Inject...``)."""

    DRIVE = 0
    FEEDBACK_LOSS = 1
    FOLLOWING_ERROR = 2
    POS_HARD_OVERTRAVEL = 3
    NEG_HARD_OVERTRAVEL = 4
    POS_SOFT_OVERTRAVEL = 5
    NEG_SOFT_OVERTRAVEL = 6


#: the AxisFault bit each cause sets
CAUSE_BIT: dict[FaultCause, AxisFault] = {
    FaultCause.DRIVE: AxisFault.DRIVE,
    FaultCause.FEEDBACK_LOSS: AxisFault.FEEDBACK,
    FaultCause.FOLLOWING_ERROR: AxisFault.POSITION_ERROR,
    FaultCause.POS_HARD_OVERTRAVEL: AxisFault.POS_HARD_OVERTRAVEL,
    FaultCause.NEG_HARD_OVERTRAVEL: AxisFault.NEG_HARD_OVERTRAVEL,
    FaultCause.POS_SOFT_OVERTRAVEL: AxisFault.POS_SOFT_OVERTRAVEL,
    FaultCause.NEG_SOFT_OVERTRAVEL: AxisFault.NEG_SOFT_OVERTRAVEL,
}

#: overtravel causes: the direction of travel beyond their limit
OVERTRAVEL: dict[FaultCause, int] = {
    FaultCause.POS_HARD_OVERTRAVEL: 1,
    FaultCause.NEG_HARD_OVERTRAVEL: -1,
    FaultCause.POS_SOFT_OVERTRAVEL: 1,
    FaultCause.NEG_SOFT_OVERTRAVEL: -1,
}

#: causes whose fault action is Disable Drive (the others: Stop Planner)
DISABLE_DRIVE = frozenset({FaultCause.DRIVE, FaultCause.FEEDBACK_LOSS, FaultCause.FOLLOWING_ERROR})

#: the causes each axis type has
APPLIES: dict[AxisType, tuple[FaultCause, ...]] = {
    AxisType.SERVO: tuple(FaultCause),
    AxisType.VIRTUAL: (FaultCause.POS_SOFT_OVERTRAVEL, FaultCause.NEG_SOFT_OVERTRAVEL),
    AxisType.FEEDBACK_ONLY: (FaultCause.FEEDBACK_LOSS,),
}

#: AxisFault bit -> Logix ServoFaultBits bit number (MOTION-RM002: 0 PosSoftOvertravel,
#: 1 NegSoftOvertravel, 2 PosHardOvertravel, 3 NegHardOvertravel, 4 Feedback,
#: 8 PositionError, 9 DriveFault)
SERVO_FAULT_BIT: dict[AxisFault, int] = {
    AxisFault.POS_SOFT_OVERTRAVEL: 0,
    AxisFault.NEG_SOFT_OVERTRAVEL: 1,
    AxisFault.POS_HARD_OVERTRAVEL: 2,
    AxisFault.NEG_HARD_OVERTRAVEL: 3,
    AxisFault.FEEDBACK: 4,
    AxisFault.POSITION_ERROR: 8,
    AxisFault.DRIVE: 9,
}

#: which fault AxisErrorID reports when several are set: the drive and its feedback
#: first, then hard before soft limits (a hard overtravel outranks a soft one)
ERROR_PRIORITY: tuple[AxisFault, ...] = (
    AxisFault.DRIVE,
    AxisFault.FEEDBACK,
    AxisFault.POSITION_ERROR,
    AxisFault.POS_HARD_OVERTRAVEL,
    AxisFault.NEG_HARD_OVERTRAVEL,
    AxisFault.POS_SOFT_OVERTRAVEL,
    AxisFault.NEG_SOFT_OVERTRAVEL,
    AxisFault.NUMERIC,
    AxisFault.WATCHDOG,
    AxisFault.PROFILE,
)


def _error_id(bit: AxisFault) -> int:
    if bit in SERVO_FAULT_BIT:
        return 1 + SERVO_FAULT_BIT[bit]
    return 1000 + int(bit).bit_length() - 1


def servo_fault(fault: int) -> int:
    """The Logix ServoFaultBits word of AxisFault bits ``fault``."""
    out = 0
    for bit, number in SERVO_FAULT_BIT.items():
        if fault & bit:
            out |= 1 << number
    return out


def axis_error_id(fault: int) -> int:
    """MC_ReadAxisError's AxisErrorID of AxisFault bits ``fault`` (0: no fault)."""
    for bit in ERROR_PRIORITY:
        if fault & bit:
            return _error_id(bit)
    return 0


def servo_fault_array(fault: np.ndarray) -> np.ndarray:
    """:func:`servo_fault` of every element."""
    out = np.zeros(fault.shape, dtype=np.int64)
    for bit, number in SERVO_FAULT_BIT.items():
        out |= ((fault & int(bit)) != 0).astype(np.int64) << number
    return out


def axis_error_id_array(fault: np.ndarray) -> np.ndarray:
    """:func:`axis_error_id` of every element."""
    out = np.zeros(fault.shape, dtype=np.int64)
    for bit in reversed(ERROR_PRIORITY):  # the first in priority written last
        out = np.where(fault & int(bit), _error_id(bit), out)
    return out


class FaultInjection:
    """The causes held on a controller's axes (by axis index) and the limits of the
    overtravels among them. The controller acts on them (``Controller.inject``)."""

    def __init__(self) -> None:
        #: axis index -> held causes (a bit per :class:`FaultCause`)
        self.held: dict[int, int] = {}
        #: (axis index, overtravel cause) -> the position the axis is beyond
        self.limits: dict[tuple[int, FaultCause], float] = {}
        #: axis indices whose held causes changed since the host last looked
        self.changed: set[int] = set()

    def holds(self, index: int, cause: FaultCause) -> bool:
        return bool(self.held.get(index, 0) >> cause & 1)

    def hold(self, index: int, cause: FaultCause, limit: float | None = None) -> None:
        self.held[index] = self.held.get(index, 0) | 1 << cause
        if limit is not None:
            self.limits[(index, cause)] = limit
        self.changed.add(index)

    def release(self, index: int, cause: FaultCause) -> None:
        bits = self.held.get(index, 0) & ~(1 << cause)
        if bits:
            self.held[index] = bits
        else:
            self.held.pop(index, None)
        self.limits.pop((index, cause), None)
        self.changed.add(index)

    def disable_drive_bits(self, index: int) -> int:
        """The AxisFault bits of the Disable Drive causes held on axis ``index``."""
        held = self.held.get(index, 0)
        bits = 0
        for cause in DISABLE_DRIVE:
            if held >> cause & 1:
                bits |= CAUSE_BIT[cause]
        return bits
