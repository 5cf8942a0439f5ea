"""MC_ReadParameter: a numeric PLCopen axis parameter, every cycle while enabled.

PLCopen Part 1: "returns the value of a vendor specific parameter"; ``ParameterNumber``
is one of the standard numbers our axes hold (:mod:`.axis_parameters`). Enable-style
(:class:`~motion_server.instructions.base.EnableBlock`): a number the axes do not hold,
or a BOOL one (MC_ReadBoolParameter reads those), is Error with ErrorID 13.
"""

from __future__ import annotations

from ...kernel import MotionError
from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType
from .axis_parameters import MCAxisParameter, lookup


@register
class MC_ReadParameter(EnableBlock):
    TYPE = "MC_ReadParameter"
    DESCRIPTION = "A numeric PLCopen axis parameter (Enable-style)"
    OPERANDS = (
        AXIS,
        Operand(
            "ParameterNumber",
            TagType.DINT,
            int(MCAxisParameter.COMMANDED_POSITION),
            enum=MCAxisParameter,
            description="PLCopen parameter number (1 commanded position ... 17 jerk)",
        ),
    )
    OUTPUTS = (StatusField("Value", TagType.LREAL, "the parameter's value", default=0.0),)

    def read(self) -> None:
        try:
            param = lookup(int(self.op["ParameterNumber"]), boolean=False)
        except MotionError as exc:
            raise self.out_of_range("ParameterNumber", str(exc)) from None
        self.outputs["Value"] = float(param.read(self.ctl, self.axis()))
