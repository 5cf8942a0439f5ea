"""MC_WriteParameter: write a numeric PLCopen axis parameter (Execute-style).

PLCopen Part 1: "modifies the value of a vendor specific parameter". Of the standard
numeric numbers our axes hold (:mod:`.axis_parameters`) these are writable: 7
MaxPositionLag, the following error limit (>= 0; 0 turns the monitoring off), effective
from the next cycle and read back by MC_ReadParameter and MC_ReadBoolParameter 6 (the
BOOL 6 itself is written with MC_WriteBoolParameter); 9 MaxVelocityAppl, 13
MaxAccelerationAppl, 15 MaxDecelerationAppl and 17 MaxJerkAppl, the maxima commands are
judged against (above 0, at most the System value), for commands from then on. Done in
the cycle of the rising edge, in any axis state. A read-only or unknown number, or a
value out of range, is Error with ErrorID 13.
"""

from __future__ import annotations

from typing import ClassVar

from ...kernel import MotionError
from ..base import BlockEvent, PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType
from .axis_parameters import MCAxisParameter, lookup


@register
class MC_WriteParameter(PLCopenBlock):
    TYPE = "MC_WriteParameter"
    DESCRIPTION = "Write a numeric PLCopen axis parameter (7, 9, 13, 15, 17)"
    OPERANDS = (
        AXIS,
        Operand(
            "ParameterNumber",
            TagType.DINT,
            int(MCAxisParameter.MAX_POSITION_LAG),
            enum=MCAxisParameter,
            description="PLCopen parameter number (writable: 7 MaxPositionLag, 9 / 13 / 15 / 17 "
            "the Appl maxima)",
        ),
        Operand("Value", TagType.LREAL, 0.0, description="the new value"),
    )
    COMMON_STATUS = (
        StatusField("Done", TagType.BOOL, "the parameter has its new value"),
        StatusField("Busy", TagType.BOOL, "the block has not finished"),
        StatusField("Error", TagType.BOOL, "finished with an error, see ErrorID"),
        StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
    )
    #: the kind of parameter written (MC_WriteBoolParameter: True)
    BOOLEAN: ClassVar[bool] = False

    def execute(self) -> None:
        ax = self.axis()
        try:
            param = lookup(int(self.op["ParameterNumber"]), boolean=self.BOOLEAN, write=True)
        except MotionError as exc:
            raise self.out_of_range("ParameterNumber", str(exc)) from None
        assert param.write is not None
        value = self.op["Value"]
        try:
            param.write(self.ctl, ax, float(bool(value)) if self.BOOLEAN else float(value))
        except MotionError as exc:
            raise self.out_of_range("Value", str(exc)) from None
        self.fire(BlockEvent.START)
        self.fire(BlockEvent.COMPLETE)
