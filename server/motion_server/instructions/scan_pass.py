"""One scan pass over instruction instances, with the axis commands of a batch handed to
the kernel in one call per kind.

Scanned one by one, each MAJ or MAG that fires builds and starts its own kernel process:
128 MAJ in one scan are 128 ``Controller.start`` calls. Here the instances of a type that
can join a batch (:attr:`BatchKind`: MAJ -> jogs, MAM -> moves, MAG -> gears, MAPC ->
position cams, MAS and MC_Stop -> stops, MC_Halt -> halts, MC_MoveVelocity -> jogs that
abort every process, MC_MoveAbsolute and MC_MoveRelative -> moves that abort every
process, MC_GearIn -> gears that abort every process) and whose trigger rose are
latched, judged and checked one by one, as their own ``scan`` does, but their kernel
commands are queued; the queue goes to the kernel in one call per kind
(``Controller.start_jogs``, ``Controller.start_moves``, ``Controller.start_gears``,
``kernel.cam_batch.start_position_cams``, ``Controller.stop_many``) and then every
instance writes its status from the process it got.

The observable result is exactly that of scanning one by one (tested against it, every
output and the kernel's arrays after every cycle). That holds because a queued command
cannot change what a later instance of the same queue reads before the queue is handed
over:

- the queue holds one kind, in the instances' order; any other instance (another type,
  a trigger that did not rise, an instance that executes alone) first hands the queue
  over, so the kernel sees the commands in the order one-by-one scanning gives;
- an instance whose axis is already in the queue (a second MAJ on one axis, a MAG or
  MC_GearIn whose slave is a queued slave or master, whose master is a queued slave or
  reaches one through the master/slave links; a MAPC whose slave is a queued slave or
  master, or whose master reaches a queued slave) first hands the queue over: its
  checks then see the state the queued commands leave;
- the jogs (or moves) of one call share one :class:`~..kernel.Limits`: the queue is
  split where the limits change, keeping the order;
- an instance that decides to execute alone (a MAJ or MAM with Merge, master-driven or
  under a pending MDAC reassignment; a MAPC with a schedule other than Immediate, a master
  direction other than both ways, or a cam preloaded on its slave; a MAS that stops
  less than all motion, changes the jerk, has a homing to end or nothing moving; an
  MC_Stop with a jerk; an MC_Halt with a jerk or buffered; an MC_MoveVelocity buffered
  or in the current direction; an MC_MoveAbsolute or MC_MoveRelative buffered, an
  MC_MoveAbsolute in the current direction on a rotary axis) hands the queue over first
  and runs its own ``execute`` (a PLCopen block, its own ``scan``; an MC_GearIn
  buffered or with a jerk-limited catch-up).

A kernel call that raises (a plan refused on one axis) has started the axes before the
one refused, as the loop would: the instance refused shows the error (or, for an
unexpected exception, is contained as :class:`~.system.MotionSystem` contains one), and
the rest of the queue is handed over again.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence, Set
from enum import IntEnum
from typing import TYPE_CHECKING, Any

from ..kernel import (
    Axis,
    AxisState,
    AxisType,
    ErrorCode,
    Limits,
    MotionError,
    PowerEvent,
    ProcessKind,
)
from ..kernel.cam_batch import start_position_cams
from ..kernel.power import TRANSITIONS
from ..kernel.processes import Process
from .base import Instruction, LogixInstruction, OperandError, PLCopenBlock
from .judging import judge_of

if TYPE_CHECKING:
    from ..kernel import Controller

#: what a scan pass calls when an instance raised an unexpected exception (None: raise)
Contain = Callable[[Instruction, Exception], None]


#: the power states in which the kernel takes a motion command (``require_motion``),
#: read from its table
_MOVABLE = tuple(
    s for s in AxisState if isinstance(TRANSITIONS.get((s, PowerEvent.MOTION)), AxisState)
)
_FEEDBACK_ONLY = AxisType.FEEDBACK_ONLY


def takes_motion(ax: Axis) -> bool:
    """True if ``Controller.require_motion(ax)`` passes (a state that takes motion, not
    feedback only, not faulted), without its walk of the power table with enum keys
    (about 1 µs). False: call it, for the kernel's own error."""
    return ax.type is not _FEEDBACK_ONLY and ax.state in _MOVABLE and not ax.fault


