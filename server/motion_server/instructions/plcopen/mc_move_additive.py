"""MC_MoveAdditive: move by Distance beyond the last commanded target position.

In DiscreteMotion (a move toward a target is running) the new target is that move's
target plus Distance: the remaining part of the aborted move is travelled too. In
ContinuousMotion, SynchronizedMotion or StandStill there is no commanded target and
Distance is added to the set (command) position where the move takes over, as
MC_MoveRelative does. A buffered move starts once the previous motion is done, on its
target, so it also ends Distance beyond it. Done when at rest on the target.
"""

from __future__ import annotations

from ...kernel import Axis, MoveProcess
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MotionBlock
from ..registry import register
from ..schema import Operand, Quantity, TagType
from .mc_move_superimposed import SuperimposedMove


def discrete_move(ax: Axis) -> MoveProcess | None:
    """The move toward a target the axis runs (DiscreteMotion), if any: a superimposed
    move is not one (it rides on the underlying motion)."""
    for p in ax.processes:
        if p.active and isinstance(p, MoveProcess) and not isinstance(p, SuperimposedMove):
            return p
    return None


@register
class MC_MoveAdditive(MotionBlock):
    TYPE = "MC_MoveAdditive"
    DESCRIPTION = "Move a distance beyond the last commanded target position"
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
        buffered = self.buffered()

        def make(v: float, a: float) -> Process:
            # measured when the move starts: a buffered move starts after the previous
            # one is done (nothing remains of it); an aborting one takes over its rest
            prev = None if buffered else discrete_move(ax)
            rest = 0.0 if prev is None else prev.displacement - prev.position
            landing = None
            if prev is not None and prev.landing is not None:
                landing = prev.landing + distance
            return MoveProcess(dt, rest + distance, limits, v, a, owner=self, landing=landing)

        self.begin(ax, make)
