"""MC_MoveAbsolute: move to a position and stop there (Done when at rest on target).

On a rotary axis Direction chooses the way round (positive, shortest, negative, current);
on a linear axis it is ignored, as the target fixes the direction.
"""

from __future__ import annotations

import math

from ...kernel import MoveProcess
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MCDirection, MotionBlock
from ..registry import register
from ..schema import Operand, Quantity, TagType


@register
class MC_MoveAbsolute(MotionBlock):
    TYPE = "MC_MoveAbsolute"
    DESCRIPTION = "Move to an absolute position"
    OPERANDS = (
        AXIS,
        Operand("Position", TagType.LREAL, 0.0, quantity=Quantity.POSITION),
        *plcopen_dynamics(),
        Operand("Direction", TagType.DINT, MCDirection.SHORTEST_WAY, enum=MCDirection),
        BUFFER_MODE,
    )

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        rollover = ax.config.rollover
        target = float(self.op["Position"])
        if rollover > 0.0 and not 0.0 <= target < rollover:
            raise self.out_of_range("Position", f"rotary target must be in [0, {rollover})")
        direction = MCDirection(int(self.op["Direction"]))
        limits = self.limits()
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            # measured when the move starts (a buffered move starts later)
            here = ax.command_position
            if rollover <= 0.0:
                distance = target - here
            elif direction == MCDirection.POSITIVE:
                distance = (target - here) % rollover
            elif direction == MCDirection.NEGATIVE:
                distance = -((here - target) % rollover)
            elif direction == MCDirection.CURRENT and v != 0.0:
                distance = (target - here) % rollover if v > 0 else -((here - target) % rollover)
            else:
                distance = math.remainder(target - here, rollover)
            landing = ax.unwound_target(target, ax.command_position_unwound + distance)
            return MoveProcess(dt, distance, limits, v, a, owner=self, landing=landing)

        self.begin(ax, make)
