"""MC_MoveAbsolute: move to a position and stop there (Done when at rest on target).

On a rotary axis Direction chooses the way round (positive, shortest, negative, current);
on a linear axis it is ignored, as the target fixes the direction.
"""

from __future__ import annotations

import math
from typing import Any

from ...kernel import Axis, Limits, MoveProcess
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MCDirection, MotionBlock
from ..registry import register
from ..scan_pass import Batch, BatchKind
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

    #: rising edges in one scan start their moves with one ``Controller.start_moves``
    BATCH = BatchKind.ABORTING_MOVE

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the move returned as (axis, distance,
        limits, landing) for ``Controller.start_moves``; None for a buffered block, or
        the current direction on a rotary axis, which reads the velocity the move
        inherits (it executes alone). Raises what ``execute`` raises before its
        command."""
        ax = self.axis()
        batch.before_axis(ax.number)
        target, direction, limits = self._judged(ax)
        if self.buffered() or (ax.config.rollover > 0.0 and direction == MCDirection.CURRENT):
            return None
        distance, landing = _route(ax, target, direction, 0.0)
        return (ax, distance, limits, landing), (ax.number,)

    def _judged(self, ax: Axis) -> tuple[float, MCDirection, Limits]:
        """The checks of ``execute`` before its command: the target, the direction and
        the limits."""
        self.check_axis(ax)
        rollover = ax.config.rollover
        target = float(self.op["Position"])
        if rollover > 0.0 and not 0.0 <= target < rollover:
            raise self.out_of_range("Position", f"rotary target must be in [0, {rollover})")
        return target, MCDirection(int(self.op["Direction"])), self.limits()

    def execute(self) -> None:
        ax = self.axis()
        target, direction, limits = self._judged(ax)
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            # measured when the move starts (a buffered move starts later)
            distance, landing = _route(ax, target, direction, v)
            return MoveProcess(dt, distance, limits, v, a, owner=self, landing=landing)

        self.begin(ax, make)


def _route(ax: Axis, target: float, direction: MCDirection, v: float) -> tuple[float, float]:
    """The distance from ``ax``'s command position to ``target`` (the way round a rotary
    axis that ``direction`` chooses, ``v`` the velocity the move inherits) and the
    unwound position it lands on."""
    rollover = ax.config.rollover
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
    return distance, ax.unwound_target(target, ax.command_position_unwound + distance)
