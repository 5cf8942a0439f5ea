"""The fault tags of an axis: what a drive reports, and the causes a bench injects.

In the axis's configuration block (after the configuration and the REAL mirrors) and
under its OPC UA object:

- ``<Axis>.ServoFault`` (read): the Logix ServoFaultBits word;
- ``<Axis>.AxisErrorID`` (read): the code PLCopen's MC_ReadAxisError reports;
- ``<Axis>.Inject...`` (read/write, operator): one command bit per fault cause the axis
  type has (a servo axis all seven, a virtual axis its soft overtravels, a feedback-only
  axis its feedback loss). 1 holds the cause, 0 removes it; an overtravel reads 0 again by
  itself once the axis is back inside its limit.

What each cause does and the numbering of both words: ``kernel/faults.py``.
"""

from __future__ import annotations

from collections.abc import Callable

from ..instructions.schema import TagType
from ..kernel import Axis, AxisType
from ..kernel.faults import APPLIES, FaultCause, axis_error_id, servo_fault
from .codec import Value
from .fields import FieldSpec

FAULT_STATUS: tuple[FieldSpec, ...] = (
    FieldSpec(
        "ServoFault",
        TagType.UDINT,
        description="Logix ServoFaultBits: 0 PosSoftOvertravel, 1 NegSoftOvertravel, "
        "2 PosHardOvertravel, 3 NegHardOvertravel, 4 Feedback, 8 PositionError, 9 DriveFault",
    ),
    FieldSpec(
        "AxisErrorID",
        TagType.UDINT,
        description="MC_ReadAxisError AxisErrorID: 1 + the ServoFault bit of the first fault "
        "(drive, feedback, position error, hard then soft overtravel); 1000 + the AxisFault "
        "bit of the others; 0 no fault",
    ),
)

#: the command bit of each cause
INJECT_FIELDS: dict[FaultCause, FieldSpec] = {
    FaultCause.DRIVE: FieldSpec(
        "InjectDriveFault",
        TagType.BOOL,
        writable=True,
        description="1: the drive reports a fault (Disable Drive) until set to 0",
    ),
    FaultCause.FEEDBACK_LOSS: FieldSpec(
        "InjectFeedbackLoss",
        TagType.BOOL,
        writable=True,
        description="1: the encoder is lost (Disable Drive) until set to 0",
    ),
    FaultCause.FOLLOWING_ERROR: FieldSpec(
        "InjectFollowingError",
        TagType.BOOL,
        writable=True,
        description="1: excessive position error, as a jammed load makes it (Disable Drive) "
        "until set to 0",
    ),
    FaultCause.POS_HARD_OVERTRAVEL: FieldSpec(
        "InjectPosHardOvertravel",
        TagType.BOOL,
        writable=True,
        description="1: the positive limit switch is made here (Stop Planner); 0 again once "
        "the axis is back below",
    ),
    FaultCause.NEG_HARD_OVERTRAVEL: FieldSpec(
        "InjectNegHardOvertravel",
        TagType.BOOL,
        writable=True,
        description="1: the negative limit switch is made here (Stop Planner); 0 again once "
        "the axis is back above",
    ),
    FaultCause.POS_SOFT_OVERTRAVEL: FieldSpec(
        "InjectPosSoftOvertravel",
        TagType.BOOL,
        writable=True,
        description="1: the axis is beyond its positive soft travel limit (Stop Planner); 0 "
        "again once it is back below",
    ),
    FaultCause.NEG_SOFT_OVERTRAVEL: FieldSpec(
        "InjectNegSoftOvertravel",
        TagType.BOOL,
        writable=True,
        description="1: the axis is beyond its negative soft travel limit (Stop Planner); 0 "
        "again once it is back above",
    ),
}

#: command bit field -> its cause
INJECT_CAUSES: dict[str, FaultCause] = {spec.name: c for c, spec in INJECT_FIELDS.items()}

#: status field -> its value on an axis
FAULT_GETTERS: dict[str, Callable[[Axis], Value]] = {
    "ServoFault": lambda ax: servo_fault(ax.fault),
    "AxisErrorID": lambda ax: axis_error_id(ax.fault),
}


def fault_fields(axis_type: AxisType) -> tuple[FieldSpec, ...]:
    """The fault tags of an axis of ``axis_type``: the status words, then its causes."""
    return FAULT_STATUS + tuple(INJECT_FIELDS[c] for c in APPLIES[axis_type])
