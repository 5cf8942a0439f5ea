"""MC_SetPosition: shift the axis's coordinate system, with no motion.

PLCopen: "shifts the coordinate system of an axis by manipulating both the set-point
position as well as the actual position of an axis with the same value without any
movement caused (re-calibration with same following error)". ``Relative`` FALSE: the
position becomes ``Position``; TRUE: it moves by ``Position`` ("relative mode can be
used for changing the position of an axis during motion", TwinCAT). ``ValueSource``
(MC_Source) says which position takes the value: the actual one (1, the default, as
TwinCAT's MC_SetPosition sets it) or the set value (0, the command); the other moves by
the same amount. Motion in progress is unaffected: "the target position of absolute
movements commanded after MC_SetPosition will be considered relative to the shifted
coordinate system" (CODESYS SM3_Basic); see :mod:`motion_server.kernel.redefine`.

Done in the cycle of the rising edge, in any state but ErrorStop (ErrorID 20) or a
shut-down axis (7); on a rotary axis an absolute Position lies in [0, rollover), and no
position may go beyond 2**53 encoder counts (ErrorID 13).
"""

from __future__ import annotations

from ..base import BlockEvent, PLCopenBlock
from ..operands import AXIS
from ..plcopen_common import MCSource
from ..registry import register
from ..schema import Operand, Quantity, StatusField, TagType


@register
class MC_SetPosition(PLCopenBlock):
    TYPE = "MC_SetPosition"
    DESCRIPTION = "Set the axis position (shift the coordinates, no motion)"
    OPERANDS = (
        AXIS,
        Operand(
            "Position",
            TagType.LREAL,
            0.0,
            quantity=Quantity.POSITION,
            description="new position, or distance when Relative",
        ),
        Operand("Relative", TagType.BOOL, False, description="FALSE absolute, TRUE relative"),
        Operand(
            "ValueSource",
            TagType.DINT,
            int(MCSource.ACTUAL_VALUE),
            enum=MCSource,
            description="the position that takes the value: 0 set value (command), 1 actual",
        ),
    )
    COMMON_STATUS = (
        StatusField("Done", TagType.BOOL, "the position has its new value"),
        StatusField("Busy", TagType.BOOL, "the block has not finished"),
        StatusField("Error", TagType.BOOL, "finished with an error, see ErrorID"),
        StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
    )

    def execute(self) -> None:
        ax = self.axis()
        actual = int(self.op["ValueSource"]) == MCSource.ACTUAL_VALUE
        self.ctl.redefine_position(
            ax, float(self.op["Position"]), bool(self.op["Relative"]), actual
        )
        self.fire(BlockEvent.START)
        self.fire(BlockEvent.COMPLETE)
