"""Many position cams started in one scan, planned together.

What many MAPC (Immediate) or MC_CamIn executed in the same scan hand the kernel: one
:class:`CamStart` per slave. :func:`start_position_cams` starts them with the same result
as starting each one after the other with ``Controller.start(slave, make, replace=())``
(the process, its state, the axis's status, the lane it joins, the order of everything),
but plans what they share once:

- cams with the same parameters on the same profile share what the constructor computes
  from them (the profile's value at the cam lock position, the period index, the
  enumerations): one cam is built by :class:`~.cams.CamProcess`, the others are copies of
  its attributes with their own master and owner;
- the masters' positions and velocities at the lock are read from the arrays in one
  gather;
- a slave without motion takes its cam as ``Motion.start`` does for an axis without
  motion, without the factory's calls; any other slave (one with processes, a cam
  preloaded on it) goes through ``Controller.start`` itself.

**The usual batch as lane rows** (:func:`_as_rows`): when every slave is distinct, at
rest, driven and in one group whose lanes take processes, and every cam is one the cam
lane takes (locked at once, its master settled), the batch is planned as arrays, with
the same result:

- the cams are made from their templates in one loop (no lane admission each);
- the cam lane takes the batch's columns as computed from the templates and the
  masters' arrays (``CamLane.admit_batch``), not read back from the objects; a lane that
  was empty is rebuilt from them directly;
- the group's composition order is checked for the new links as arrays (each slave
  after its master): when it holds, the group is not sorted again at the next step;
- the level each new cam will have is found from the levels the lanes hold (its
  master's lane, or its master a cam of the same batch), and when no follower already
  in the lanes reads one of the new slaves, the cams are handed to the lane with these
  levels: the next step orders the lanes that changed, without levelling every follower
  of the group again (``GroupLanes._hand_over``).

Anything else (a slave moving, a master composed in Python, a cam that cannot start) takes
the path above, one cam after the other.

A cam that cannot start (its cam lock position outside the profile's range) raises
:class:`~.errors.MotionError` there, after the cams before it started and before the
ones after it: as the same starts one after the other would.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from .axis import Axis
from .cam_profile import CamProfile
from .cams import CamMode, CamProcess, LockDirection
from .controller import Controller
from .enums import MasterReference, ProcessKind
from .errors import MotionError
from .lanes import GroupLanes
from .lanes.cams import CamLane
from .processes import Process, ProcessFactory


class CamStart(NamedTuple):
    """One position cam locked at once on ``slave`` (MAPC Immediate, MC_CamIn without a
    ramp-in): the :class:`~.cams.CamProcess` arguments of such a cam. (A named tuple:
    many are made in one scan, and a frozen dataclass costs five times as much.)"""

    slave: Axis
    master: Axis
    profile: CamProfile
    mode: CamMode
    scale: float
    master_scaling: float
    cam_lock: float
    source: MasterReference = MasterReference.COMMAND
    origin: float = 0.0
    kind: ProcessKind | None = None
    owner: Any = None

    def build(self, ctl: Controller) -> CamProcess:
        """The cam as its constructor makes it."""
        return CamProcess(
            ctl,
            self.profile,
            self.mode,
            self.scale,
            self.master_scaling,
            self.cam_lock,
            master=self.master.index,
            source=self.source,
            master_number=self.master.number,
            lock=LockDirection.IMMEDIATE,
            rollover=self.master.config.rollover,
            origin=self.origin,
            kind=self.kind,
            owner=self.owner,
        )


def _shared(c: CamStart) -> tuple[Any, ...]:
    """What cams built alike share (everything but the master and the owner)."""
    return (
        id(c.profile),
        c.mode,
        c.scale,
        c.master_scaling,
        c.cam_lock,
        c.source,
        c.origin,
        c.kind,
        c.master.config.rollover,
    )


def _factory(ctl: Controller, c: CamStart) -> ProcessFactory:
    def make(v: float, a: float) -> Process:
        return c.build(ctl)

    return make


def start_position_cams(ctl: Controller, starts: Sequence[CamStart]) -> list[CamProcess]:
    """Start the cams of ``starts`` in order (see the module docstring); returns them."""
    if not starts:
        return []
    rows = _as_rows(ctl, starts)
    if rows is not None:
        return rows
    return _one_after_another(ctl, starts)


def _as_rows(ctl: Controller, starts: Sequence[CamStart]) -> list[CamProcess] | None:
    """The usual batch, started as rows of the cam lanes: every slave distinct, in one
    group whose lanes take processes, its drive on, without motion (no process, no
    preloaded cam, nothing buffered, no stop row), every cam one the cam lane takes
    (a position cam locked at once on another axis, whose master is settled as
    ``GroupLanes._offer_cam`` asks). Otherwise None, and nothing has changed.

    Each cam is a copy of its parameter set's template with its own master's position
    and velocity (gathered once); the cam lane takes the batch's columns as arrays
    (:meth:`~.lanes.cams.CamLane.admit_batch`), and when the group's composition order
    and the followers' levels stay valid with the new links (checked as arrays and
    from the levels the lanes hold), neither is computed again at the next step."""
    motion = ctl.motion
    s = motion.s
    n = len(starts)
    lanes = motion.lanes_for(starts[0].slave)
    if lanes is None:
        return None
    group = lanes.group.number
    # one pass over the starts: what each must be, and its parameter set
    templates: dict[tuple[Any, ...], int] = {}
    firsts: list[CamStart] = []  # the first start of each parameter set
    which: list[int] = []
    last: tuple[Any, ...] | None = None  # the parameters of the start before
    t = -1
    rollover = 0.0
    position_cam = ProcessKind.POSITION_CAM
    for c in starts:
        ax = c[0]
        if (
            ax.group != group
            or ax.stop_rows is not None
            or ax._processes
            or ax.preloaded_cams
            or ax.buffered is not None
            or c[1] is ax
            or (c[9] is not None and c[9] != position_cam)
        ):
            return None
        params = c[2:10]  # (a profile compares by identity)
        if params != last or c[1].config.rollover != rollover:
            key = _shared(c)
            t = templates.setdefault(key, len(firsts))
            if t == len(firsts):
                firsts.append(c)
            rollover = c[1].config.rollover
        which.append(t)
        last = params
    slaves = [c[0] for c in starts]
    masters = [c[1] for c in starts]
    slave_idx = [ax.index for ax in slaves]
    if len(set(slave_idx)) != n:
        return None
    sl = np.array(slave_idx, dtype=np.intp)
    midx = np.array([ax.index for ax in masters], dtype=np.intp)
    if not s.drive_on[sl].all():
        return None
    sources = {c.source for c in starts}
    cam_lanes = {src: _cam_lane(lanes, src) for src in sources}
    # the group's composition order: where each axis composes (-1: not in the group)
    order = lanes.group.order
    if lanes._order is order:
        order_idx = lanes._order_idx
    else:
        order_idx = np.array([ax.index for ax in order], dtype=np.intp)
    at = np.full(len(s.busy), -1, dtype=np.intp)
    at[order_idx] = np.arange(len(order_idx))
    # the level each new cam on a command position gets (None: levelled again at the
    # rebuild), and whether its master is settled (GroupLanes._offer_cam)
    levelled = not (lanes.dirty or lanes.handed)
    levels = _levels(lanes, starts, sl, midx, at) if levelled else None
    if levels is None:
        in_batch = set(slave_idx)
        settled = lanes._master_settled
        for c in starts:
            m = c[1].index
            if c.source == MasterReference.COMMAND and m not in in_batch and not settled(m):
                return None  # (the lanes would keep it out)
    # one template per parameter set: what the constructor leaves, as the lane finds it
    shared: list[dict[str, Any]] = []
    for c in firsts:
        try:
            p = c.build(ctl)
        except MotionError:
            return None  # started one after the other: it raises where it must
        if not CamLane.accepts(p):
            return None
        d = dict(p.__dict__)
        d["lane"] = cam_lanes[c.source]
        d["offer_pending"] = False  # (Motion.offer clears it before the lane admits)
        shared.append(d)
    # the masters' positions and velocities, read as each constructor reads them
    if len(sources) == 1:
        pos, vel, _ = ctl.master_arrays(next(iter(sources)))
        m_at, v_at = pos[midx], vel[midx]
    else:
        m_at = np.empty(n)
        v_at = np.empty(n)
        for src in sources:
            pos, vel, _ = ctl.master_arrays(src)
            sel = np.array([c.source == src for c in starts], dtype=bool)
            m_at[sel] = pos[midx[sel]]
            v_at[sel] = vel[midx[sel]]
    # from here on the batch starts: each cam the only process of its slave
    out: list[CamProcess] = []
    new = CamProcess.__new__
    for c, ax, k, m, v in zip(starts, slaves, which, m_at.tolist(), v_at.tolist(), strict=True):
        master = c[1]
        p = new(CamProcess)
        p.__dict__.update(shared[k])
        p.owner = c.owner
        p.index = master.index
        p.masters = (master.number,)
        p.m_prev = p.m0 = p.m_eff = m
        p.v_prev = v
        ax._processes.append(p)
        out.append(p)
    # Motion.start_from_rest, for all of them: busy, the status marked stale, the order
    s.busy[sl] = True
    s.dirty.update(slave_idx)
    if not motion.order_dirty and not _order_holds(at, sl, midx):
        motion.order_dirty = True
    ids = None
    if levels is not None and not motion.order_dirty:
        if len(sources) == 1 and MasterReference.COMMAND in sources:
            ids = dict(zip(map(id, out), levels, strict=True))  # (every cam levelled)
        else:
            ids = {id(p): lv for p, lv in zip(out, levels, strict=True) if lv >= 0}
    # the lanes' admission, in the batch's order
    if len(sources) == 1:
        lane = cam_lanes[next(iter(sources))]
        joined = list(zip(out, slaves, strict=True))
        lane.admit_batch(joined, _columns(shared, which, m_at, v_at), ids)
    else:
        for src, lane in cam_lanes.items():
            rows = [k for k in range(n) if starts[k].source == src]
            joining: list[tuple[Process, Axis]] = [(out[k], slaves[k]) for k in rows]
            cols = _columns(shared, [which[k] for k in rows], m_at[rows], v_at[rows])
            lane.admit_batch(joining, cols, ids)
    return out


def _cam_lane(lanes: GroupLanes, source: MasterReference) -> CamLane:
    for follower in lanes.followers[source]:
        if isinstance(follower, CamLane):
            return follower
    raise AssertionError("every source has a cam lane")


def _columns(
    shared: list[dict[str, Any]], which: list[int], m_at: np.ndarray, v_at: np.ndarray
) -> dict[str, np.ndarray]:
    """The cam lane's ``FIELDS`` (but ``base``) of cams of the batch (``which``: the
    parameter set of each), what ``CamLane._load`` reads from each: the templates'
    values, the masters' positions and velocities."""
    count = len(which)
    one = len(shared) == 1
    sel = None if one else np.array(which, dtype=np.intp)
    col: dict[str, np.ndarray] = {}
    for name, attr in _TEMPLATE_FIELDS.items():
        values = [float(d.get(attr, 0.0)) for d in shared]
        col[name] = np.full(count, values[0]) if sel is None else np.array(values)[sel]
    for name in ("start", "end", "length", "rise"):
        values = [float(getattr(d["profile"], name)) for d in shared]
        col[name] = np.full(count, values[0]) if sel is None else np.array(values)[sel]
    col["m0"] = m_at
    col["m_last"] = m_at
    col["v_prev"] = v_at
    col["passes"] = np.zeros(count, dtype=np.int64)
    return col