class BatchKind(IntEnum):
    """The kernel batch an instruction type's commands join."""

    JOG = 0
    GEAR = 1
    POSITION_CAM = 2
    STOP = 3
    HALT = 4
    #: jogs that replace every process (MC_MoveVelocity, aborting)
    VELOCITY = 5
    #: moves that replace a move (MAM without Merge)
    MOVE = 6
    #: moves that replace every process (MC_MoveAbsolute, MC_MoveRelative, aborting)
    ABORTING_MOVE = 7
    #: gears that replace every process (MC_GearIn, aborting)
    GEAR_IN = 8


#: the process kind each batch starts (how a refused batch finds what it started)
_PROCESS_KIND: dict[BatchKind, ProcessKind] = {
    BatchKind.JOG: ProcessKind.JOG,
    BatchKind.GEAR: ProcessKind.GEAR,
    BatchKind.POSITION_CAM: ProcessKind.POSITION_CAM,
    BatchKind.STOP: ProcessKind.STOP,
    BatchKind.HALT: ProcessKind.STOP,
    BatchKind.VELOCITY: ProcessKind.JOG,
    BatchKind.MOVE: ProcessKind.MOVE,
    BatchKind.ABORTING_MOVE: ProcessKind.MOVE,
    BatchKind.GEAR_IN: ProcessKind.GEAR,
}
_NO_STATUS: dict[str, Any] = {}
#: the processes a new gear supersedes (MAG), a new move (MAM)
_REPLACE_GEAR = (ProcessKind.GEAR,)
_REPLACE_MOVE = (ProcessKind.MOVE,)
#: the kinds whose jobs carry their limits third: one kernel call per run of equal limits
_BY_LIMITS = frozenset((BatchKind.JOG, BatchKind.VELOCITY, BatchKind.MOVE, BatchKind.ABORTING_MOVE))


