"""MASD, Motion Axis Shutdown: force the axis into Axis Shutdown at once.

The drive is disabled and the axis coasts; every motion process ends. Motion commands and
MSO answer ERR 7 until MASR (or MGSR) resets the shutdown. Any axis type can be shut down.
"""

from __future__ import annotations

from ...kernel import Axis
from ..logix_common import AxisCommand
from ..registry import register


@register
class MASD(AxisCommand):
    TYPE = "MASD"
    DESCRIPTION = "Motion Axis Shutdown: drive off, Axis Shutdown state"

    def action(self, ax: Axis) -> None:
        self.ctl.shutdown(ax)
