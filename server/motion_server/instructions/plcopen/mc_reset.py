"""MC_Reset: clear the axis faults, ErrorStop -> StandStill (power on) or Disabled.

The kernel clears the faults at once; Done follows in the same cycle, once the axis is no
longer faulted. The drive stays off after a fault: MC_Power with Enable high switches it
on again. On an axis without faults MC_Reset is done with no effect. A fault whose cause
is still present (an injected drive fault held: ``kernel/faults.py``) comes back at once:
Error, ErrorID 20 (axis faulted).
"""

from __future__ import annotations

from ...kernel import AxisState, ErrorCode, MotionError
from ..base import BlockEvent, PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import StatusField, TagType


@register
class MC_Reset(PLCopenBlock):
    TYPE = "MC_Reset"
    DESCRIPTION = "Reset axis faults (ErrorStop -> StandStill/Disabled)"
    OPERANDS = (AXIS,)
    COMMON_STATUS = (
        StatusField("Done", TagType.BOOL, "the faults are cleared"),
        StatusField("Busy", TagType.BOOL, "the block has not finished"),
        StatusField("Error", TagType.BOOL, "finished with an error, see ErrorID"),
        StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
    )

    def execute(self) -> None:
        ax = self.axis()
        self.ctl.fault_reset(ax)
        if ax.fault:
            raise MotionError(ErrorCode.AXIS_FAULTED, f"{ax.name}: the fault's cause remains")
        self.fire(BlockEvent.START)

    def poll(self) -> None:
        ax = self.axis()
        if ax.state != AxisState.AXIS_FAULTED and ax.fault == 0:
            self.fire(BlockEvent.COMPLETE)