class Batch:
    """The queued kernel commands of one kind, in the instances' order.

    ``jobs[k]`` is the command of ``owners[k]``: for jogs ``(axis, signed target,
    limits)``, for moves ``(axis, distance, limits, landing)``, for gears ``(slave,
    term, clutch rate, MC_GearIn's (acceleration, deceleration) or None, direction)``,
    for position cams a
    :class:`~..kernel.cam_batch.CamStart` (its slave first). ``axes`` holds every axis
    number a queued command touches, ``slaves`` the axes it starts a process on.
    """

    __slots__ = (
        "axes", "contain", "ctl", "jobs", "kind", "owners", "plans", "slaves", "stopping",
    )  # fmt: skip

    def __init__(self, ctl: Controller, contain: Contain | None) -> None:
        self.ctl = ctl
        self.contain = contain
        self.kind: BatchKind | None = None
        self.jobs: list[tuple[Any, ...]] = []
        self.owners: list[BatchInstruction] = []
        self.axes: set[int] = set()
        self.slaves: set[int] = set()
        #: what the instances of this scan pass planned from their values alone, by the
        #: judge's key and what else the plan reads (the axis's limits): equal operands
        #: on equal axes are planned once
        self.plans: dict[tuple[Any, ...], Any] = {}
        #: group number -> a group stop is in progress (``Controller.group_stopping``),
        #: known until the queue is handed over (only commands outside a batch stop
        #: groups, and they hand it over first)
        self.stopping: dict[int, bool] = {}

    def before_axis(self, number: int) -> None:
        """A command on axis ``number`` is about to be checked: if a queued one touches
        that axis, the queue is handed over first, so that the checks see it (a second
        command on one axis in a scan)."""
        if number in self.axes:
            self.flush()

    def reaching(self, master: int, slave: int) -> tuple[bool, bool]:
        """(a gear or cam of ``slave`` on ``master`` closes a loop, ``master`` is a slave
        queued here or follows one): :func:`walk_masters` over the queued slaves."""
        return walk_masters(self.ctl, master, slave, self.slaves if self.jobs else _NONE)

    def add(
        self, kind: BatchKind, owner: BatchInstruction, job: tuple[Any, ...], axes: Iterable[int]
    ) -> None:
        if self.kind is not kind:
            self.flush()
            self.kind = kind
        self.jobs.append(job)
        self.owners.append(owner)
        self.slaves.add(job[0].number)
        self.axes.update(axes)

    def flush(self) -> None:
        """Hand the queued commands over to the kernel and write every owner's status."""
        self.stopping.clear()  # (also with nothing queued: an instance may have asked)
        if not self.jobs:
            return
        kind, jobs, owners = self.kind, self.jobs, self.owners
        self.jobs, self.owners = [], []
        self.axes.clear()
        self.slaves.clear()
        if kind in _BY_LIMITS:
            # one call per run of equal limits, in order
            start = 0
            for k in range(1, len(jobs) + 1):
                if k == len(jobs) or jobs[k][2] != jobs[start][2]:
                    self._hand_over(kind, jobs[start:k], owners[start:k])
                    start = k
        else:
            assert kind is not None
            self._hand_over(kind, jobs, owners)

    def _hand_over(
        self,
        kind: BatchKind,
        jobs: Sequence[tuple[Any, ...]],
        owners: Sequence[BatchInstruction],
    ) -> None:
        while jobs:
            ctl = self.ctl
            axes = [job[0] for job in jobs]
            before = [owner.process for owner in owners]
            started: Sequence[Process]
            try:
                if kind is BatchKind.JOG:
                    limits: Limits = jobs[0][2]
                    started = ctl.start_jogs(axes, [job[1] for job in jobs], limits, owners)
                elif kind is BatchKind.VELOCITY:
                    targets = [job[1] for job in jobs]
                    started = ctl.start_jogs(axes, targets, jobs[0][2], owners, replace=None)
                elif kind is BatchKind.MOVE or kind is BatchKind.ABORTING_MOVE:
                    distances = [job[1] for job in jobs]
                    landings = [job[3] for job in jobs]
                    replace = None if kind is BatchKind.ABORTING_MOVE else _REPLACE_MOVE
                    started = ctl.start_moves(
                        axes, distances, jobs[0][2], owners, landings, replace
                    )
                elif kind is BatchKind.POSITION_CAM:
                    started = start_position_cams(ctl, jobs)  # type: ignore[arg-type]
                elif kind is BatchKind.STOP:
                    started = ctl.stop_many(axes, [job[1] for job in jobs], owners)
                elif kind is BatchKind.HALT:
                    started = ctl.stop_many(axes, [job[1] for job in jobs], owners, halt=True)
                else:
                    started = ctl.start_gears(
                        axes,
                        [job[1] for job in jobs],
                        [job[2] for job in jobs],
                        owners,
                        [job[3] for job in jobs],
                        None if kind is BatchKind.GEAR_IN else _REPLACE_GEAR,
                    )
            except Exception as exc:
                # the axes before the refused one started, as in the loop
                k = _started_count(axes, owners, before, _PROCESS_KIND[kind])
                for i in range(k):
                    self._started(owners[i], _new_process(axes[i], owners[i], before[i], kind))
                refused = owners[k]
                if isinstance(exc, MotionError):
                    refused.fail(exc.code)
                    refused.batch_refused()
                else:
                    refused.batch_refused()
                    if getattr(refused, "_rising", False):
                        refused._write_status(_NO_STATUS)
                    if self.contain is None:
                        raise
                    self.contain(refused, exc)
                jobs, owners = jobs[k + 1 :], owners[k + 1 :]
                continue
            for owner, p in zip(owners, started, strict=True):
                self._started(owner, p)
            return

    def _started(self, owner: BatchInstruction, process: Process) -> None:
        """``owner.batch_started(process)``, an unexpected exception in it contained as
        the one-by-one scan contains it (the others' status is still written)."""
        try:
            owner.batch_started(process)
        except Exception as exc:
            if owner._rising:
                owner._write_status(_NO_STATUS)
            if self.contain is None:
                raise
            self.contain(owner, exc)


