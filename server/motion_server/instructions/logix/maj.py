"""MAJ, Motion Axis Jog: run at a speed in a direction until stopped or superseded.

A new MAJ on the axis supersedes the jog process in progress (inheriting its velocity)
and superimposes on the others (gear, move); Merge enabled ends every other process and
blends from the axis's current velocity.
"""

from __future__ import annotations

from enum import IntEnum

from ...kernel import JogProcess, Limits, ProcessKind
from ...kernel.processes import Process
from .. import dynamics
from ..dynamics import MergeMode, MergeSpeed
from ..logix_common import ProcessInstruction
from ..operands import AXIS, logix_dynamics
from ..registry import register
from ..schema import Operand, TagType


class JogDirection(IntEnum):
    FORWARD = 0
    REVERSE = 1


@register
class MAJ(ProcessInstruction):
    TYPE = "MAJ"
    DESCRIPTION = "Motion Axis Jog"
    SETS_PC = False
    OPERANDS = (
        AXIS,
        Operand("Direction", TagType.DINT, 0, enum=JogDirection),
        *logix_dynamics(),
    )

    def execute(self) -> None:
        ax = self.axis()
        self.ctl.require_motion(ax)
        merge = int(self.op["Merge"]) == MergeMode.ENABLED
        speed = dynamics.speed(self, ax)
        if merge and int(self.op["MergeSpeed"]) == MergeSpeed.CURRENT:
            speed = abs(ax.command_velocity)
        limits = dynamics.logix_limits(self, ax, speed)
        if speed <= 0.0:
            limits = Limits(
                ax.config.max_velocity, limits.acceleration, limits.deceleration, limits.jerk
            )
        sign = -1.0 if int(self.op["Direction"]) == JogDirection.REVERSE else 1.0
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            return JogProcess(dt, sign * speed, limits, v, a, owner=self)

        replace = None if merge else (ProcessKind.JOG,)
        self.started(self.ctl.start(ax, make, replace=replace))
