"""MC_Stop: bring the axis to rest and hold it in Stopping while Execute stays high.

Every other motion on the axis is aborted (its blocks report CommandAborted); motion
commands are refused while the axis is Stopping. Done is held while Execute is high; the
axis returns to StandStill once Done is set and Execute is low. A Deceleration or Jerk
beyond the axis's maximum is limited to it: a stop is never refused for braking too hard.
"""

from __future__ import annotations

from typing import Any

from ...kernel import ProcessState
from ...kernel.processes import Process
from ..base import BlockEvent
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import MotionBlock
from ..registry import register
from ..scan_pass import Batch, BatchKind


@register
class MC_Stop(MotionBlock):
    TYPE = "MC_Stop"
    DESCRIPTION = "Stop the axis and hold it in Stopping while Execute is high"
    OPERANDS = (AXIS, *plcopen_dynamics(with_velocity=False))

    BATCH = BatchKind.STOP

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the stop returned as (axis,
        deceleration) for ``Controller.stop_many``; None for a jerk-limited stop (it
        executes alone). Raises what ``execute`` raises before its command."""
        ax = self.axis()
        number = ax.number
        batch.before_axis(number)
        self.ctl.require_motion(ax)
        decel, jerk = self.stop_dynamics(ax)
        if jerk != 0.0:
            return None
        return (ax, decel), (number,)

    def batch_started(self, process: Process) -> None:
        """The rest of ``execute`` and of the rising edge's scan."""
        self._started(process)
        self._publish()
        self._release_if_idle()

    def batch_refused(self) -> None:
        """The kernel refused the stop (its error set): the end of the scan."""
        self._publish()
        self._release_if_idle()

    def execute(self) -> None:
        ax = self.axis()
        self.ctl.require_motion(ax)
        decel, jerk = self.stop_dynamics(ax)
        self._started(self.ctl.stop(ax, None, decel, jerk, owner=self))

    def _started(self, process: Process) -> None:
        """Follow the stop ``process`` of the axis, latched Stopping by this block."""
        self.process = process
        self.axis().stop_latch = self
        self.fire(BlockEvent.START)
        self.active = True
        if process.state == ProcessState.DONE:
            self.fire(BlockEvent.COMPLETE)

    def poll(self) -> None:
        super().poll()
        self._release_if_idle()

    def on_release(self) -> None:
        self._release_if_idle()

    def scan(self) -> None:
        super().scan()
        self._release_if_idle()

    def asleep(self) -> bool:
        if not super().asleep():
            return False
        try:
            return self.axis().stop_latch is not self  # else the scan drops the latch
        except Exception:
            return True

    def _release_if_idle(self) -> None:
        """Drop the Stopping latch once Execute is low and the stop has ended."""
        try:
            ax = self.axis()
        except Exception:
            return
        if ax.stop_latch is self and not self.inputs[self.TRIGGER] and self.state.name != "BUSY":
            ax.stop_latch = None