def walk_masters(ctl: Controller, master: int, slave: int, queued: Set[int]) -> tuple[bool, bool]:
    """(a gear of ``slave`` to ``master`` closes a loop, ``master`` is one of ``queued``
    or follows one of them) through the active processes' masters: the walk of
    ``Controller.would_cycle``, which a gear queued on such a slave would change."""
    frontier = [master]
    seen: set[int] = set()
    loops = reaches = False
    while frontier:
        n = frontier.pop()
        if n == slave:
            loops = True
        if n in queued:
            reaches = True
        if loops and (reaches or not queued):
            break
        if n in seen:
            continue
        seen.add(n)
        try:
            ax = ctl.axis(n)
        except MotionError:
            continue
        for p in ax.processes:
            if p.active:
                frontier.extend(p.masters)
    return loops, reaches


_NONE: frozenset[int] = frozenset()


def _new_process(ax: Axis, owner: object, before: Process | None, kind: BatchKind) -> Process:
    """The process of ``kind`` that ``owner`` started on ``ax`` in a refused batch."""
    pk = _PROCESS_KIND[kind]
    for p in ax.processes:
        if p.owner is owner and p.kind == pk and p is not before and _started(p):
            return p
    raise LookupError(f"no {pk.name} of {owner!r} on {ax.name}")


def _started_count(
    axes: Sequence[Axis], owners: Sequence[object], before: Sequence[Any], kind: ProcessKind
) -> int:
    """How many of a refused batch's commands started: the first axis without a new
    active process of ``kind`` owned by its instance is the one refused."""
    for k, ax in enumerate(axes):
        owner, old = owners[k], before[k]
        if not any(
            p.owner is owner and p.kind == kind and p is not old and _started(p)
            for p in ax.processes
        ):
            return k
    raise LookupError("a batch raised but every command in it started")


def _started(p: Process) -> bool:
    """``p``, found on its axis after a batch raised, is one the batch started: active,
    or a stop ramp (one from rest is done at once; it stays until the next step)."""
    return p.active or p.kind == ProcessKind.STOP


class BatchInstruction(LogixInstruction):
    """A Logix process instruction whose rising edge can join a kernel batch.

    ``batch_job`` does what ``execute`` does up to the kernel command and returns that
    command instead (or None: the instance executes alone); ``batch_started`` follows the
    process the batch started, ``batch_refused`` undoes what a refused start leaves.
    """

    BATCH: BatchKind
    process: Process | None

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """The queued command and the axis numbers it touches, or None; ``key`` is the
        judge's key of the latched values (None: no key), by which ``batch.plans`` may
        keep what depends only on them."""
        raise NotImplementedError

    def batch_started(self, process: Process) -> None:
        raise NotImplementedError

    def batch_refused(self) -> None:
        """The kernel refused this instance's queued command: what is left to do once
        its error shows (a kernel error; an unexpected one: before it is contained)."""


def scan_pass(
    instances: Iterable[Instruction], contain: Contain | None = None, batch: bool = True
) -> None:
    """Scan ``instances`` in order (``Instruction.scan``), the rising edges of batch
    types queued and handed to the kernel together (see the module docstring).
    ``contain(inst, exc)`` takes an instance's unexpected exception (None: it is
    raised); ``batch=False`` scans every instance alone (the reference)."""
    queue: Batch | None = None
    kinds = _KINDS
    for inst in instances:
        cls = type(inst)
        kind = kinds.get(cls, _UNKNOWN) if batch else None
        if kind is _UNKNOWN:
            kind = kinds[cls] = _kind_of(cls)
        if kind is None or inst._last_trigger or not inst.inputs[inst.TRIGGER]:
            if queue is not None:
                queue.flush()
            try:
                inst.scan()
            except Exception as exc:
                if contain is None:
                    raise
                contain(inst, exc)
            continue
        if queue is None:
            queue = Batch(inst.ctl, contain)
        elif queue.kind is not kind:
            queue.flush()  # the other kind's commands first, before this one's checks
        if isinstance(inst, LogixInstruction):
            _rise(inst, kind, queue)  # type: ignore[arg-type]
        else:
            _rise_block(inst, kind, queue)  # type: ignore[arg-type]
    if queue is not None:
        queue.flush()


