"""MAJ, Motion Axis Jog: run at a speed in a direction until stopped or superseded.

A new MAJ on the axis supersedes the jog process in progress (inheriting its velocity)
and superimposes on the others (gear, move); Merge enabled ends every other process and
blends from the axis's current velocity. With every rate in master units (SpeedUnits,
AccelUnits, DecelUnits = 4) the jog is master-driven: it runs at Speed units per unit of
its MDAC master's travel (see :mod:`.mdsc`).
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any

from ...kernel import Axis, JogProcess, Limits, ProcessKind
from ...kernel.master_driven import MasterDrivenJog
from ...kernel.mdac_links import MasterLink
from ...kernel.processes import Process
from ..dynamics import DriveMode, MergeMode, MergeSpeed
from ..logix_common import STARTED_ACTIVE
from ..operands import AXIS, logix_dynamics
from ..registry import register
from ..scan_pass import Batch, BatchKind
from ..schema import Operand, TagType
from .mdsc import SpeedControlledMotion, tracking_status


class JogDirection(IntEnum):
    FORWARD = 0
    REVERSE = 1


_REVERSE = int(JogDirection.REVERSE)
_AT_CURRENT = int(MergeSpeed.CURRENT)
_MERGE = int(MergeMode.ENABLED)
_TIME_DRIVEN = DriveMode.TIME_DRIVEN
#: the status of a MAJ whose jog started (see ``started_active``)
_JOG_STARTED = {**STARTED_ACTIVE, "TrackingMaster": False}
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

    #: rising edges in one scan start their jogs with one ``Controller.start_jogs``
    BATCH = BatchKind.JOG

    def _plan_jog(self, ax: Axis) -> tuple[DriveMode, float, Limits, float]:
        """The checks and the plan: drive mode, speed, validated limits, direction sign."""
        self.check_axis(ax)
        return self._planned(ax)

    def _planned(self, ax: Axis) -> tuple[DriveMode, float, Limits, float]:
        mode, speed, limits = self.plan(ax)
        if speed <= 0.0:
            # a jog at speed 0: the velocity limit is only a placeholder
            top = ax.config.max_velocity if mode == DriveMode.TIME_DRIVEN else 1.0
            limits = Limits(top, limits.acceleration, limits.deceleration, limits.jerk)
        limits = limits.validated()
        sign = -1.0 if int(self.op["Direction"]) == _REVERSE else 1.0
        return mode, speed, limits, sign

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the jog returned as (axis, signed
        target, limits) for ``Controller.start_jogs``; None for a jog that starts alone
        (Merge ends every other process, a master-driven jog, a pending MDAC switch).
        Without Merge the plan depends on the operands' values and the axis's limits
        only: MAJ with the same values on axes with the same limits plan once. The axis
        checks of ``check_axis`` run in full only where they refuse (the kernel's error):
        an axis in a state that takes motion, not faulted, in a group not stopping (known
        once per group until the batch is handed over) passes them."""
        if int(self.op["Merge"]) == _MERGE:
            return None
        ax = self.batch_axis(batch)
        if ax is None:
            return None
        number = ax.number
        cfg = ax.config
        memo = None
        if key is not None:
            memo = (MAJ, key, cfg.max_velocity, cfg.max_acceleration, cfg.max_deceleration,
                    cfg.max_jerk)  # fmt: skip
            planned = batch.plans.get(memo)
            if planned is not None:
                return (ax, planned[0], planned[1]), (number,)
        mode, speed, limits, sign = self._planned(ax)
        if mode != _TIME_DRIVEN:
            return None
        target = sign * speed
        if memo is not None and speed > 0.0:
            # (not a speed of zero: 0.0 and -0.0 are one key but give targets of two signs)
            batch.plans[memo] = (target, limits)
        return (ax, target, limits), (number,)

    def batch_started(self, process: Process) -> None:
        if isinstance(process, JogProcess):  # time-driven: tracks no master
            self.started_active(process, _JOG_STARTED)
        else:
            self.started(process, tracking_status(process))

    def batch_refused(self) -> None:
        self.outputs["TrackingMaster"] = False  # a refused start tracks nothing

    def execute(self) -> None:
        ax = self.axis()
        mode, speed, limits, sign = self._plan_jog(ax)
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
