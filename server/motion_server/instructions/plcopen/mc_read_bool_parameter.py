"""MC_ReadBoolParameter: a BOOL PLCopen axis parameter, every cycle while enabled.

PLCopen Part 1: "returns the value of a vendor specific parameter of type BOOL": here 4
EnableLimitPos, 5 EnableLimitNeg (FALSE: no software limits) and 6
EnablePosLagMonitoring (:mod:`.axis_parameters`). Enable-style
(:class:`~motion_server.instructions.base.EnableBlock`): another number is Error with
ErrorID 13.
"""

from __future__ import annotations

from ...kernel import MotionError
from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType
from .axis_parameters import MCAxisParameter, lookup


@register
class MC_ReadBoolParameter(EnableBlock):
    TYPE = "MC_ReadBoolParameter"
    DESCRIPTION = "A BOOL PLCopen axis parameter (Enable-style)"
    OPERANDS = (
        AXIS,
        Operand(
            "ParameterNumber",
            TagType.DINT,
            int(MCAxisParameter.ENABLE_POS_LAG_MONITORING),
            enum=MCAxisParameter,
            description="PLCopen parameter number (4, 5 software limits, 6 lag monitoring)",
        ),
    )
    OUTPUTS = (StatusField("Value", TagType.BOOL, "the parameter's value", default=False),)

    def read(self) -> None:
        try:
            param = lookup(int(self.op["ParameterNumber"]), boolean=True)
        except MotionError as exc:
            raise self.out_of_range("ParameterNumber", str(exc)) from None
        self.outputs["Value"] = bool(param.read(self.ctl, self.axis()))
