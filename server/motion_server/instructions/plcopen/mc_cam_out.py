"""MC_CamOut: disengage the slave from its cam; it keeps its velocity (PLCopen Part 1).

The cam process (of MC_CamIn or MAPC) is replaced by a constant-velocity process at the
cam's velocity: the slave is in ContinuousMotion until a stop (MC_Stop, MC_Halt ...), as
after MC_GearOut. Done in the scan it executes; the cam's block reports CommandAborted.

Errors: ErrorID 1006 the slave is not position camming; 5, 7, 20 its power state.
"""

from __future__ import annotations

from ...kernel import ErrorCode, MotionError, ProcessKind
from ...kernel.cams import active_cam
from ...kernel.gearing import VelocityHold
from ...kernel.processes import Process
from ..base import BlockEvent, PLCopenBlock
from ..registry import register
from .mc_gear_in import SLAVE


@register
class MC_CamOut(PLCopenBlock):
    TYPE = "MC_CamOut"
    DESCRIPTION = "Disengage the slave from its cam; it keeps its velocity until stopped"
    OPERANDS = (SLAVE,)

    def execute(self) -> None:
        slave = self.axis("Slave")
        self.ctl.require_motion(slave)
        if active_cam(slave, ProcessKind.POSITION_CAM) is None:
            raise MotionError(ErrorCode.NOT_CAMMING, f"{slave.name} is not camming")

        def make(v: float, a: float) -> Process:
            return VelocityHold(v, owner=self)

        self.ctl.start(slave, make, replace=(ProcessKind.POSITION_CAM,))
        self.fire(BlockEvent.START)
        self.fire(BlockEvent.COMPLETE)
