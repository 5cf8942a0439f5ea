"""Group stops planned as arrays: the stop ramps of many axes in one pass.

A group stop (MGS in every mode that ramps, leaving run mode) replaces every process of
every axis of the group by one trapezoidal :class:`~.processes.StopRamp` from the summed
velocity of what it replaces, at the axis's maximum deceleration (steeper from beyond the
Maximum Speed: :func:`.limits.group_stop_deceleration`). Done axis by axis
(:meth:`Controller.stop <.controller.Controller.stop>` through :meth:`Motion.start
<.motion.Motion.start>`) that costs some 90 Python calls per axis, most of them
bookkeeping that is the same for every axis. :func:`stop_axes` does the same work for a
batch of axes:

1. every process in a fast lane is written back into its object (lane by lane), and the
   velocity and acceleration of each axis's active processes are summed, in the order
   :meth:`Motion.start` sums them;
2. the decelerations and the checks a ramp's constructor makes (``Limits.validated``,
   :func:`.trapezoid.judge_ramp`) are computed for all axes at once, with the very same
   floating-point operations; if any axis would be refused, nothing has changed (the
   evictions of step 1 move nothing) and the caller takes the reference path, which
   raises exactly where it always did;
3. each axis's processes are aborted and folded into its base in order, and its ramp is
   built from a template (the attributes the constructor sets, :func:`ramp`);
4. the ramps join the group's :class:`~.lanes.ramps.StopLane` as one batch, their lane
   state already in arrays, so the next rebuild loads no member one by one.

The usual batch is simpler still (:func:`_member_lanes`, :func:`_stop_members`): every
axis has one process, a lane member the last step composed. Then the controller's
arrays already hold the sums and the fold (composition writes ``cmd_pos = base +
position``, ``cmd_vel = velocity``, ``cmd_acc = acceleration`` for one process, the
lanes the same bit for bit), so no process is read for them: the members are written
back and aborted lane by lane, the lanes the stop empties are cleared at once
(``Lane.clear``), and the composition order is kept when no axis reads a master any
more (:func:`retire_order`).

A group stop in Hard Disable or Hard Shutdown switches the axes off the same way
(:mod:`.power_plan`), with the helpers kept here: the lanes emptied at once
(:func:`empty_lanes`, :func:`clear_emptied`), the members' abort judged in C-level passes
(:func:`plain_and_active`), the ramps' judgement (:func:`refused`) and the composition
order (:func:`retire_order`).

The result is bit-identical to the reference path: the same process objects in the same
states, the same axis bases, status arrays and lane membership (tested side by side in
``tests/unit/test_stop_plan.py``). ``Controller(lanes=False)`` keeps the reference path.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from operator import attrgetter

import numpy as np

from .axis import Axis
from .cams import CamProcess
from .enums import AbortReason, ProcessState
from .lanes import GroupLanes
from .lanes.base import Lane
from .lanes.stop_rows import StopRows
from .limits import Limits
from .motion import Motion
from .processes import Process, StopRamp
from .state import Index, compact
from .trapezoid import MAX_DURATION, TrapezoidProfile

_ACTIVE = ProcessState.ACTIVE
_DONE = ProcessState.DONE
_NO_ABORT = AbortReason.NONE
_ABORTED = ProcessState.ABORTED
_abort = Process.abort
_cam_abort = CamProcess.abort

_set = object.__setattr__  # Limits is a frozen dataclass
_state = attrgetter("state")
_own_processes = attrgetter("_processes")
_stop_rows = attrgetter("stop_rows")
_preloaded = attrgetter("preloaded_cams")
_max_deceleration = attrgetter("config.max_deceleration")
_max_velocity = attrgetter("config.max_velocity")


def _column(get: Callable[[object], float], objects: Sequence[object]) -> np.ndarray:
    """``get`` of each of ``objects`` as a float array (no Python call per object)."""
    return np.fromiter(map(get, objects), dtype=float, count=len(objects))


def ramp(
    dt: float,
    deceleration: float,
    velocity: float,
    owner: object,
    limits: Limits | None = None,
    stopping: bool = True,
) -> StopRamp:
    """``StopRamp(dt, deceleration, 0.0, velocity, acceleration, owner, stopping)`` for
    arguments its constructor accepts (checked by the caller), without the constructor's
    calls: the same attributes with the same values (``limits``: equal limits to share,
    if the caller has them). A ramp from rest with no acceleration to inherit is done at
    once: the caller finishes it."""
    if limits is None:
        limits = Limits.__new__(Limits)
        _set(limits, "velocity", max(abs(velocity), 1e-9) * 2.0)
        _set(limits, "acceleration", deceleration)
        _set(limits, "deceleration", deceleration)
        _set(limits, "jerk", 0.0)
    prof = TrapezoidProfile.__new__(TrapezoidProfile)
    prof._dt = dt
    prof.position = 0.0
    prof.velocity = float(velocity)
    prof.acceleration = 0.0
    prof.finished = False
    prof.cycles = 0
    prof.plan = None
    prof._target_position = None
    prof._target_velocity = 0.0
    r = StopRamp.__new__(StopRamp)
    r.owner = owner
    r.state = _ACTIVE
    r.abort_reason = _NO_ABORT
    r.error_code = 0
    r.position = 0.0
    r.velocity = velocity
    r.acceleration = 0.0
    r.stopping = stopping
    r.landing = None
    r.limits = limits
    r.profile = prof
    return r


def empty_lanes(motion: Motion, axes: Sequence[Axis]) -> tuple[GroupLanes, list[Lane]]:
    """Evict, lane by lane, every lane of the axes' group whose processes are all on
    ``axes`` (the others' members leave one by one as their axes are settled); the
    group's lanes, and the lanes emptied (see :func:`clear_emptied`)."""
    lanes = motion.lanes[axes[0].group]
    emptied: list[Lane] = []
    if len(lanes):
        batch = {ax.index for ax in axes}
        for whole in lanes.all:
            if len(whole) and whole.within(batch):
                whole.evict_all()
                emptied.append(whole)
    return lanes, emptied


def clear_emptied(lanes: GroupLanes, emptied: list[Lane]) -> None:
    """Once every process of the batch has ended: clear the lanes :func:`empty_lanes`
    emptied, unless a process joined one since (a follower released by a shutdown), so
    that the next rebuild has nothing to do for them; the processes they held are freed
    a chunk per step, as that rebuild would have them freed (``Lane.clear``)."""
    dropped = [lane.clear() for lane in emptied if not lane._joining and lane.members]
    if dropped:
        lanes._defer_release(dropped)


def refused(v: np.ndarray, d: np.ndarray, maximum: np.ndarray | None = None) -> bool:
    """True if a ramp's constructor would refuse one of these (velocity, deceleration):
    ``Limits.validated`` (finite and positive limits) or ``judge_ramp`` (a ramp no plan
    could hold); or if one of the axes' maximum decelerations ``maximum`` (the ramps'
    unless beyond the Maximum Speed) is not finite and positive.

    First judged from a few extremes (:func:`_within`): enough to accept the usual
    batch; element by element (:func:`_refused_exactly`) only when that is not."""
    if v.size and _within(v, d, maximum):
        return False
    return _refused_exactly(v, d, maximum)


def _refused_exactly(v: np.ndarray, d: np.ndarray, maximum: np.ndarray | None = None) -> bool:
    """:func:`refused`, judged element by element."""
    with np.errstate(all="ignore"):
        big = np.maximum(np.abs(v), 1e-9) * 2.0
        duration = np.abs(v) / d
        ok = (
            np.isfinite(v)
            & np.isfinite(big)
            & np.isfinite(d)
            & (d > 0.0)
            & np.isfinite(duration)
            & (duration <= MAX_DURATION)
            & np.isfinite(duration * v)
        )
        if maximum is not None:
            ok &= np.isfinite(maximum) & (maximum > 0.0)
    return not bool(ok.all())


def _within(v: np.ndarray, d: np.ndarray, maximum: np.ndarray | None) -> bool:
    """A sufficient condition for :func:`refused` to accept every (velocity,
    deceleration) of a non-empty batch, from the largest speed, the smallest and largest
    deceleration (and maximum): every ``|v| / d`` is at most ``max |v| / min d`` and every
    ``duration * |v|`` at most that times ``max |v|``, as IEEE division and multiplication
    are monotonic; a NaN anywhere makes an extreme NaN, which fails every comparison.
    False says nothing (the caller checks element by element)."""
    fastest = float(np.abs(v).max())
    least = float(d.min())
    most = float(d.max())
    if not (least > 0.0 and math.isfinite(most) and math.isfinite(fastest)):
        return False
    if not math.isfinite(max(fastest, 1e-9) * 2.0):
        return False
    if maximum is not None:
        low = float(maximum.min())
        if not (low > 0.0 and math.isfinite(float(maximum.max()))):
            return False
    longest = fastest / least
    return longest <= MAX_DURATION and math.isfinite(longest * fastest)


def plain_and_active(members: list[Process]) -> bool:
    """Every process of ``members`` is active and aborts as ``Process.abort`` does: its
    class does not override it, or it is a cam with no successor waiting
    (``CamProcess.abort`` is then ``Process.abort``). Read without a Python call per
    process (the states counted, not hashed: an enum member's hash is a Python call)."""
    kinds: set[type[Process]] = set(map(type, members))
    for kind in kinds:
        if kind.abort is _abort:
            continue
        if kind.abort is not _cam_abort:
            return False
        if any(p.successor is not None for p in members if type(p) is kind):
            return False
    return list(map(_state, members)).count(_ACTIVE) == len(members)


def stepped_lanes(lanes: GroupLanes) -> tuple[list[Lane], int] | None:
    """The lanes of ``lanes`` that hold members, and how many, when every member was
    stepped since the last rebuild (no lane has a process joining or evicted); None
    otherwise."""
    found: list[Lane] = []
    total = 0
    for lane in lanes.all:
        members = lane.members
        if lane._joining:
            return None
        if members:
            if len(lane._slot) != len(members):
                return None
            found.append(lane)
            total += len(members)
    return found, total


def members_of(motion: Motion, found: list[Lane], idx: np.ndarray, whole: bool) -> bool:
    """Every member of the lanes ``found`` is on an axis of a batch (array indices
    ``idx``; ``whole``: the batch is every axis of the group, so every member of its
    lanes is on one of them) and is active, aborting as ``Process.abort`` does
    (:func:`plain_and_active`)."""
    batch: np.ndarray | None = None
    if not whole:
        batch = np.zeros(len(motion.s.busy), dtype=bool)
        batch[idx] = True
    for lane in found:
        if batch is not None and not batch[lane.idx].all():
            return False
        if not plain_and_active(lane.members):
            return False
    return True


def _member_lanes(
    motion: Motion, lanes: GroupLanes, axes: Sequence[Axis], idx: np.ndarray
) -> list[Lane] | None:
    """The lanes holding every process of ``axes``, if the batch is that simple: each
    axis's only process a member of one of the group's lanes, stepped there since the
    last rebuild (no lane has a process joining or evicted, nor stop rows), a process
    that aborts as ``Process.abort`` does (a cam too, with no successor waiting),
    active; no cam preloaded. Else None (then
    :func:`stop_axes` settles and sums axis by axis).

    Found from the lanes: a lane's member is the only process of its axis, with nothing
    buffered (a command, a buffered one too, takes the axis out of its lane first), so
    members on ``axes`` alone, as many as the axes, are one process per axis. The
    members' classes and states are read with ``operator.attrgetter`` (no Python call
    per process)."""
    stepped = stepped_lanes(lanes)
    if stepped is None:
        return None
    found, total = stepped
    if total != len(axes) or lanes.stops.rows:
        return None
    # (the batch the whole group, a group stop of a group without feedback-only axes, is
    # the usual one)
    if not members_of(motion, found, idx, len(axes) == len(lanes.group.axes)):
        return None
    if any(map(_preloaded, axes)):
        return None
    return found


def _stop_members(
    motion: Motion,
    lanes: GroupLanes,
    member_lanes: list[Lane],
    axes: Sequence[Axis],
    idx: np.ndarray,
    at: Index,
    owner: object,
    reason: AbortReason,
    maxima: tuple[np.ndarray, np.ndarray] | None,
    stopping: bool,
) -> bool:
    """:func:`stop_axes` for a batch :func:`_member_lanes` accepted: each axis has one
    process, a lane member the last step composed, so the controller's arrays already
    hold what the stop needs. The command of such an axis is what composition writes
    for one process (``Motion.compose``; the lanes write the same, bit for bit):
    ``cmd_pos = base + position``, ``cmd_vel = velocity``, ``cmd_acc = acceleration``.
    So the ramp inherits ``0.0 + cmd_vel`` and ``0.0 + cmd_acc`` (what
    :meth:`Motion.start <.motion.Motion.start>` sums) and the axis's new base, its base
    plus the aborted process's position, is ``cmd_pos``. No process is read for them.
    The lanes write their members back at once (``Lane.evict_all``: the aborted
    processes keep their final state, as axis by axis), and the processes are aborted
    as ``Process.abort`` would abort them (state and reason: they left their lane)."""
    s = motion.s
    # (``at``: a slice when the axes are consecutive, views instead of copies)
    v_arr = 0.0 + s.cmd_vel[at]
    a_arr = 0.0 + s.cmd_acc[at]
    if maxima is None:
        dec = _column(_max_deceleration, axes)
        vmax = _column(_max_velocity, axes)
    else:
        dec, vmax = maxima
    # group_stop_deceleration, element by element: the maximum deceleration within the
    # Maximum Speed (every axis, usually: then nothing is divided)
    speed = np.abs(v_arr)
    within = speed <= vmax
    if within.all():
        d_arr = dec
        # (the ramps' decelerations are the maxima: judging them judges the maxima)
        refusing = refused(v_arr, dec)
    else:
        with np.errstate(all="ignore"):
            d_arr = np.where(within, dec, dec * (speed / vmax))
        refusing = refused(v_arr, d_arr, dec)
    if refusing:
        for lane in member_lanes:
            lane.evict_all()  # (axis by axis next: the write-back moves nothing)
        return False
    for lane in member_lanes:
        lane.evict_all((_ABORTED, reason))
    # the emptied lanes empty now (their next rebuild has nothing to do); the processes
    # they held are freed a chunk per step, as a rebuild would have them freed
    clear_emptied(lanes, member_lanes)
    base = s.cmd_pos[idx]  # (a copy: the rows keep it)
    rowed = s.drive_on[at] & ((v_arr != 0.0) | (a_arr != 0.0))
    if not stopping or not motion.offers(axes[0].group):
        rowed[:] = False  # (the rows stand for ramps that stop: a halt is an object)
    rows: StopRows | None = None
    every = bool(rowed.all())
    if every:
        rows = StopRows(
            lanes.stops,
            lanes,
            list(axes),
            idx,
            base,
            v_arr,
            d_arr,
            axes[0].period,
            owner,
            ramp,
            at,
        )
        for ax, b in zip(axes, base.tolist(), strict=True):
            ax.base = b
            ax._processes = []
            ax.stop_rows = rows
    else:
        rows = _some_rowed(
            motion, lanes, axes, idx, owner, rowed, base, v_arr, a_arr, d_arr, stopping
        )
    retire_order(motion, lanes, _rows_hold(lanes, rows if every else None))
    if rows is not None:
        s.busy[rows.at] = True
        s.dirty.update(rows.idx.tolist())
        lanes.stops.add_rows(rows)
    return True


def _some_rowed(
    motion: Motion,
    lanes: GroupLanes,
    axes: Sequence[Axis],
    idx: np.ndarray,
    owner: object,
    rowed: np.ndarray,
    base: np.ndarray,
    v_arr: np.ndarray,
    a_arr: np.ndarray,
    d_arr: np.ndarray,
    stopping: bool,
) -> StopRows | None:
    """The ramps of :func:`_stop_members` when not all are rows (a ramp from rest, a
    drive off, a group without lanes): those built here, the others' rows returned."""
    flags = rowed.tolist()
    vs = v_arr.tolist()
    accels = a_arr.tolist()
    ds = d_arr.tolist()
    shared: dict[tuple[float, float], Limits] = {}
    rowed_axes: list[Axis] = []
    for k, (ax, b) in enumerate(zip(axes, base.tolist(), strict=True)):
        ax.base = b
        if flags[k]:
            rowed_axes.append(ax)
            ax._processes = []
            continue
        _ramp_object(motion, ax, vs[k], accels[k], ds[k], owner, shared, stopping)
    if not rowed_axes:
        return None
    sel = np.flatnonzero(rowed)
    rows = StopRows(
        lanes.stops,
        lanes,
        rowed_axes,
        idx[sel],
        base[sel],
        v_arr[sel],
        d_arr[sel],
        axes[0].period,
        owner,
        ramp,
    )
    for ax in rowed_axes:
        ax.stop_rows = rows
    return rows


def _ramp_object(
    motion: Motion,
    ax: Axis,
    v: float,
    a: float,
    d: float,
    owner: object,
    shared: dict[tuple[float, float], Limits],
    stopping: bool,
) -> None:
    """The ramp of ``ax`` built as an object, not a row (a ramp from rest, a drive off,
    a group without lanes, a halt): from ``v`` at ``d``, done at once from rest with no
    acceleration ``a`` to inherit. It becomes the axis's only process (no stop row is
    left on an axis whose processes the stop read), busy while it runs and offered to
    its lane as ``Motion.start`` offers it (a halt's). ``shared``: the limits of the
    batch's ramps by (velocity, deceleration), equal ones shared (they are immutable)."""
    key = (v, d)
    limits = shared.get(key)
    r = ramp(ax.period, d, v, owner, limits, stopping)
    if limits is None:
        shared[key] = r.limits
    if v == 0.0 and a == 0.0:
        r.state = _DONE
    ax._processes = [r]
    i = ax.index
    s = motion.s
    s.scalars.busy[i] = active = r.state is _ACTIVE
    s.dirty.add(i)
    if active:
        motion.offer(ax)


def retire_order(motion: Motion, lanes: GroupLanes, whole: bool) -> None:
    """The stop removed processes that read masters: the composition order changes
    (``Motion.coupling_changed``: every group sorted again at the next step). When the
    stop left no axis of the group reading a master (``whole``: every axis of the group
    either a row of the stop lane or without motion) and no other group waits for a
    sort, the order is known without sorting: the group's axes as configured (what
    ``Motion.sort`` gives axes that read no master), usually the order already kept."""
    if motion.order_dirty or not whole:
        motion.coupling_changed()
        return
    g = lanes.group
    if g.order != g.axes:
        g.order = list(g.axes)
        lanes.dirty = True


def _rows_hold(lanes: GroupLanes, rows: StopRows | None) -> bool:
    """Every axis of the group is a row of ``rows`` (made just now, one row per axis of
    the group: as many rows as the group has axes)."""
    return rows is not None and len(rows.axes) == len(lanes.group.axes)


def idle(axes: Sequence[Axis]) -> bool:
    """No axis of ``axes`` has a process (nor a ramp left as a row)."""
    return not any(map(_own_processes, axes)) and list(map(_stop_rows, axes)).count(None) == len(
        axes
    )


def abort_all(ax: Axis, procs: list[Process], reason: AbortReason) -> None:
    """``Motion.retire`` of every process of ``ax`` (``procs``, its processes, out of
    the lanes) and of its preloaded cams, without the calls: each active one aborted as
    ``Process.abort`` does (inline when its class does not override it), each that ended
    folded into the axis's base, in order."""
    if ax.preloaded_cams:
        for p in ax.preloaded_cams:
            p.abort(reason)
        ax.preloaded_cams = [p for p in ax.preloaded_cams if p.active]
    base = ax.base
    for p in procs:
        if p.state is _ACTIVE:
            if type(p).abort is _abort:
                p.state = _ABORTED
                p.abort_reason = reason
            else:
                p.abort(reason)
        if p.state is not _ACTIVE:
            base += p.position
    ax.base = base


def something_to_stop(ax: Axis) -> bool:
    """A stop has something to replace on ``ax``: a process (a ramp still a row of the
    stop lane too, not made for this), a buffered command or a preloaded cam. An axis
    without any is at rest: a ramp from rest would end at once and move nothing."""
    return bool(
        ax._processes or ax.stop_rows is not None or ax.buffered is not None or ax.preloaded_cams
    )


def stop_axes(
    motion: Motion,
    axes: Sequence[Axis],
    owner: object,
    reason: AbortReason = AbortReason.STOPPED,
    idx: np.ndarray | None = None,
    maxima: tuple[np.ndarray, np.ndarray] | None = None,
    at: Index | None = None,
    stopping: bool = True,
) -> bool:
    """Replace every process of each of ``axes`` (driven axes in Servo Control, in
    group order, their MDAC links already broken) by a trapezoidal ramp to rest at its
    maximum deceleration, bounded as a group stop bounds it; cancel what is buffered.

    The ramps of axes whose drive is on, in a group with fast lanes, join its stop lane
    as one :class:`~.lanes.stop_rows.StopRows`: their objects are made when something
    reads the axis's processes. The others (a ramp from rest, done at once; no lanes)
    are built here. ``idx``: the axes' array indices, ``maxima``: their maximum
    decelerations and velocities, ``at`` the indices as :func:`.state.compact` gives
    them, if the caller has them. ``stopping=False``: the ramps of a halt (MC_Halt: the
    axis is not Stopping), every one built here (the rows stand for ramps that stop).

    Returns False without having changed anything if an axis's ramp would be refused (a
    non-finite velocity, a deceleration out of range, a ramp too long): the caller then
    stops them one by one, which raises as it always did."""
    if not axes:
        return True
    lanes = motion.lanes[axes[0].group]
    if idx is None:
        idx = np.array([ax.index for ax in axes], dtype=np.intp)
    member_lanes = _member_lanes(motion, lanes, axes, idx)
    if member_lanes is not None:
        if at is None:
            at = compact(idx)
        return _stop_members(
            motion, lanes, member_lanes, axes, idx, at, owner, reason, maxima, stopping
        )
    lanes, emptied = empty_lanes(motion, axes)
    n = len(axes)
    # the axes with something to stop. The others are at rest with nothing to stop (an
    # MGS of a group already stopped): the ramp from rest a stop makes them is done at
    # once, moves nothing and is dropped by the next composition, so none is made (a
    # group of 256 such axes: about 2 ms of ramps made and composed in the cycle)
    work = [k for k, ax in enumerate(axes) if something_to_stop(ax)]
    vs = [0.0] * n
    accels = [0.0] * n
    for k in work:
        ax = axes[k]
        # settle (lanes write their state back) and sum what the ramp inherits, in the
        # order Motion.start sums it
        v = a = 0.0
        for p in ax.processes:
            lane = p.lane
            if lane is not None:
                lane.evict(p)
            if p.state is _ACTIVE:
                v += p.velocity
                a += p.acceleration
        vs[k] = v
        accels[k] = a
        for p in ax.preloaded_cams:
            lane = p.lane
            if lane is not None:
                lane.evict(p)
    v_arr = np.array(vs, dtype=float)
    if maxima is None:
        dec = _column(_max_deceleration, axes)
        vmax = _column(_max_velocity, axes)
    else:
        dec, vmax = maxima
    with np.errstate(all="ignore"):
        absv = np.abs(v_arr)
        # group_stop_deceleration, element by element
        d_arr = np.where(absv <= vmax, dec, dec * (absv / vmax))
    if not (np.isfinite(dec) & (dec > 0.0)).all() or refused(v_arr, d_arr):
        return False
    ds = d_arr.tolist()
    s = motion.s
    dirty = s.dirty
    offered = motion.offers(axes[0].group)
    drive_on = s.drive_on
    coupling = False
    # the ramps left as rows: (position in ``axes``, axis, base)
    rowed: list[int] = []
    rowed_axes: list[Axis] = []
    rowed_idx: list[int] = []
    bases: list[float] = []
    # equal limits are shared by the ramps of this batch (they are immutable)
    shared: dict[tuple[float, float], Limits] = {}
    for k in work:
        ax = axes[k]
        procs = ax.processes
        if not procs:
            lanes.dirty = True
        abort_all(ax, procs, reason)
        base = ax.base
        if not coupling and any(p.masters for p in procs):
            # (a process that read no master changes no composition order)
            coupling = True
        if ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        v = vs[k]
        i = ax.index
        if stopping and offered and not (v == 0.0 and accels[k] == 0.0) and drive_on.item(i):
            # a ramp the stop lane takes at once: a row, its object made when read
            rowed.append(k)
            rowed_axes.append(ax)
            rowed_idx.append(i)
            bases.append(base)
            ax._processes = []
            continue
        _ramp_object(motion, ax, v, accels[k], ds[k], owner, shared, stopping)
    clear_emptied(lanes, emptied)
    if coupling:
        motion.coupling_changed()
    if rowed:
        sel = np.array(rowed, dtype=np.intp)
        rows = StopRows(
            lanes.stops,
            lanes,
            rowed_axes,
            np.array(rowed_idx, dtype=np.intp),
            np.array(bases, dtype=float),
            v_arr[sel],
            d_arr[sel],
            rowed_axes[0].period,
            owner,
            ramp,
        )
        for ax in rowed_axes:
            ax.stop_rows = rows
        s.busy[rows.idx] = True
        dirty.update(rows.idx.tolist())
        lanes.stops.add_rows(rows)
    return True
