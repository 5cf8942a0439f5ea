"""MC_HaltSuperimposed: halt the superimposed motion of an axis, and only that.

PLCopen Part 1: "commands a halt to all superimposed motions of the axis. The underlying
motion is not interrupted." The MC_MoveSuperimposed in progress is aborted (it reports
CommandAborted) and its own velocity, the part it adds to the underlying move, jog or
gear, ramps to rest at Deceleration (Jerk 0: trapezoidal); the underlying motion goes on
as it was, and the axis stays in its state (at rest: DiscreteMotion until the ramp
ends). Done when the superimposed velocity is 0; Done in the scan of the edge when there
is nothing superimposed to halt. A Deceleration or Jerk beyond the axis maximum is
limited to it, as for MC_Halt. A new MC_MoveSuperimposed during the ramp takes over from
it (this block: CommandAborted); an aborting motion command, MC_Halt or MC_Stop aborts it
with the underlying motion. Refused while the axis is Stopping (ErrorID 78), as every
motion command is.
"""

from __future__ import annotations

from ...kernel import AbortReason, ProcessState
from ...kernel.processes import Process
from ..base import BlockEvent
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import MotionBlock
from ..registry import register
from .mc_move_superimposed import SuperimposedHalt, superimposed_move


@register
class MC_HaltSuperimposed(MotionBlock):
    TYPE = "MC_HaltSuperimposed"
    DESCRIPTION = "Halt the superimposed motion only (the underlying motion goes on)"
    OPERANDS = (
        AXIS,
        *(op for op in plcopen_dynamics(with_velocity=False) if op.name != "Acceleration"),
    )

    def execute(self) -> None:
        self.process = None
        ax = self.axis()
        self.check_axis(ax)
        decel, jerk = self.stop_dynamics(ax)
        old = superimposed_move(ax)
        v0 = a0 = 0.0
        if old is not None:  # never in a lane: its velocity is current
            v0, a0 = old.velocity, old.acceleration
        # built before anything changes: a bad Deceleration leaves the move running
        halt = SuperimposedHalt(self.ctl.dt(ax), decel, jerk, v0, a0, owner=self, stopping=False)
        self.fire(BlockEvent.START)
        if old is not None:
            old.abort(AbortReason.SUPERSEDED)
        if old is None or halt.state == ProcessState.DONE:
            # nothing superimposed, or nothing left of its velocity: halted already
            self.fire(BlockEvent.COMPLETE)
            return

        def make(v: float, a: float) -> Process:
            return halt

        self.process = self.ctl.start(ax, make, replace=())
        self.active = True
