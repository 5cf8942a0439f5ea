"""MC_GearOut: disengage the slave from its master; the slave keeps its velocity.

The gear process (of MC_GearIn, MC_GearInPos or MAG) is replaced by a constant-velocity
process at the gear's velocity: the slave is in ContinuousMotion until a stop (MC_Stop,
MC_Halt ...). Done in the scan it executes; the gearing block reports CommandAborted.

Errors: slave not geared ErrorID 1003; a combined (MC_CombineAxes) slave 1002, the seed
forbids MC_GearOut there (use MC_Stop); the slave must be in Servo Control (5, 7, 20).
"""

from __future__ import annotations

from ...kernel import ErrorCode, MotionError, ProcessKind
from ...kernel.gearing import GearProcess, VelocityHold, active_gear
from ...kernel.processes import Process
from ..base import BlockEvent, PLCopenBlock
from ..registry import register
from .mc_gear_in import SLAVE


@register
class MC_GearOut(PLCopenBlock):
    TYPE = "MC_GearOut"
    DESCRIPTION = "Disengage the slave; it keeps its velocity until stopped"
    OPERANDS = (SLAVE,)

    def execute(self) -> None:
        slave = self.axis("Slave")
        self.ctl.require_motion(slave)
        gear = active_gear(slave)
        if gear is None:
            raise MotionError(ErrorCode.NOT_GEARED, f"{slave.name} is not geared")
        if isinstance(gear, GearProcess) and gear.combined:
            raise MotionError(
                ErrorCode.COMBINED_SLAVE_GEAR_OUT,
                f"{slave.name} follows two masters: stop it with MC_Stop",
            )

        def make(v: float, a: float) -> Process:
            return VelocityHold(v, owner=self)

        self.ctl.start(slave, make, replace=(ProcessKind.GEAR,))
        self.fire(BlockEvent.START)
        self.fire(BlockEvent.COMPLETE)