#: the cam lane's fields that a new cam takes from its template (its parameter set), and
#: the attributes that hold them (absent from a new cam's instance: the class default 0)
_TEMPLATE_FIELDS = {
    "origin": "origin",
    "scale": "scale",
    "ms": "master_scaling",
    "cam_lock": "cam_lock",
    "f0": "f0",
    "mode": "mode",
    "k": "k",
    "x": "x",
    "pos": "position",
    "vel": "velocity",
    "acc": "acceleration",
}


def _order_holds(at: np.ndarray, sl: np.ndarray, midx: np.ndarray) -> bool:
    """``Motion._order_holds`` of every cam of the batch, as arrays (``at``: each axis's
    place in the group's composition order, -1 outside the group, whose order holds
    every axis of it): each slave composes after its master when that is in the
    group."""
    here = at[sl]
    if (here < 0).any():
        return False
    before = at[midx]
    return bool((before < here).all())


def _levels(
    lanes: GroupLanes,
    starts: Sequence[CamStart],
    sl: np.ndarray,
    midx: np.ndarray,
    at: np.ndarray,
) -> list[int] | None:
    """The command level each new cam gets at the next rebuild (-1 for a cam on an
    actual position, which is not levelled), as ``GroupLanes._order_command_followers``
    would find it, if the levels of the followers already in the lanes stay as they
    are: none of them reads a new slave (a master without motion is read at level 0; in
    a lane it may not be). Called only when nothing else waits for the followers to be
    levelled again (``dirty``, ``handed``). None when not sure (or when a master is not
    settled: then the caller asks ``GroupLanes._master_settled``)."""
    cmd = lanes.followers[MasterReference.COMMAND]
    # the level a command follower of each axis gets: 0 outside the group or in a lane
    # that steps first; its own level + 1 in a command follower lane; -1 not known here
    lv = np.where(at < 0, 0, -1)
    for lane in (
        lanes.cruise,
        lanes.profiles,
        lanes.stops,
        lanes.scurves,
        *lanes.followers[MasterReference.ACTUAL],
    ):
        if lane.members:
            lv[lane.idx] = 0
    for lane in cmd:
        if lane.members:
            if len(lane.member_levels) != len(lane.members) or np.isin(lane.midx, sl).any():
                return None
            lv[lane.idx] = np.array(lane.member_levels) + 1
    lv[sl] = -2  # slaves of the batch: levelled below
    of_master = lv[midx]
    everyone = all(c.source == MasterReference.COMMAND for c in starts)
    if everyone and bool((of_master >= 0).all()):
        return of_master.tolist()  # (the usual batch: every master settled and known)
    command = [c.source == MasterReference.COMMAND for c in starts]
    ups = of_master.tolist()
    by_slave = {c.slave.index: j for j, c in enumerate(starts)}
    group = lanes.group
    found: dict[int, int | None] = {}

    def level(k: int) -> int | None:
        """The level of the batch's cam ``k`` (on a command position)."""
        if k in found:
            return found[k]
        found[k] = None  # (a loop of masters: not levelled here)
        up: int | None = ups[k]
        if up == -1:
            up = _master_level(group.by_index[starts[k].master.index])
        elif up == -2:
            j = by_slave[starts[k].master.index]
            if not command[j]:
                up = 0  # (an actual-position lane steps first)
            else:
                below = level(j)
                up = None if below is None else below + 1
        found[k] = up
        return up

    out: list[int] = []
    for k in range(len(starts)):
        if not command[k]:
            out.append(-1)
            continue
        got = level(k)
        if got is None:
            return None
        out.append(got)
    return out


