"""MC_Halt: bring the axis to rest under normal operating conditions.

Unlike MC_Stop there is no Stopping latch: the axis is in DiscreteMotion while it ramps
down and in StandStill once at rest, when Done is set. Another motion command may take
over during the ramp (this block then reports CommandAborted). Refused while the axis is
Stopping (ErrorID 78), as every motion command is. A Deceleration or Jerk beyond the
axis's maximum is limited to it (a halt is never refused for braking too hard).
"""

from __future__ import annotations

from ...kernel import StopRamp
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MotionBlock
from ..registry import register


@register
class MC_Halt(MotionBlock):
    TYPE = "MC_Halt"
    DESCRIPTION = "Decelerate to rest (no Stopping latch; abortable)"
    OPERANDS = (
        AXIS,
        *(op for op in plcopen_dynamics(with_velocity=False) if op.name != "Acceleration"),
        BUFFER_MODE,
    )

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        decel, jerk = self.stop_dynamics(ax)
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            return StopRamp(dt, decel, jerk, v, a, owner=self, stopping=False)

        self.begin(ax, make)
