"""MSF, Motion Servo Off: drive disabled at once, servo loop opened; the axis coasts.

Every motion process on the axis ends (their instructions drop IP). A feedback-only axis
has no drive: ERR 8. On an axis that is not in Servo Control MSF changes nothing and is
done at once (a faulted or shut-down drive is already off).
"""

from __future__ import annotations

from ...kernel import Axis, AxisType, ErrorCode, MotionError
from ..logix_common import AxisCommand
from ..registry import register


@register
class MSF(AxisCommand):
    TYPE = "MSF"
    DESCRIPTION = "Motion Servo Off: drive disabled, the axis coasts"

    def action(self, ax: Axis) -> None:
        if ax.type == AxisType.FEEDBACK_ONLY:
            raise MotionError(ErrorCode.WRONG_AXIS_TYPE, f"{ax.name} has no drive")
        self.ctl.servo_off(ax)
