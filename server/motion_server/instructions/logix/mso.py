"""MSO, Motion Servo On: enable the drive and close the servo loop at the actual position."""

from __future__ import annotations

from ...kernel import Axis
from ..logix_common import AxisCommand
from ..registry import register


@register
class MSO(AxisCommand):
    TYPE = "MSO"
    DESCRIPTION = "Motion Servo On: Axis Ready -> Servo Control"

    def action(self, ax: Axis) -> None:
        self.ctl.servo_on(ax)
