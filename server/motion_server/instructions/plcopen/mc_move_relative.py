"""MC_MoveRelative: move by Distance from the command position where the move starts.

Done when at rest on the target. A buffered move measures from where the previous motion
ended; an aborting move from the position where it takes over, inheriting the velocity.
"""

from __future__ import annotations

from ...kernel import MoveProcess
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MotionBlock
from ..registry import register
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

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        distance = float(self.op["Distance"])
        limits = self.limits()
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            return MoveProcess(dt, distance, limits, v, a, owner=self)

        self.begin(ax, make)
