"""MAFR, Motion Axis Fault Reset: clear the axis faults.

A faulted axis returns to Axis Ready (drive off; MSO enables it again). Any axis type can
be reset, a feedback-only axis too (its faults are encoder faults). On an axis without
faults MAFR is done at once and changes nothing.
"""

from __future__ import annotations

from ...kernel import Axis
from ..logix_common import AxisCommand
from ..registry import register


@register
class MAFR(AxisCommand):
    TYPE = "MAFR"
    DESCRIPTION = "Motion Axis Fault Reset: clear faults, Axis Faulted -> Axis Ready"

    def action(self, ax: Axis) -> None:
        self.ctl.fault_reset(ax)
