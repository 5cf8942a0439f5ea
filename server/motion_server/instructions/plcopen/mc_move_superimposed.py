"""MC_MoveSuperimposed: a relative move of Distance on top of whatever the axis does.

The underlying motion (a move, a jog, a gear) is not aborted: the superimposed move is
one more process on the axis, and the velocities add, as an incremental MAM does on a
geared slave. On an axis at rest it is an MC_MoveRelative. A second MC_MoveSuperimposed
replaces the active one only (which reports CommandAborted), inheriting its velocity and
travelling Distance from where it takes over; the underlying motion goes on. An aborting
motion command, MC_Halt and MC_Stop abort both. Done when the superimposed move has
covered Distance (the underlying motion may still run). CoveredDistance is the distance
it has covered so far, held after it ends. MC_HaltSuperimposed ends it (CommandAborted)
and ramps its velocity to rest; a new MC_MoveSuperimposed replaces that halt as it
replaces a superimposed move.
"""

from __future__ import annotations

from ...kernel import AbortReason, Axis, MoveProcess, ProcessKind, StopRamp
from ...kernel.processes import Process
from ..base import BlockEvent
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import MotionBlock
from ..registry import register
from ..schema import Operand, Quantity, StatusField, TagType


class SuperimposedMove(MoveProcess):
    """A move riding on the axis's other motion. Its own class keeps it out of the fast
    lanes (they admit processes by exact class), so the lanes stay bit-identical."""


class SuperimposedHalt(StopRamp):
    """MC_HaltSuperimposed: the superimposed move's own velocity ramped to rest, on top
    of the underlying motion. A move process, as the superimposed move it replaces (a
    Logix MAS of type Move stops it; it keeps the axis's state), outside the lanes."""

    kind = ProcessKind.MOVE


def superimposed_move(ax: Axis) -> SuperimposedMove | SuperimposedHalt | None:
    """The axis's active superimposed motion (a move, or the halt of one), if any."""
    for p in ax.processes:
        if p.active and isinstance(p, SuperimposedMove | SuperimposedHalt):
            return p
    return None


@register
class MC_MoveSuperimposed(MotionBlock):
    TYPE = "MC_MoveSuperimposed"
    DESCRIPTION = "Superimpose a relative move on the running motion"
    OPERANDS = (
        AXIS,
        Operand("Distance", TagType.LREAL, 0.0, quantity=Quantity.POSITION),
        Operand(
            "VelocityDiff",
            TagType.LREAL,
            10.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.VELOCITY,
            description="velocity of the superimposed move over the underlying motion",
        ),
        *plcopen_dynamics(with_velocity=False),
    )
    OUTPUTS = (
        StatusField(
            "CoveredDistance",
            TagType.LREAL,
            "distance covered by the superimposed move",
            quantity=Quantity.POSITION,
        ),
    )

    def execute(self) -> None:
        self.process = None
        ax = self.axis()
        self.check_axis(ax)
        distance = float(self.op["Distance"])
        limits = self.limits(float(self.op["VelocityDiff"]), "VelocityDiff")
        old = superimposed_move(ax)
        v0 = a0 = 0.0
        if old is not None:  # never in a lane: its velocity is current
            v0, a0 = old.velocity, old.acceleration
        # built before anything changes: if it cannot be planned the old one goes on
        new = SuperimposedMove(self.ctl.dt(ax), distance, limits, v0, a0, owner=self)
        if old is not None:
            old.abort(AbortReason.SUPERSEDED)

        def make(v: float, a: float) -> Process:
            return new

        self.process = self.ctl.start(ax, make, replace=())
        self.fire(BlockEvent.START)
        self.active = True

    def publish_extra(self) -> None:
        p = self.process
        self.outputs["CoveredDistance"] = p.position if p is not None else 0.0
