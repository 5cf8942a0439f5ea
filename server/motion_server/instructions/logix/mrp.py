"""MRP, Motion Redefine Position: the axis's actual or command position takes a new value.

"The value specified by Position is used to update the Actual or Command position of
Axis ... If Absolute is selected the Position value is assigned to the current Actual or
Command position. If Relative is selected the Position value is added as a displacement
... The process of redefining the current axis position has no affect on motion in
progress as the instruction preserves the current servo following error" (MOTION-RM002).
The other position moves by the same amount; motion in progress, gearing to or from the
axis and the homing sensors are unaffected (:mod:`motion_server.kernel.redefine`).

DN in the scan of the rising edge (the simulated axis needs no coarse updates to apply
it). Any axis type; a faulted (ERR 20) or shut down (ERR 7) axis refuses. On a rotary
axis an absolute Position lies in [0, rollover) (ERR 13 otherwise); a position beyond
2**53 encoder counts is refused (ERR 13). MRP does not set Homed.
"""

from __future__ import annotations

from enum import IntEnum

from ...kernel import ErrorCode, MotionError
from ..base import LogixInstruction
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, Quantity, TagType


class RedefineType(IntEnum):
    ABSOLUTE = 0
    RELATIVE = 1


class PositionSelect(IntEnum):
    ACTUAL = 0
    COMMAND = 1


@register
class MRP(LogixInstruction):
    TYPE = "MRP"
    DESCRIPTION = "Motion Redefine Position (actual or command, absolute or relative)"
    OPERANDS = (
        AXIS,
        Operand("Type", TagType.DINT, 0, enum=RedefineType, description="0 absolute, 1 relative"),
        Operand(
            "PositionSelect",
            TagType.DINT,
            0,
            enum=PositionSelect,
            description="0 actual, 1 command",
        ),
        Operand(
            "Position",
            TagType.REAL,
            0.0,
            quantity=Quantity.POSITION,
            description="new position (absolute) or displacement (relative)",
        ),
    )

    def execute(self) -> None:
        ax = self.axis()
        relative = int(self.op["Type"]) == RedefineType.RELATIVE
        actual = int(self.op["PositionSelect"]) == PositionSelect.ACTUAL
        position = float(self.op["Position"])
        rollover = ax.config.rollover
        if not relative and rollover > 0.0 and not 0.0 <= position < rollover:
            raise self.out_of_range(
                "Position", f"rotary axis: position must be in [0, {rollover:g})"
            )
        try:
            self.ctl.redefine_position(ax, position, relative, actual)
        except MotionError as exc:
            if exc.code == ErrorCode.PARAMETER_OUT_OF_RANGE:
                raise self.out_of_range("Position", str(exc)) from None
            raise
        self.set_bits(DN=True)
