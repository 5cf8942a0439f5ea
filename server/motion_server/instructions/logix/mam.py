"""MAM, Motion Axis Move: absolute, incremental or rotary moves that end at rest.

A new MAM supersedes the move process in progress (inheriting its velocity) and
superimposes on the others: an incremental MAM on a geared slave is the documented phase
advance/retard. Rotary move types need a rotary axis and a target in [0, rollover). With
every rate in master units the move is master-driven: it covers its distance while its
MDAC master travels (see :mod:`.mdsc`).
"""

from __future__ import annotations

import math
from enum import IntEnum

from ...kernel import Axis, MoveProcess, ProcessKind
from ...kernel.master_driven import MasterDrivenMove
from ...kernel.mdac_links import MasterLink
from ...kernel.processes import Process
from ..operands import AXIS, logix_dynamics
from ..registry import register
from ..schema import Operand, Quantity, TagType
from .mdsc import SpeedControlledMotion


class MoveType(IntEnum):
    ABSOLUTE = 0
    INCREMENTAL = 1
    ROTARY_SHORTEST_PATH = 2
    ROTARY_POSITIVE = 3
    ROTARY_NEGATIVE = 4


@register
class MAM(SpeedControlledMotion):
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
        self.check_axis(ax)
        mode, speed, limits = self.plan(ax)
        if speed <= 0.0:
            raise self.out_of_range("Speed", "a move needs a speed > 0")
        limits = limits.validated()
        distance = self._distance(ax.command_position, ax.config.rollover)
        landing = None
        if int(self.op["MoveType"]) != MoveType.INCREMENTAL:
            end = ax.command_position_unwound + distance
            landing = ax.unwound_target(float(self.op["Position"]), end)
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            return MoveProcess(dt, distance, limits, v, a, owner=self, landing=landing)

        def make_master(link: MasterLink, master: Axis, ratio: float) -> Process:
            self.judge_master_driven(ax, master, speed, limits, ratio, distance)
            return MasterDrivenMove(
                self.ctl, master, link.reference, distance, limits, ratio, owner=self
            )

        replace = None if self.merging else (ProcessKind.MOVE,)
        self.launch(ax, ProcessKind.MOVE, mode, speed, make, make_master, replace)

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
