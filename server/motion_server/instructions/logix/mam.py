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
from typing import Any

from ...kernel import Axis, Limits, MoveProcess, ProcessKind
from ...kernel.master_driven import MasterDrivenMove
from ...kernel.mdac_links import MasterLink
from ...kernel.processes import Process
from ..dynamics import DriveMode
from ..logix_common import STARTED_ACTIVE
from ..operands import AXIS, logix_dynamics
from ..registry import register
from ..scan_pass import Batch, BatchKind
from ..schema import Operand, Quantity, TagType
from .mdsc import SpeedControlledMotion, tracking_status


class MoveType(IntEnum):
    ABSOLUTE = 0
    INCREMENTAL = 1
    ROTARY_SHORTEST_PATH = 2
    ROTARY_POSITIVE = 3
    ROTARY_NEGATIVE = 4


_TIME_DRIVEN = DriveMode.TIME_DRIVEN
#: the operands the plan of a move's dynamics reads (its target's are not among them)
_DYNAMICS = tuple(op.name for op in logix_dynamics())
#: the status of a MAM whose time-driven move started (see ``started_active``)
_MOVE_STARTED = {**STARTED_ACTIVE, "TrackingMaster": False}


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

    #: rising edges in one scan start their moves with one ``Controller.start_moves``
    BATCH = BatchKind.MOVE

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the move returned as (axis, distance,
        limits, landing) for ``Controller.start_moves``; None for a move that starts
        alone (Merge ends every other process, a master-driven move, a pending MDAC
        switch). The plan of the dynamics depends on the dynamics operands' values and
        the axis's limits only (not on the target): MAM with the same dynamics on axes
        with the same limits plan them once. The axis checks run in full only where they
        refuse, as MAJ's do."""
        if self.merging:
            return None
        ax = self.batch_axis(batch)
        if ax is None:
            return None
        cfg = ax.config
        # (the judge passed the latched values: they hash)
        memo = (MAM, *map(self.op.__getitem__, _DYNAMICS), cfg.max_velocity,
                cfg.max_acceleration, cfg.max_deceleration, cfg.max_jerk)  # fmt: skip
        limits: Limits | None = batch.plans.get(memo)
        if limits is None:
            mode, speed, limits = self.plan(ax)
            if mode != _TIME_DRIVEN:
                return None
            limits = self._dynamics(speed, limits)
            batch.plans[memo] = limits
        distance, landing = self._target(ax)
        return (ax, distance, limits, landing), (ax.number,)

    def batch_started(self, process: Process) -> None:
        if isinstance(process, MoveProcess):  # time-driven: tracks no master
            self.started_active(process, _MOVE_STARTED)
        else:
            self.started(process, tracking_status(process))

    def batch_refused(self) -> None:
        self.outputs["TrackingMaster"] = False  # a refused start tracks nothing

    def _dynamics(self, speed: float, limits: Limits) -> Limits:
        """The move's limits, once its speed is judged."""
        if speed <= 0.0:
            raise self.out_of_range("Speed", "a move needs a speed > 0")
        return limits.validated()

    def _target(self, ax: Axis) -> tuple[float, float | None]:
        """The distance to travel and, for a target that is not a distance, the unwound
        position the move lands on."""
        distance = self._distance(ax.command_position, ax.config.rollover)
        landing = None
        if int(self.op["MoveType"]) != MoveType.INCREMENTAL:
            end = ax.command_position_unwound + distance
            landing = ax.unwound_target(float(self.op["Position"]), end)
        return distance, landing

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        mode, speed, limits = self.plan(ax)
        limits = self._dynamics(speed, limits)
        distance, landing = self._target(ax)
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
