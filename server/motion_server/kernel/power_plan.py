"""Group power-offs planned as arrays: every axis of a group off at once.

A group stop in Hard Disable or Hard Shutdown of a group whose axes are all in Servo
Control, or a fast disable's last step once the ramps settled, switches every axis off:
each axis's processes end (``Motion.abort``), its after-stop action and latch are dropped
and its drive goes off. :func:`power_off_axes` does it for a batch of axes: the lanes are
written back lane by lane, each axis's processes ended and its power state changed
inline, in axis order (a shutdown releases its axis's followers before the next axis, as
axis by axis); a group of lane members, or of axes at rest, without per-axis bookkeeping
at all (:func:`_power_off_members`, the followers' release worked out as arrays).

The result is bit-identical to the reference path (tested side by side in
``tests/unit/test_stop_plan.py``); the helpers shared with the group stop's ramps are in
:mod:`.stop_plan`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import repeat
from operator import attrgetter, itemgetter

import numpy as np

from .axis import Axis
from .enums import AbortReason, AfterStop, AxisState, ProcessState
from .lanes.base import Lane
from .motion import Motion
from .power import ABORT_REASON, PowerEvent
from .processes import Process
from .stop_plan import (
    abort_all,
    clear_emptied,
    empty_lanes,
    idle,
    members_of,
    refused,
    retire_order,
    stepped_lanes,
)

_ACTIVE = ProcessState.ACTIVE
_ABORTED = ProcessState.ABORTED
_abort = Process.abort
_index = attrgetter("index")
_masters = attrgetter("masters")
_first = itemgetter(0)
_own_processes = attrgetter("_processes")
_rows_and_buffered = attrgetter("stop_rows", "buffered")
_NEITHER = (None, None)
_stop_rows = attrgetter("stop_rows")
_preloaded = attrgetter("preloaded_cams")


def power_off_axes(
    motion: Motion,
    axes: Sequence[Axis],
    state: AxisState,
    event: PowerEvent,
    switched: Callable[[], None],
    after: Callable[[Axis], None] | None = None,
    releasing: bool = False,
    prepare: Callable[[], None] | None = None,
    maxima: tuple[np.ndarray, np.ndarray] | None = None,
    idx: np.ndarray | None = None,
) -> None:
    """Take ``axes`` (of one group, all in Servo Control) to ``state`` (Axis Ready,
    Axis Shutdown) by ``event`` (SERVO_OFF, SHUTDOWN), as :meth:`Power.fire
    <.power.Power.fire>` does axis by axis (a group stop's Hard Disable and Hard
    Shutdown): every process ends at once (:meth:`Motion.abort <.motion.Motion.abort>`
    with the event's abort reason), the after-stop action and the latch are dropped,
    the drive goes off (``switched``: the drive model's). The lanes are written back
    lane by lane, the processes' bookkeeping is inline. ``after(ax)`` runs after each
    axis (a shutdown releases the axis's followers there, before the next axis;
    ``releasing``: that is all ``after`` does, ``Motion.release_followers``).
    ``prepare()`` runs before the first axis when they are taken one by one (what
    ``after`` needs, found before anything changes). ``maxima``: the axes' maximum
    decelerations and velocities, ``idx`` their array indices, if the caller has them."""
    if not axes:
        return
    reason = ABORT_REASON[event]
    if (after is None or releasing) and _power_off_members(
        motion, axes, state, event, reason, switched, releasing, maxima, idx
    ):
        return
    if prepare is not None:
        prepare()
    lanes, emptied = empty_lanes(motion, axes)
    s = motion.s
    busy = s.scalars.busy
    dirty = s.dirty
    drive_on = s.drive_on
    code = int(event)
    coupling = False
    for ax in axes:
        procs = ax.processes
        for p in procs:
            lane = p.lane
            if lane is not None:
                lane.evict(p)
        for p in ax.preloaded_cams:
            lane = p.lane
            if lane is not None:
                lane.evict(p)
        ax.power_event = code
        # Motion.abort: Motion.retire of every process
        abort_all(ax, procs, reason)
        if procs:
            keep = [p for p in procs if p.state is _ACTIVE]
            if len(keep) != len(procs):
                ax.processes = keep
                coupling = True
        i = ax.index
        busy[i] = any(p.state is _ACTIVE for p in ax.processes)
        dirty.add(i)
        if ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        ax.stop_latch = None
        # Power._enter
        ax.after_stop = AfterStop.NOTHING
        ax.state = state
        if drive_on.item(i):
            switched()
        drive_on[i] = False
        if after is not None:
            after(ax)
    clear_emptied(lanes, emptied)
    if coupling:
        motion.coupling_changed()


def _power_off_members(
    motion: Motion,
    axes: Sequence[Axis],
    state: AxisState,
    event: PowerEvent,
    reason: AbortReason,
    switched: Callable[[], None],
    releasing: bool = False,
    maxima: tuple[np.ndarray, np.ndarray] | None = None,
    idx: np.ndarray | None = None,
) -> bool:
    """:func:`power_off_axes` without ``after`` (or, ``releasing``, with the shutdown's
    release of each axis's followers), when every axis either has no motion at
    all (at rest after a fast disable's ramp) or one process that is a lane member the
    last step composed (a Hard Disable of moving axes): the members are written back
    at once and aborted, the base of an axis with one is its command (as in
    :func:`_stop_members`), and the axes' power state, latch and after-stop action are
    set with their status arrays written once for all. False (nothing changed) when the
    batch is not that simple.

    A shutdown releases the followers of each axis before the next (``releasing``):
    a follower after its master in the batch has its process aborted there (the same
    reason), folded into its base, and, its drive on and its velocity not zero, a stop
    ramp from that velocity, which its own shutdown then aborts where it started (its
    base plus 0.0); a follower before its master is shut down before the release finds
    anything. So with every process reading one master, nothing outside the batch in
    motion and no such ramp refused (then axis by axis raises), the result is the
    batch's with 0.0 added to the bases of the followers that had a ramp."""
    lanes = motion.lanes[axes[0].group]
    n = len(axes)
    stepped = stepped_lanes(lanes)
    if stepped is None:
        return False
    found, total = stepped
    # (another stop's rows may still ramp other axes: an axis of the batch with a row,
    # or with its ramp made from one, is refused below)
    if idx is None:
        idx = np.fromiter(map(_index, axes), dtype=np.intp, count=n)
    whole = n == len(lanes.group.axes)
    if found and not members_of(motion, found, idx, whole):
        return False
    # the members, one process each, are all the processes of the batch; nothing else
    # is on its axes (no ramp still a row, nothing buffered, no cam preloaded)
    if (
        sum(map(len, map(_own_processes, axes))) != total
        or list(map(_rows_and_buffered, axes)).count(_NEITHER) != n
        or any(map(_preloaded, axes))
    ):
        return False
    s = motion.s
    ramped = _released_with_ramp(motion, found, axes, idx, maxima) if releasing else None
    if releasing and ramped is None:
        return False
    for lane in found:
        lane.evict_all((_ABORTED, reason))
        # Motion.abort folds the aborted process into the base: base + position, which
        # is the command composition wrote (see _stop_members)
        bases = s.cmd_pos[lane.idx]
        if ramped is not None and ramped.any():
            bases = np.where(ramped[lane.idx], bases + 0.0, bases)
        for ax, b in zip(lane.axes, bases.tolist(), strict=True):
            ax.base = b
            ax._processes = []
    clear_emptied(lanes, found)
    code = int(event)
    nothing = AfterStop.NOTHING
    for ax in axes:
        ax.power_event = code
        ax._stop_latch = None
        ax._after_stop = nothing
        ax._state = state
    s.busy[idx] = False
    s.axis_state[idx] = int(state)
    s.after_stop[idx] = int(nothing)
    s.state_changes += n
    s.dirty.update(idx.tolist())
    drive_on = s.drive_on
    for _ in range(int(np.count_nonzero(drive_on[idx]))):
        switched()  # (once per drive switched off, as axis by axis)
    drive_on[idx] = False
    if total:
        # (the batch the whole group: none of its axes has a process or a row left)
        retire_order(motion, lanes, whole or idle(lanes.group.axes))
    return True


def _released_with_ramp(
    motion: Motion,
    found: list[Lane],
    axes: Sequence[Axis],
    idx: np.ndarray,
    maxima: tuple[np.ndarray, np.ndarray] | None,
) -> np.ndarray | None:
    """For a shutdown of ``axes`` (array indices ``idx``) whose processes are the
    members of ``found``: a mask over the controller's axes of the followers its
    release gives a stop ramp (see :func:`_power_off_members`); None when the batch
    is not that simple. ``maxima``: the axes' maximum decelerations (and velocities),
    if the caller has them."""
    s = motion.s
    n_all = len(s.busy)
    if len(axes) != n_all:
        outside = np.ones(n_all, dtype=bool)
        outside[idx] = False
        others = [motion.axes[i] for i in np.flatnonzero(outside).tolist()]
        if any(map(_own_processes, others)) or list(map(_stop_rows, others)).count(None) != len(
            others
        ):
            return None  # a process outside the batch may read one of its axes
    order = np.full(n_all, -1, dtype=np.intp)
    order[idx] = np.arange(len(axes))
    ramped = np.zeros(n_all, dtype=bool)
    # axis number -> array index: the state's own table, read for the masters alone
    index_of = s._index.get
    for lane in found:
        masters = list(map(_masters, lane.members))
        counts = list(map(len, masters))
        if counts.count(0) == len(counts):
            continue
        if max(counts) > 1:
            return None  # a process reading two masters: released as a whole, one by one
        reads = np.fromiter(map(bool, counts), dtype=bool, count=len(counts))
        wanted = list(map(_first, filter(None, masters)))
        m = np.fromiter(map(index_of, wanted, repeat(-1)), dtype=np.intp, count=len(wanted))
        slaves = lane.idx[reads]
        if (m < 0).any() or (m == slaves).any():
            return None
        # released by its master's shutdown, before its own
        released = (order[m] >= 0) & (order[m] < order[slaves])
        ramped[slaves[released]] = True
    # the release ramps the velocity it sums (0 + velocity: the command's), the drive on
    i = np.flatnonzero(ramped)
    v = 0.0 + s.cmd_vel[i]
    ramped[i] = s.drive_on[i] & (v != 0.0)
    i = np.flatnonzero(ramped)
    if i.size:
        if maxima is None:
            dec = np.array([motion.axes[k].config.max_deceleration for k in i.tolist()])
        else:
            dec = maxima[0][order[i]]
        if refused(s.cmd_vel[i] + 0.0, dec, dec):
            return None  # a ramp the release would refuse: axis by axis raises
    return ramped
