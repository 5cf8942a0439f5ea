"""MC_MoveRelative: move by Distance from the command position where the move starts.

Done when at rest on the target. A buffered move measures from where the previous motion
ended; an aborting move from the position where it takes over, inheriting the velocity.
"""

from __future__ import annotations

from typing import Any

from ...kernel import MoveProcess
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MotionBlock
from ..registry import register
from ..scan_pass import Batch, BatchKind
from ..schema import Operand, Quantity, TagType


@register
class MC_MoveRelative(MotionBlock):
    TYPE = "MC_MoveRelative"
    DESCRIPTION = "Move a distance relative to the position at start"
    OPERANDS = (
        AXIS,
        Operand("Distance", TagType.LREAL, 0.0, quantity=Quantity.POSITION),
        *plcopen_dynamics(),
        BUFFER_MODE,
    )

    #: rising edges in one scan start their moves with one ``Controller.start_moves``
    BATCH = BatchKind.ABORTING_MOVE

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the move returned as (axis, distance,
        limits, no landing) for ``Controller.start_moves``; None for a buffered block
        (it executes alone). Raises what ``execute`` raises before its command."""
        ax = self.axis()
        batch.before_axis(ax.number)
        self.check_axis(ax)
        distance = float(self.op["Distance"])
        limits = self.limits()
        if self.buffered():
            return None
        return (ax, distance, limits, None), (ax.number,)

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        distance = float(self.op["Distance"])
        limits = self.limits()
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            return MoveProcess(dt, distance, limits, v, a, owner=self)

        self.begin(ax, make)
