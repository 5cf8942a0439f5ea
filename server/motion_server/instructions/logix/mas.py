"""MAS, Motion Axis Stop: stop one kind of motion process, or all of them.

DN when the stop is initiated, IP until the axis has come to rest, then PC. StopType
Home stops an active homing sequence, and Home or All ends a passive homing waiting for
its event (on a feedback-only axis too). The deceleration is the axis maximum unless
ChangeDecel selects DecelRate; the ramp is trapezoidal unless ChangeDecelJerk selects
DecelJerk. DecelRate and DecelUnits are judged only when ChangeDecel is Yes, DecelJerk
and JerkUnits only when ChangeDecelJerk is Yes (the rule of every instruction: an
operand its mode does not use is not judged).
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any, ClassVar

from ...kernel import AbortReason, AxisType, ErrorCode, MotionError, ProcessKind
from ...kernel.processes import Process
from ..base import Gate, gate
from ..dynamics import AccelUnits, JerkUnits, rate
from ..dynamics import jerk as jerk_of
from ..logix_common import STARTED_ACTIVE, ProcessInstruction
from ..operands import AXIS
from ..registry import register
from ..scan_pass import Batch, BatchKind
from ..schema import Operand, Quantity, TagType


class StopType(IntEnum):
    ALL = 0
    JOG = 1
    MOVE = 2
    GEAR = 3
    HOME = 4
    TUNE = 5
    TEST = 6
    POSITION_CAM = 7
    TIME_CAM = 8
    MASTER_OFFSET_MOVE = 9
    DIRECT_CONTROL = 10


class YesNo(IntEnum):
    NO = 0
    YES = 1


STOP_KINDS: dict[StopType, tuple[ProcessKind, ...] | None] = {
    StopType.ALL: None,
    StopType.JOG: (ProcessKind.JOG,),
    StopType.MOVE: (ProcessKind.MOVE,),
    StopType.GEAR: (ProcessKind.GEAR,),
    StopType.HOME: (ProcessKind.HOME,),
    StopType.POSITION_CAM: (ProcessKind.POSITION_CAM,),
    StopType.TIME_CAM: (ProcessKind.TIME_CAM,),
}


@register
class MAS(ProcessInstruction):
    TYPE = "MAS"
    DESCRIPTION = "Motion Axis Stop"
    #: DecelRate counts only with ChangeDecel = Yes, DecelJerk with ChangeDecelJerk = Yes
    GATES: ClassVar[dict[str, tuple[Gate, ...]]] = {
        "DecelRate": (gate("ChangeDecel", YesNo.YES),),
        "DecelUnits": (gate("ChangeDecel", YesNo.YES),),
        "DecelJerk": (gate("ChangeDecelJerk", YesNo.YES),),
        "JerkUnits": (gate("ChangeDecelJerk", YesNo.YES),),
    }
    OPERANDS = (
        AXIS,
        Operand("StopType", TagType.DINT, 0, enum=StopType),
        Operand("ChangeDecel", TagType.DINT, 0, enum=YesNo),
        Operand(
            "DecelRate",
            TagType.REAL,
            100.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.ACCELERATION,
        ),
        Operand("DecelUnits", TagType.DINT, 0, enum=AccelUnits),
        Operand("ChangeDecelJerk", TagType.DINT, 0, enum=YesNo),
        Operand("DecelJerk", TagType.REAL, 100.0, minimum=0.0, quantity=Quantity.JERK),
        Operand("JerkUnits", TagType.DINT, 0, enum=JerkUnits),
    )

    BATCH = BatchKind.STOP

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the stop returned as (axis, deceleration)
        for ``Controller.stop_many``: a stop of all motion, without a jerk, on an axis
        with motion to stop and no homing to end. Any other executes alone (its own
        path: a homing ended, DN and PC at once, a stop of some kinds, a jerk)."""
        op = self.op
        if int(op["StopType"]) != StopType.ALL or int(op["ChangeDecelJerk"]) == YesNo.YES:
            return None
        ax = self.axis()
        number = ax.number
        batch.before_axis(number)
        if (
            ax.type == AxisType.FEEDBACK_ONLY
            or ax.index in self.ctl.homing.jobs
            or ax.homing_armed is not None
            or not ax.servo_on
            or not ax.active()
        ):
            return None
        cfg = ax.config
        decel = cfg.max_deceleration
        if int(op["ChangeDecel"]) == YesNo.YES:
            decel = rate(self, ax, "DecelRate", "DecelUnits", cfg.max_deceleration)
        return (ax, decel), (number,)

    def batch_started(self, process: Process) -> None:
        self.started_active(process, STARTED_ACTIVE)

    def batch_refused(self) -> None:
        """The kernel refused the stop (a ramp too long): nothing to undo."""

    def execute(self) -> None:
        ax = self.axis()
        stop_type = StopType(int(self.op["StopType"]))
        homing = stop_type in (StopType.ALL, StopType.HOME)
        if homing and self.ctl.cancel_homing(ax) and ax.type == AxisType.FEEDBACK_ONLY:
            # a passive homing waiting for its event ended (it commands no motion)
            self.set_bits(DN=True, PC=True)
            return
        if ax.type == AxisType.FEEDBACK_ONLY:
            raise MotionError(ErrorCode.WRONG_AXIS_TYPE, f"{ax.name} is feedback only")
        kinds = STOP_KINDS.get(stop_type, ())
        if kinds is None:
            moving = ax.active()
        else:
            moving = [p for k in kinds for p in ax.active(k)]
        if not ax.servo_on or not moving:
            if ax.preloaded_cams:
                # a Pending cam preloaded while no cam ran ends with the stop of its kind
                self.ctl.motion.retire(ax, kinds, AbortReason.STOPPED)
            # nothing of that kind is moving (or no process of that kind exists here):
            # the stop is complete at once
            self.set_bits(DN=True, PC=True)
            return
        cfg = ax.config
        decel = cfg.max_deceleration
        if int(self.op["ChangeDecel"]) == YesNo.YES:
            decel = rate(self, ax, "DecelRate", "DecelUnits", cfg.max_deceleration)
        j = 0.0
        if int(self.op["ChangeDecelJerk"]) == YesNo.YES:
            j = jerk_of(self, ax, "DecelJerk", abs(ax.command_velocity), decel)
        self.started(self.ctl.stop(ax, kinds, decel, j, owner=self))
