"""MC_WriteBoolParameter: write a BOOL PLCopen axis parameter (Execute-style).

PLCopen Part 1: "modifies the value of a vendor specific parameter of type BOOL". Of the
standard numbers our axes hold (:mod:`.axis_parameters`) one BOOL is writable: 6
EnablePosLagMonitoring. FALSE switches the following error monitoring off and keeps
the limit (7 MaxPositionLag still reads it); TRUE switches it on again, refused while
that limit is 0 (nothing to monitor). Effective from the next cycle and read back by
MC_ReadBoolParameter 6. Done in the cycle of the rising edge, in any axis state. Another
number (4/5 EnableLimitPos/Neg: the axes have no software limits) is Error with ErrorID
13.
"""

from __future__ import annotations

from ...kernel import MotionError
from ..base import BlockEvent, PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType
from .axis_parameters import MCAxisParameter, lookup


@register
class MC_WriteBoolParameter(PLCopenBlock):
    TYPE = "MC_WriteBoolParameter"
    DESCRIPTION = "Write a BOOL PLCopen axis parameter (6 EnablePosLagMonitoring)"
    OPERANDS = (
        AXIS,
        Operand(
            "ParameterNumber",
            TagType.DINT,
            int(MCAxisParameter.ENABLE_POS_LAG_MONITORING),
            enum=MCAxisParameter,
            description="PLCopen parameter number (writable: 6 EnablePosLagMonitoring)",
        ),
        Operand("Value", TagType.BOOL, True, description="the new value"),
    )
    COMMON_STATUS = (
        StatusField("Done", TagType.BOOL, "the parameter has its new value"),
        StatusField("Busy", TagType.BOOL, "the block has not finished"),
        StatusField("Error", TagType.BOOL, "finished with an error, see ErrorID"),
        StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
    )

    def execute(self) -> None:
        ax = self.axis()
        try:
            param = lookup(int(self.op["ParameterNumber"]), boolean=True, write=True)
        except MotionError as exc:
            raise self.out_of_range("ParameterNumber", str(exc)) from None
        assert param.write is not None
        try:
            param.write(self.ctl, ax, float(bool(self.op["Value"])))
        except MotionError as exc:
            raise self.out_of_range("Value", str(exc)) from None
        self.fire(BlockEvent.START)
        self.fire(BlockEvent.COMPLETE)
