"""MC_Halt: bring the axis to rest under normal operating conditions.

Unlike MC_Stop there is no Stopping latch: the axis is in DiscreteMotion while it ramps
down and in StandStill once at rest, when Done is set. Another motion command may take
over during the ramp (this block then reports CommandAborted). Refused while the axis is
Stopping (ErrorID 78), as every motion command is. A Deceleration or Jerk beyond the
axis's maximum is limited to it (a halt is never refused for braking too hard).

Halts in the aborting modes without a Jerk, executed on many axes in the same scan, are
planned as one batch (``Controller.stop_many`` with ``halt``); the others execute alone.
"""

from __future__ import annotations

from typing import Any

from ...kernel.processes import halt_ramp
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MotionBlock
from ..registry import register
from ..scan_pass import Batch, BatchKind


@register
class MC_Halt(MotionBlock):
    TYPE = "MC_Halt"
    DESCRIPTION = "Decelerate to rest (no Stopping latch; abortable)"
    OPERANDS = (
        AXIS,
        *(op for op in plcopen_dynamics(with_velocity=False) if op.name != "Acceleration"),
        BUFFER_MODE,
    )

    BATCH = BatchKind.HALT

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the halt returned as (axis,
        deceleration) for ``Controller.stop_many``; None for a buffered or jerk-limited
        halt (it executes alone). Raises what ``execute`` raises before its command."""
        ax = self.axis()
        number = ax.number
        batch.before_axis(number)
        self.check_axis(ax)
        decel, jerk = self.stop_dynamics(ax)
        if jerk != 0.0 or self.buffered():
            return None
        return (ax, decel), (number,)

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        decel, jerk = self.stop_dynamics(ax)
        self.begin(ax, halt_ramp(self.ctl.dt(ax), decel, jerk, self))
