"""MAJ, Motion Axis Jog: run at a speed in a direction until stopped or superseded.

A new MAJ on the axis supersedes the jog process in progress (inheriting its velocity)
and superimposes on the others (gear, move); Merge enabled ends every other process and
blends from the axis's current velocity. With every rate in master units (SpeedUnits,
AccelUnits, DecelUnits = 4) the jog is master-driven: it runs at Speed units per unit of
its MDAC master's travel (see :mod:`.mdsc`).
"""

from __future__ import annotations

from enum import IntEnum

from ...kernel import Axis, JogProcess, Limits, ProcessKind
from ...kernel.master_driven import MasterDrivenJog
from ...kernel.mdac_links import MasterLink
from ...kernel.processes import Process
from ..dynamics import DriveMode, MergeSpeed
from ..operands import AXIS, logix_dynamics
from ..registry import register
from ..schema import Operand, TagType
from .mdsc import SpeedControlledMotion


class JogDirection(IntEnum):
    FORWARD = 0
    REVERSE = 1


_REVERSE = int(JogDirection.REVERSE)
_AT_CURRENT = int(MergeSpeed.CURRENT)
#: the processes a jog without Merge supersedes
_REPLACE = (ProcessKind.JOG,)


@register
class MAJ(SpeedControlledMotion):
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
        self.check_axis(ax)
        mode, speed, limits = self.plan(ax)
        if speed <= 0.0:
            # a jog at speed 0: the velocity limit is only a placeholder
            top = ax.config.max_velocity if mode == DriveMode.TIME_DRIVEN else 1.0
            limits = Limits(top, limits.acceleration, limits.deceleration, limits.jerk)
        limits = limits.validated()
        sign = -1.0 if int(self.op["Direction"]) == _REVERSE else 1.0
        dt = self.ctl.dt(ax)
        merging = self.merging
        merge_current = merging and int(self.op["MergeSpeed"]) == _AT_CURRENT

        def make(v: float, a: float) -> Process:
            return JogProcess(dt, sign * speed, limits, v, a, owner=self)

        def make_master(link: MasterLink, master: Axis, ratio: float) -> Process:
            target = abs(ratio) if merge_current else speed
            self.judge_master_driven(ax, master, sign * target, limits, ratio)
            return MasterDrivenJog(
                self.ctl, master, link.reference, sign * target, limits, ratio, owner=self
            )

        replace = None if merging else _REPLACE
        self.launch(ax, ProcessKind.JOG, mode, speed, make, make_master, replace)
