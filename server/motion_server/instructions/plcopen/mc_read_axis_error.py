"""MC_ReadAxisError: the axis's fault word, as the kernel holds it.

PLCopen Part 1: "describes general axis errors not relating to the function blocks";
AxisErrorID is vendor specific. Here it is the axis's AxisFault word (the tag
``<Axis>.AxisFault``: bit 0 position error, 1 profile, 2 watchdog, 3 numeric, and any
bit added later), read generically: 0 when the axis has no fault. Enable-style
(:class:`~motion_server.instructions.base.EnableBlock`); an axis that does not exist is
Error with ErrorID 11, not an axis error.
"""

from __future__ import annotations

from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import StatusField, TagType


@register
class MC_ReadAxisError(EnableBlock):
    TYPE = "MC_ReadAxisError"
    DESCRIPTION = "The axis's fault word (Enable-style)"
    OPERANDS = (AXIS,)
    OUTPUTS = (
        StatusField("AxisErrorID", TagType.UDINT, "the axis's AxisFault bits (0: no fault)"),
    )

    def read(self) -> None:
        self.outputs["AxisErrorID"] = int(self.axis().fault)
