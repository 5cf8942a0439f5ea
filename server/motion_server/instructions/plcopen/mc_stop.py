"""MC_Stop: bring the axis to rest and hold it in Stopping while Execute stays high.

Every other motion on the axis is aborted (its blocks report CommandAborted); motion
commands are refused while the axis is Stopping. Done is held while Execute is high; the
axis returns to StandStill once Done is set and Execute is low. A Deceleration or Jerk
beyond the axis's maximum is limited to it: a stop is never refused for braking too hard.
"""

from __future__ import annotations

from ...kernel import ProcessState
from ..base import BlockEvent
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import MotionBlock
from ..registry import register


@register
class MC_Stop(MotionBlock):
    TYPE = "MC_Stop"
    DESCRIPTION = "Stop the axis and hold it in Stopping while Execute is high"
    OPERANDS = (AXIS, *plcopen_dynamics(with_velocity=False))

    def execute(self) -> None:
        ax = self.axis()
        self.ctl.require_motion(ax)
        decel, jerk = self.stop_dynamics(ax)
        self.process = self.ctl.stop(ax, None, decel, jerk, owner=self)
        ax.stop_latch = self
        self.fire(BlockEvent.START)
        self.active = True
        if self.process.state == ProcessState.DONE:
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
