"""Shared shapes of PLCopen motion blocks: buffer modes and following one process."""

from __future__ import annotations

import math
from enum import IntEnum
from typing import ClassVar

from ..kernel import Axis, ErrorCode, Limits, MotionError, Pending, ProcessState
from ..kernel.controller import ProcessFactory
from ..kernel.processes import Process
from .base import BlockEvent, BlockState, PLCopenBlock
from .schema import Operand, TagType

_ACTIVE = ProcessState.ACTIVE
_BUSY = BlockState.BUSY


def follows_as(cls: type[PLCopenBlock], owner: type[PLCopenBlock]) -> bool:
    """``cls`` scans, updates, polls and publishes as ``owner`` does (what a block's
    ``parked_on`` relies on: a subclass that changes one of them does not park)."""
    return all(
        getattr(cls, name) is getattr(owner, name)
        for name in ("scan", "update", "poll", "publish_extra")
    )


def _parks(cls: type[MotionBlock]) -> bool:
    """Blocks of ``cls`` change nothing while their process runs (see
    :meth:`MotionBlock.parked_on`)."""
    return follows_as(cls, MotionBlock)


class BufferMode(IntEnum):
    ABORTING = 0
    BUFFERED = 1


class MCDirection(IntEnum):
    POSITIVE = 1
    SHORTEST_WAY = 2
    NEGATIVE = 3
    CURRENT = 4


class MCSource(IntEnum):
    """PLCopen MC_Source: the reverse numbering of Logix MasterReference."""

    SET_VALUE = 0
    ACTUAL_VALUE = 1


BUFFER_MODE = Operand(
    "BufferMode", TagType.DINT, 0, enum=BufferMode, description="0 aborting, 1 buffered"
)


