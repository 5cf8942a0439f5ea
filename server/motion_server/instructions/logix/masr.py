"""MASR, Motion Axis Shutdown Reset: Axis Shutdown -> Axis Ready, faults cleared.

On an axis that is not shut down MASR clears its faults (a faulted axis returns to Axis
Ready, as after MAFR) and is otherwise done at once with no effect.
"""

from __future__ import annotations

from ...kernel import Axis
from ..logix_common import AxisCommand
from ..registry import register


@register
class MASR(AxisCommand):
    TYPE = "MASR"
    DESCRIPTION = "Motion Axis Shutdown Reset: Axis Shutdown -> Axis Ready"

    def action(self, ax: Axis) -> None:
        self.ctl.shutdown_reset(ax)
