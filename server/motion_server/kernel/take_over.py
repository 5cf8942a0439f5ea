"""A batch start on an axis already moving: ``Motion.start`` when the new process
replaces the axis's one process, without the calls.

MAJ on a jogging axis (a new speed) and MC_MoveAbsolute on a jogging axis (the aborting
mode) replace the one process of each axis. :func:`sole_replaced` says whether an axis is
that simple; :func:`take_over` then does what ``Motion.start`` does before the new
process joins its axis: settle the old process (out of its lane), build the new one from
the old one's velocity and acceleration (if that raises, nothing else has changed, as in
``Motion.start``), abort the old one as ``Process.abort`` does and fold its displacement
into the axis's base. The caller adds the new process to the list returned: its batch's
admission to a lane, or :func:`join`, the rest of ``Motion.start``.

An old process in a time-driven lane (a jog at speed, a ramp) leaves it with
``Lane.pass_on``: the followers that read the axis keep their level when the new process
joins a time-driven lane too, which the batches' processes do. When it does not join one,
the caller marks the lanes returned ``dirty``, as an eviction would have.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from typing import Any, Generic, TypeVar

from .axis import Axis
from .enums import AbortReason, ProcessKind, ProcessState
from .lanes import GroupLanes
from .motion import Motion
from .override import NEUTRAL
from .processes import Process

_ACTIVE = ProcessState.ACTIVE
_ABORTED = ProcessState.ABORTED
_abort = Process.abort

#: the new process's class, and what its builder returns besides it (a batch's prototype)
P = TypeVar("P", bound=Process)
T = TypeVar("T")


def same_bits(x: float, y: float) -> bool:
    """``x`` and ``y`` have the same bits (finite or infinite; zeros by their sign): a
    batch's new processes built from them are alike."""
    return x == y and (x != 0.0 or math.copysign(1.0, x) == math.copysign(1.0, y))


class LastStart(Generic[T]):
    """The start a batch built last from motion: its target or distance (the object),
    period, velocity and acceleration, and its prototype. The usual batch (one target
    object for every axis, every axis at the same speed) finds the next axis's here."""

    __slots__ = ("a", "period", "proto", "v", "what")

    def __init__(self) -> None:
        self.proto: T | None = None
        self.what: object = None
        self.period = self.v = self.a = 0.0

    def get(self, what: object, period: float, v: float, a: float) -> T | None:
        """The prototype kept, if it was built from these."""
        proto = self.proto
        if (
            proto is not None
            and self.what is what
            and self.period == period
            and same_bits(v, self.v)
            and same_bits(a, self.a)
        ):
            return proto
        return None

    def keep(self, what: object, period: float, v: float, a: float, proto: T) -> None:
        self.what, self.period, self.v, self.a, self.proto = what, period, v, a, proto


def sole_replaced(
    ax: Axis, procs: list[Process], replace: Collection[ProcessKind] | None
) -> Process | None:
    """The one process of ``ax`` (``procs``, its processes) that a start replacing
    ``replace`` (None: every kind) supersedes, if the axis is that simple: one active
    process of a kind replaced, aborting as ``Process.abort`` does; no override, no
    preloaded cam, nothing buffered. Else None."""
    if len(procs) != 1 or ax.preloaded_cams or ax.buffered is not None:
        return None
    if ax.override is not NEUTRAL and not ax.override.neutral:
        return None
    q = procs[0]
    if q.state is not _ACTIVE or type(q).abort is not _abort:
        return None
    if replace is not None and q.kind not in replace:
        return None
    return q


def take_over(
    motion: Motion,
    ax: Axis,
    q: Process,
    build: Callable[[float, float], tuple[P, T]],
) -> tuple[P, T, list[Process], GroupLanes | None]:
    """``Motion.start`` on ``ax`` up to the new process's joining, ``q`` its one process
    (:func:`sole_replaced`): the new process built by ``build(v, a)`` from ``q``'s
    velocity and acceleration (summed as ``Motion.start`` sums them), with what ``build``
    returns besides it, the axis's new, empty process list, and the lanes to mark
    ``dirty`` if the new process does not join a time-driven lane (None: nothing to
    mark)."""
    lanes: GroupLanes | None = None
    lane: Any = q.lane
    if lane is not None:
        if lane.RELEVELS:
            lane.evict(q)
        else:
            lane.pass_on(q)
            lanes = motion.lanes[ax.group]
    try:
        p, extra = build(0.0 + q.velocity, 0.0 + q.acceleration)
    except BaseException:
        # (refused: ``q`` runs on, composed in Python, as after ``Motion.settle``)
        if lanes is not None:
            lanes.dirty = True
        raise
    q.state = _ABORTED
    q.abort_reason = AbortReason.SUPERSEDED
    ax.base += q.position
    if q.masters and q.masters != p.masters:
        # (a successor reading the same masters, a gear at a new ratio, leaves the
        # composition order as valid as it was)
        motion.coupling_changed()
    new: list[Process] = []
    ax._processes = new
    return p, extra, new, lanes


def join(motion: Motion, ax: Axis, new: list[Process], p: Process) -> None:
    """The rest of ``Motion.start`` once :func:`take_over` built ``p`` on ``ax`` (``new``
    the list it returned): ``p`` becomes the axis's process, and is offered to the
    lanes."""
    new.append(p)
    if p.masters:
        motion.coupling_changed()
    ax.motion_changed()
    motion.offer(ax)
