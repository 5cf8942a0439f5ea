"""MAM, Motion Axis Move: absolute, incremental or rotary moves that end at rest.

A new MAM supersedes the move process in progress (inheriting its velocity) and
superimposes on the others: an incremental MAM on a geared slave is the documented phase
advance/retard. Rotary move types need a rotary axis and a target in [0, rollover).
"""

from __future__ import annotations

import math
from enum import IntEnum

from ...kernel import MoveProcess, ProcessKind
from ...kernel.processes import Process
from .. import dynamics
from ..dynamics import MergeMode, MergeSpeed
from ..logix_common import ProcessInstruction
from ..operands import AXIS, logix_dynamics
from ..registry import register
from ..schema import Operand, Quantity, TagType


class MoveType(IntEnum):
    ABSOLUTE = 0
    INCREMENTAL = 1
    ROTARY_SHORTEST_PATH = 2
    ROTARY_POSITIVE = 3
    ROTARY_NEGATIVE = 4


@register
class MAM(ProcessInstruction):
    TYPE = "MAM"
    DESCRIPTION = "Motion Axis Move"
    OPERANDS = (
        AXIS,
        Operand("MoveType", TagType.DINT, 0, enum=MoveType),
        Operand(
            "Position",
            TagType.REAL,
            0.0,
            quantity=Quantity.POSITION,
            description="target (absolute, rotary) or distance (incremental)",
        ),
        *logix_dynamics(),
    )

    def execute(self) -> None:
        ax = self.axis()
        self.ctl.require_motion(ax)
        merge = int(self.op["Merge"]) == MergeMode.ENABLED
        speed = dynamics.speed(self, ax)
        if merge and int(self.op["MergeSpeed"]) == MergeSpeed.CURRENT:
            speed = abs(ax.command_velocity)
        if speed <= 0.0:
            raise self.out_of_range("Speed", "a move needs a speed > 0")
        limits = dynamics.logix_limits(self, ax, speed)
        distance = self._distance(ax.command_position, ax.config.rollover)
        landing = None
        if int(self.op["MoveType"]) != MoveType.INCREMENTAL:
            end = ax.command_position_unwound + distance
            landing = ax.unwound_target(float(self.op["Position"]), end)
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            return MoveProcess(dt, distance, limits, v, a, owner=self, landing=landing)

        replace = None if merge else (ProcessKind.MOVE,)
        self.started(self.ctl.start(ax, make, replace=replace))

    def _distance(self, here: float, rollover: float) -> float:
        kind = MoveType(int(self.op["MoveType"]))
        target = float(self.op["Position"])
        if kind == MoveType.INCREMENTAL:
            return target
        if rollover > 0.0:
            if not 0.0 <= target < rollover:
                raise self.out_of_range("Position", f"rotary target must be in [0, {rollover})")
        elif kind != MoveType.ABSOLUTE:
            raise self.out_of_range("MoveType", "rotary move types need a rotary axis")
        if kind == MoveType.ABSOLUTE:
            return target - here
        if kind == MoveType.ROTARY_SHORTEST_PATH:
            return math.remainder(target - here, rollover)
        if kind == MoveType.ROTARY_POSITIVE:
            return (target - here) % rollover
        return -((here - target) % rollover)