def _master_level(master: Axis) -> int | None:
    """The level a command follower of ``master`` (in the group, in no lane as a
    member, not a slave of the batch) gets, if it is settled and known: 0 without
    motion; else None (joining a lane: its level is decided at the rebuild)."""
    if master.stop_rows is None and not master._processes and master.buffered is None:
        return 0
    return None


def _one_after_another(ctl: Controller, starts: Sequence[CamStart]) -> list[CamProcess]:
    """The cams of ``starts`` started in order, each offered to the lanes on its own."""
    motion = ctl.motion
    s = motion.s
    out: list[CamProcess] = []
    by_source: dict[MasterReference, tuple[list[float], list[float]]] = {}
    for src in {c.source for c in starts}:
        pos, vel, _ = ctl.master_arrays(src)
        idx = np.array([c.master.index for c in starts], dtype=np.intp)
        by_source[src] = (pos[idx].tolist(), vel[idx].tolist())
    #: the attributes of the first cam built for each set of shared parameters, as its
    #: constructor left them (before the start offers it to a lane)
    templates: dict[tuple[Any, ...], dict[str, Any]] = {}
    busy = s.scalars.busy
    dirty = s.dirty
    for j, c in enumerate(starts):
        ax = c.slave
        if ax.processes or ax.preloaded_cams:
            # not an axis without motion: the start's own path, the cam built as usual
            started = ctl.start(ax, _factory(ctl, c), replace=())
            assert isinstance(started, CamProcess)
            out.append(started)
            continue
        key = _shared(c)
        template = templates.get(key)
        if template is None:
            p = c.build(ctl)  # raises as the constructor does
            templates[key] = dict(p.__dict__)
        else:
            # the constructor's result for this master: what it read from the master
            # (its position as the lock, its velocity) and the master and owner
            m_pos, m_vel = by_source[c.source]
            m = m_pos[j]
            d = dict(template)
            d["owner"] = c.owner
            d["index"] = c.master.index
            d["masters"] = (c.master.number,)
            d["m_prev"] = d["m0"] = d["m_eff"] = m
            d["v_prev"] = m_vel[j]
            p = CamProcess.__new__(CamProcess)
            p.__dict__ = d
        # Motion.start for an axis without motion (``replace=()``: a buffered command
        # stays; a cam is never scaled by an override)
        motion.lanes[ax.group].dirty = True
        ax.processes.append(p)
        motion.order_dirty = True
        busy[ax.index] = True
        dirty.add(ax.index)
        motion.offer(ax)
        out.append(p)
    return out
