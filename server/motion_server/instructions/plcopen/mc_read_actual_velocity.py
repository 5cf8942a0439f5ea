"""MC_ReadActualVelocity: the axis's actual velocity, every cycle while enabled.

PLCopen Part 1: "returns the actual velocity"; signed (negative moving down). The value
is the one the tag ``<Axis>.ActualVelocity`` shows after the same cycle. Enable-style
(:class:`~motion_server.instructions.base.EnableBlock`).
"""

from __future__ import annotations

from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Quantity, StatusField, TagType


@register
class MC_ReadActualVelocity(EnableBlock):
    TYPE = "MC_ReadActualVelocity"
    DESCRIPTION = "The axis's actual velocity (Enable-style)"
    OPERANDS = (AXIS,)
    OUTPUTS = (
        StatusField(
            "Velocity",
            TagType.LREAL,
            "actual velocity (signed)",
            quantity=Quantity.VELOCITY,
            default=0.0,
        ),
    )

    def read(self) -> None:
        self.outputs["Velocity"] = float(self.axis().actual_velocity)
