"""MC_ReadActualPosition: the axis's actual position, every cycle while enabled.

PLCopen Part 1: "returns the actual position". The value is the one the tag
``<Axis>.ActualPosition`` shows after the same cycle (in [0, rollover) on a rotary axis;
redefinitions included). Enable-style
(:class:`~motion_server.instructions.base.EnableBlock`).
"""

from __future__ import annotations

from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Quantity, StatusField, TagType


@register
class MC_ReadActualPosition(EnableBlock):
    TYPE = "MC_ReadActualPosition"
    DESCRIPTION = "The axis's actual position (Enable-style)"
    OPERANDS = (AXIS,)
    OUTPUTS = (
        StatusField(
            "Position",
            TagType.LREAL,
            "actual position",
            quantity=Quantity.POSITION,
            default=0.0,
        ),
    )

    def read(self) -> None:
        self.outputs["Position"] = float(self.axis().actual_position)
