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

from ..operands import AXIS
from ..registry import register
from ..schema import Operand, TagType
from .axis_parameters import MCAxisParameter
from .mc_write_parameter import MC_WriteParameter


@register
class MC_WriteBoolParameter(MC_WriteParameter):
    """MC_WriteParameter's block (outputs, execution) on the BOOL parameters."""

    TYPE = "MC_WriteBoolParameter"
    DESCRIPTION = "Write a BOOL PLCopen axis parameter (6 EnablePosLagMonitoring)"
    BOOLEAN = True
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