#: the batch kind of each instruction type seen (None: scanned alone)
_KINDS: dict[type[Instruction], Any] = {}
_UNKNOWN = object()


def _kind_of(cls: type[Instruction]) -> BatchKind | None:
    """``cls.BATCH`` if the ``batch_job`` the type has stands for the ``execute`` it has,
    and it scans as :class:`LogixInstruction` does, or, a PLCopen block, as
    :class:`PLCopenBlock` does or as the class that wrote its ``batch_job`` says (a
    subclass that changes any of them is scanned alone)."""
    kind = getattr(cls, "BATCH", None)
    if kind is None or cls.validate is not Instruction.validate:
        return None
    owners = {name: _defined_by(cls, name) for name in ("batch_job", "execute", "scan")}
    if owners["batch_job"] is not owners["execute"]:
        return None
    if issubclass(cls, LogixInstruction):
        return kind if cls.scan is LogixInstruction.scan else None
    if issubclass(cls, PLCopenBlock) and owners["scan"] in (PLCopenBlock, owners["batch_job"]):
        return kind
    return None


def _defined_by(cls: type, name: str) -> type | None:
    for base in cls.__mro__:
        if name in vars(base):
            return base
    return None


def _rise_block(inst: Instruction, kind: BatchKind, queue: Batch) -> None:
    """The rising edge of a PLCopen block (``PLCopenBlock.scan``), its command queued
    when ``batch_job`` plans one. Anything else (a verdict against an operand, a
    command the block executes alone or the kernel refuses at once) is the block's own
    scan, after the queue is handed over: it judges, executes and fails as it always
    does. A queued block writes its status once its command started
    (``batch_started``)."""
    block: Any = inst
    block.latch()
    try:
        key = judge_of(type(inst)).judge(inst)
        planned = block.batch_job(queue, key)
    except Exception:
        planned = None  # (judged again, and shown, by the scan below)
    if planned is None:
        queue.flush()
        try:
            inst.scan()
        except Exception as exc:
            if queue.contain is None:
                raise
            queue.contain(inst, exc)
        return
    # PLCopenBlock.scan's rising edge, up to the execution
    block._last_trigger = True
    block.outputs["ErrorID"] = 0
    block.on_restart()
    block.latch()
    job, axes = planned
    queue.add(kind, block, job, axes)


def _rise(inst: BatchInstruction, kind: BatchKind, queue: Batch) -> None:
    """The rising edge of ``inst`` (``LogixInstruction.scan``), its command queued."""
    inst._last_trigger = True
    inst._rising = True
    inst.latch()
    try:
        key = judge_of(type(inst)).judge(inst)  # (Instruction.validate, keeping the key)
        planned = inst.batch_job(queue, key)
        if planned is not None:
            job, axes = planned
            queue.add(kind, inst, job, axes)
            return
        queue.flush()
        inst.execute()
    except OperandError as exc:
        idx = exc.index + (1 if exc.index >= inst.MOTION_CONTROL_INDEX else 0)
        inst.fail(exc.code, idx if exc.code == ErrorCode.PARAMETER_OUT_OF_RANGE else 0)
    except MotionError as exc:
        inst.fail(exc.code)
    except Exception as exc:
        if inst._rising:
            inst._write_status(_NO_STATUS)
        queue.flush()  # the commands before it went to the kernel before it raised
        if queue.contain is None:
            raise
        queue.contain(inst, exc)
        return
    if inst._rising:
        inst._write_status(_NO_STATUS)