class MotionBlock(PLCopenBlock):
    """A block that commands one motion process on ``Axis``.

    Aborting mode ends every process on the axis and inherits its velocity; buffered mode
    waits until the active motion is done (or at speed / in sync). Busy until done,
    aborted or failed; Active while its process runs.
    """

    #: True when the block is done as soon as its process has "reached" (InVelocity is
    #: not Done: MC_MoveVelocity stays Busy)
    DONE_ON_FINISH: ClassVar[bool] = True

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.process: Process | None = None
        self.pending: Pending | None = None

    def check_axis(self, ax: Axis) -> None:
        self.ctl.require_motion(ax)
        if ax.stopping:
            raise MotionError(
                ErrorCode.NOT_ALLOWED_WHILE_STOPPING,
                f"{ax.name} is stopping: motion commands are refused",
            )

    def limits(self, velocity: float | None = None, velocity_name: str = "Velocity") -> Limits:
        """Velocity (or ``velocity``), Acceleration, Deceleration and Jerk as validated
        profile limits, within the axis's maxima: a command beyond one is refused (Error,
        ErrorID of the operand out of range), as the PLCopen vendors' blocks check their
        inputs before the job reaches the motion controller. ``velocity_name`` names the
        operand a velocity beyond the maximum is reported on."""
        limits = Limits(
            float(self.op["Velocity"]) if velocity is None else velocity,
            float(self.op["Acceleration"]),
            float(self.op["Deceleration"]),
            float(self.op["Jerk"]),
        ).validated()
        cfg = self.axis().config
        for name, value, maximum, what in (
            (velocity_name, limits.velocity, cfg.max_velocity, "max_velocity"),
            ("Acceleration", limits.acceleration, cfg.max_acceleration, "max_acceleration"),
            ("Deceleration", limits.deceleration, cfg.max_deceleration, "max_deceleration"),
            ("Jerk", limits.jerk, cfg.max_jerk or math.inf, "max_jerk"),
        ):
            if value > maximum:
                raise self.out_of_range(
                    name, f"{name} {value:g} is beyond the axis {what} {maximum:g}"
                )
        return limits

    def stop_dynamics(self, ax: Axis) -> tuple[float, float]:
        """Deceleration and Jerk of a stop or halt (MC_Stop, MC_Halt), limited to the
        axis's maxima rather than refused: a stop asked steeper than the axis may brake
        still stops it, at its maximum deceleration (and jerk), as Logix MAS and MGS do.
        A value that is no valid rate at all (<= 0, NaN) is left for the kernel to judge
        (ErrorID 13). Jerk 0 stays 0 (trapezoidal), as for every PLCopen motion block."""
        cfg = ax.config
        decel = float(self.op["Deceleration"])
        jerk = float(self.op["Jerk"])
        if decel > cfg.max_deceleration:
            decel = cfg.max_deceleration
        if cfg.max_jerk > 0.0 and jerk > cfg.max_jerk:
            jerk = cfg.max_jerk
        return decel, jerk

    def check_gear_dynamics(self, ax: Axis) -> None:
        """Acceleration, Deceleration and Jerk of a gear's catch-up (MC_GearIn and the
        other synchronising blocks) within the slave's maxima: beyond one, ErrorID 13 on
        that operand, as for every motion command (:meth:`limits`)."""
        cfg = ax.config
        for name, maximum, what in (
            ("Acceleration", cfg.max_acceleration, "max_acceleration"),
            ("Deceleration", cfg.max_deceleration, "max_deceleration"),
            ("Jerk", cfg.max_jerk or math.inf, "max_jerk"),
        ):
            value = float(self.op[name])
            if value > maximum:
                raise self.out_of_range(
                    name, f"{name} {value:g} is beyond the slave's {what} {maximum:g}"
                )

    def parked_on(self) -> Process | None:
        """The running process of a block that only waits for its end (see
        :meth:`running`), where the type's scan, update, poll and publish are these (a
        block that shows more while it runs, InVelocity, InGear, InSync, parks only if
        it says when)."""
        return self.running() if _parks(type(self)) else None

    def running(self) -> Process | None:
        """The block's process while the block is Busy with it, not buffered, Execute
        steady; else None."""
        p = self.process
        if (
            p is None
            or p.state is not _ACTIVE
            or self.state is not _BUSY
            or self.pending is not None
            or not self.active
            or bool(self.inputs[self.TRIGGER]) != self._last_trigger
        ):
            return None
        return p

    def buffered(self) -> bool:
        """The block's command waits for the motion in progress (BufferMode Buffered):
        :meth:`begin` queues it; any other mode aborts that motion."""
        return int(self.op.get("BufferMode", BufferMode.ABORTING)) == BufferMode.BUFFERED

    def begin(self, ax: Axis, make: ProcessFactory) -> None:
        self.process = None
        self.pending = None
        if self.buffered():
            self.pending = self.ctl.buffer(ax, make, owner=self)
            self.process = self.pending.process
        else:
            self.process = self.ctl.start(ax, make, replace=None)
        self.fire(BlockEvent.START)
        self.active = self.process is not None

    def batch_started(self, process: Process) -> None:
        """For a block that queues in a scan's batch (``BATCH``) the command ``begin``
        starts in the aborting modes: the rest of ``begin`` once the batch started
        ``process``, and of the rising edge's scan."""
        self.process = process
        self.pending = None
        self.fire(BlockEvent.START)
        self.active = True
        self._publish()

    def batch_refused(self) -> None:
        """The kernel refused the queued command (its error set): ``begin`` would have
        left no process."""
        self.process = None
        self.pending = None
        self._publish()

    def poll(self) -> None:
        if self.process is None and self.pending is not None:
            if self.pending.cancelled:
                code, self.pending = self.pending.error_code, None
                if code:
                    self.fail(code)
                else:
                    self.fire(BlockEvent.ABORT)
                return
            self.process = self.pending.process
            if self.process is None:
                return
        p = self.process
        if p is None:
            return
        self.active = p.active
        if p.state == ProcessState.DONE and self.DONE_ON_FINISH:
            self.fire(BlockEvent.COMPLETE)
        elif p.state == ProcessState.ABORTED:
            self.fire(BlockEvent.ABORT)
        elif p.state == ProcessState.ERROR:
            self.fail(p.error_code)
