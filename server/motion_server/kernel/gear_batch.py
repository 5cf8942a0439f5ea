"""Gears started on many slaves in one call: MAG or MC_GearIn executed on N slaves in the
same scan, each on one master.

:func:`start_gears` does what ``Controller.start`` does for each slave in order, with
MAG's factory

    ``lambda v, a: GearProcess(ctl, slave, (term,), ramp, v, a, owner, direction)``

where ``ramp`` is ``RateRamp(rate)`` (the clutch: the slave catches up at ``rate`` from
the velocity it inherits, then locks) or None (no clutch: locked at once), and
``replace=(ProcessKind.GEAR,)``; or MC_GearIn's, whose trapezoidal catch-up is
``RateRamp(acceleration, deceleration)`` (a pair given as the rate) and whose aborting
mode replaces every process (``replace=None``). It leaves the very same state (the tests compare the
two attribute by attribute and step them side by side, lanes on and off). What it saves
is the per-slave work that does not depend on the slave:

- the ratio and the clutch rate are judged once per distinct value (the same errors, in
  the same order: the rate, then the ratio);
- on a slave without motion, the first gear with given parameters is built by the
  constructors; the others copy its attributes, their coupling's and their ramp's, and
  take what depends on their own master (its array index, its position and velocity at
  the start, its conversion constant) as the constructor computes it;
- the gears that join a lane are handed to it together, with their columns (what the
  lane would load from each at the next rebuild). When each reads a master stepped
  before every follower (a jog, a move, a stop ramp in a time-driven lane, or an axis of
  another group) and no follower in the lanes reads their slaves, their level is known
  (0): the next rebuild orders the follower lanes without levelling every follower
  again (:meth:`.lanes.gears.BatchedLane.admit_started`).

A slave whose one process the gear replaces (a gear on a slave already geared: a new
ratio; :mod:`.take_over`) takes a gear built from that process's velocity and
acceleration, once per set of parameters and start state, the others copied, and joins
the batch as a gear from rest does. Any other slave (more processes, a preloaded cam or
a buffered command) is started through ``Motion.start`` with the factory. As with the
loop, a :class:`.errors.MotionError` on a slave leaves the slaves before it started and
nothing changed on it.
"""

from __future__ import annotations

import struct
from collections.abc import Collection, Sequence
from itertools import chain
from typing import Any

import numpy as np

from .axis import Axis
from .enums import MasterReference, ProcessKind
from .gearing import GearProcess, GearTerm, RateRamp, _Coupling
from .lanes import GroupLanes
from .lanes.gears import BatchedLane, CatchUpLane, GearLane
from .motion import Motion
from .processes import Process, ProcessFactory
from .state import AxisArrays
from .take_over import sole_replaced, take_over

#: what a gear replaces (Logix MAG; None for the PLCopen aborting mode)
_REPLACE = (ProcessKind.GEAR,)
#: a gear's catch-up: None (locked at once), MAG's clutch rate, or MC_GearIn's
#: (acceleration, deceleration)
Rate = float | tuple[float, float] | None
_COMMAND = MasterReference.COMMAND


def _factory(
    ctx: AxisArrays,
    slave: Axis,
    term: GearTerm,
    rate: Rate,
    owner: object,
    direction: int,
) -> ProcessFactory:
    """MAG's (or MC_GearIn's) factory: the ramp built with the gear (``RateRamp`` judges
    its rate, or its acceleration and deceleration)."""

    def make(v: float, a: float) -> Process:
        ramp = _ramp(rate)
        return GearProcess(ctx, slave, (term,), ramp, v, a, owner=owner, direction=direction)

    return make


def _ramp(rate: Rate) -> RateRamp | None:
    """The catch-up of ``rate``: none, MAG's clutch rate, or (acceleration,
    deceleration)."""
    if rate is None:
        return None
    if isinstance(rate, tuple):
        return RateRamp(*rate)
    return RateRamp(rate)


class _Template:
    """A gear as the constructors left it on a slave without motion (before its start):
    its attributes, its coupling's and its ramp's, to copy for another master."""

    __slots__ = ("coupling", "gear", "ramp")

    def __init__(self, p: GearProcess) -> None:
        self.gear = dict(vars(p))
        c = p._c[0]
        self.coupling = {name: getattr(c, name) for name in _Coupling.__slots__}
        ramp = p.ramp
        self.ramp = None if ramp is None else dict(vars(ramp))


def _copy(
    t: _Template, ctx: AxisArrays, slave: Axis, term: GearTerm, index: int, owner: object
) -> GearProcess:
    """``GearProcess(ctx, slave, (term,), ramp, 0.0, 0.0, owner, direction)`` from the
    template of a gear built with the same ratio, reference, rate and direction: what
    depends on the master (and the slave's conversion constant) set as the constructor
    sets it."""
    c = _Coupling.__new__(_Coupling)
    cs = t.coupling
    pos = cs["pos"]
    vel = cs["vel"]
    c.pos = pos
    c.vel = vel
    c.acc = cs["acc"]
    c.exact = exact = cs["exact"]
    c.index = index
    c.cpu_m = cpu_m = float(ctx.conversion[index])
    c.cpu_s = cpu_s = float(slave.config.conversion_constant)
    c.num = num = cs["num"]
    c.den = den = cs["den"]
    c.ratio = num / den * cpu_m / cpu_s if exact else cs["ratio"]
    c.lock_pos = pos.item(index)
    c.lock_counts = 0
    c.slave_counts = 0
    c.v_prev = vel.item(index)
    d = dict(t.gear)
    d["owner"] = owner
    d["terms"] = (term,)
    d["masters"] = (term.master,)
    d["_c"] = [c]
    d["single"] = c
    if t.ramp is not None:
        ramp = RateRamp.__new__(RateRamp)
        ramp.__dict__.update(t.ramp)
        d["_ramp"] = ramp
    elif exact:
        # locked at once: _Coupling.lock of a fraction ratio (its position read again)
        try:
            c.lock_counts = round(c.lock_pos * cpu_m)
        except (OverflowError, ValueError):
            c.lock_counts = 0
    p = GearProcess.__new__(GearProcess)
    p.__dict__ = d
    return p


class _Joining:
    """The gears of the batch bound for one follower lane, admitted together: the
    members, their rows of the lane's ``FIELDS``, whether all step at level 0."""

    __slots__ = ("at_zero", "lane", "masters", "members", "rows")

    def __init__(self, lane: BatchedLane) -> None:
        self.lane = lane
        self.members: list[tuple[Process, Axis]] = []
        self.rows: list[tuple[Any, ...]] = []
        self.masters: list[int] = []  # the members' masters' indices
        self.at_zero = True


class _Batch:
    """What the gears of one call share while they start: the lanes they join, and what
    is known of the masters and readers of each group's lanes."""

    __slots__ = ("first", "joining", "masters_at_zero", "positions", "readers")

    def __init__(self) -> None:
        self.joining: dict[int, _Joining] = {}
        #: per group: the ids of the lanes stepped before every follower
        self.first: dict[int, set[int]] = {}
        #: master index -> a command follower of it steps at level 0
        self.masters_at_zero: dict[int, bool] = {}
        #: per group: the axis indices the followers in its lanes read (a slave among
        #: them changes their levels when it joins a lane)
        self.readers: dict[int, set[int]] = {}
        #: per group: each axis index's place in the composition order
        self.positions: dict[int, dict[int, int]] = {}

    def admit(self) -> None:
        """Hand the gathered gears to their lanes (in the order they started), and
        forget what the lanes held: another start may change it."""
        for j in self.joining.values():
            j.lane.admit_started(j.members, _columns(j.rows), j.at_zero, j.masters)
        self.joining.clear()
        self.masters_at_zero.clear()
        self.readers.clear()


def _columns(rows: list[tuple[Any, ...]]) -> list[np.ndarray] | None:
    """The lane's columns from its rows of floats (or ints), converted to float64 as the
    rebuild converts the rows it loads: packed as C doubles and read by numpy in one
    call (numpy's own conversion of a list of Python numbers costs about four times as
    much). None when a value does not convert: the rebuild loads the gears one by one."""
    if not rows:
        return None
    n, w = len(rows), len(rows[0])
    try:
        buf = struct.pack(f"{n * w}d", *chain.from_iterable(rows))
    except (struct.error, OverflowError, TypeError):
        return None
    return list(np.frombuffer(buf, dtype=float).reshape(n, w).T)


def start_gears(
    motion_or_ctl: Any,
    slaves: Sequence[Axis],
    terms: Sequence[GearTerm],
    clutch_rates: Sequence[Rate],
    owners: Sequence[object] | None = None,
    directions: Sequence[int] | None = None,
    replace: Collection[ProcessKind] | None = _REPLACE,
) -> list[Process]:
    """Start a gear of ``terms[k]`` on ``slaves[k]`` for every k in order (see the module
    docstring): clutched at ``clutch_rates[k]`` (None: locked at once; a pair: MC_GearIn's
    acceleration and deceleration), owned by ``owners[k]`` (None: no owner), in the
    direction ``directions[k]`` kept on the slave (+1 same, -1 opposite, as MAG resolves
    it; None: +1, the constructor's default), each replacing ``replace`` (a gear, as MAG;
    None: every process, MC_GearIn's aborting mode). ``motion_or_ctl`` is the
    :class:`~.motion.Motion` or the controller holding it. Returns the processes
    started."""
    n = len(slaves)
    if (
        len(terms) != n
        or len(clutch_rates) != n
        or (owners is not None and len(owners) != n)
        or (directions is not None and len(directions) != n)
    ):
        raise ValueError("one term, clutch rate (and owner and direction, if any) per slave")
    motion: Motion = motion_or_ctl if isinstance(motion_or_ctl, Motion) else motion_or_ctl.motion
    ctx = motion.s
    started: list[Process] = []
    # per set of parameters, the first gear the constructors built (so its ratio and
    # rate were judged valid; an unseen or refused set is built, and raises, as usual)
    templates: dict[tuple[Any, ...], _Template] = {}
    batch = _Batch()
    try:
        for k in range(n):
            ax = slaves[k]
            term = terms[k]
            rate = clutch_rates[k]
            owner = None if owners is None else owners[k]
            direction = 1 if directions is None else directions[k]
            procs = ax._processes if ax.stop_rows is None else ax.processes
            if procs or ax.preloaded_cams or ax.buffered is not None:
                q = sole_replaced(ax, procs, replace)
                if q is not None:
                    started.append(
                        _from_motion(motion, ax, q, term, rate, owner, direction, templates, batch)
                    )
                    continue
                # not an axis without motion: the start's own path, in the loop's order
                batch.admit()
                make = _factory(ctx, ax, term, rate, owner, direction)
                started.append(motion.start(ax, make, replace))
                continue
            p, index = _built(ctx, ax, term, rate, owner, direction, templates)
            _started(motion, ax, procs, p, index, term.source, batch)
            started.append(p)
    finally:
        # (also when a gear is refused: those before it started, as in the loop)
        batch.admit()
    return started


def _built(
    ctx: AxisArrays,
    ax: Axis,
    term: GearTerm,
    rate: Rate,
    owner: object,
    direction: int,
    templates: dict[tuple[Any, ...], _Template],
    moving: tuple[float, float] | None = None,
) -> tuple[GearProcess, int]:
    """MAG's gear on ``ax`` (its factory's, from rest or from ``moving``: the velocity
    and acceleration it inherits) and its master's array index: built by the
    constructors once per set of parameters and start state (a refused set raises
    there, as usual), copied with its own master for the others."""
    num, den = term.numerator, term.denominator
    key: tuple[Any, ...] = (num, type(num), den, type(den), term.counts, int(term.source),
                            rate, direction)  # fmt: skip
    v = a = 0.0
    if moving is not None:
        v, a = moving
        key = (*key, v.hex(), a.hex())
    t = templates.get(key)
    if t is None:
        p = _factory(ctx, ax, term, rate, owner, direction)(v, a)
        assert isinstance(p, GearProcess)
        templates[key] = _Template(p)
        return p, p._c[0].index
    index = ctx.index_of(term.master)  # (raises as the coupling does)
    p = _copy(t, ctx, ax, term, index, owner)
    ax.gear_direction = -1 if direction < 0 else 1
    return p, index


def _started(
    motion: Motion,
    ax: Axis,
    procs: list[Process],
    p: GearProcess,
    index: int,
    source: MasterReference,
    batch: _Batch,
    levelled: bool = True,
) -> None:
    """``Motion.start_from_rest`` of ``p`` on ``ax`` (``procs`` its empty process list;
    ``index`` its master's), the lane's admission gathered in ``batch`` (``levelled``:
    as for :func:`_join`)."""
    s = motion.s
    procs.append(p)
    i = ax.index
    if not motion.order_dirty and not _order_holds(motion, ax, i, index, batch):
        motion.order_dirty = True
    s.scalars.busy[i] = True
    s.dirty.add(i)
    lanes = motion._offer_to.get(ax.group)
    if lanes is not None and s.drive_on.item(i):
        _join(lanes, p, ax, index, source, batch, levelled)
    if p.lane is None:
        motion.lanes[ax.group].dirty = True


def _from_motion(
    motion: Motion,
    ax: Axis,
    q: Process,
    term: GearTerm,
    rate: Rate,
    owner: object,
    direction: int,
    templates: dict[tuple[Any, ...], _Template],
    batch: _Batch,
) -> GearProcess:
    """``Motion.start`` of the gear on ``ax`` when it replaces the axis's one process
    ``q`` (:func:`.take_over.sole_replaced`: a gear on a slave already geared, a new
    ratio): built from ``q``'s velocity and acceleration (:func:`_built`), then started
    and gathered for its lane as one from rest. The lanes it leaves are rebuilt in
    full (its followers read a slave composed anew)."""
    p, index, new, _ = take_over(
        motion,
        ax,
        q,
        lambda v, a: _built(motion.s, ax, term, rate, owner, direction, templates, (v, a)),
    )
    # the group's followers are levelled again at the next rebuild, as after the
    # loop's start: the slave's process left its lane (a gear from a follower lane,
    # which marks the lanes, a jog from a time-driven one, or it was composed in Python)
    motion.lanes[ax.group].dirty = True
    _started(motion, ax, new, p, index, term.source, batch, levelled=False)
    return p


def _order_holds(motion: Motion, ax: Axis, i: int, index: int, batch: _Batch) -> bool:
    """``Motion._order_holds`` of a gear on ``ax`` (index ``i``, without motion before)
    reading the master at ``index``: the master, if in the group, composes before it.
    The group's order does not change during the call (it is sorted at the next step),
    so its positions are looked up once per group."""
    at = batch.positions.get(ax.group)
    if at is None:
        motion._order_holds(ax, Process())  # (no masters: the positions cached, True)
        cached = motion._positions
        assert cached is not None
        at = batch.positions[ax.group] = cached[ax.group][1]
    here = at.get(i)
    if here is None:
        return False
    master = motion.axes[index]
    if master.group != ax.group:
        return True
    before = at.get(index)
    return before is not None and before < here


def _join(
    lanes: GroupLanes,
    p: GearProcess,
    ax: Axis,
    index: int,
    source: MasterReference,
    batch: _Batch,
    levelled: bool = True,
) -> None:
    """``GroupLanes.offer`` of the gear ``p`` just started on ``ax`` (without motion
    before), the admission itself gathered in ``batch``. ``levelled`` False: the lanes
    are levelled in full at the next rebuild (``dirty``), so whether the gear steps at
    level 0 is not worked out."""
    p.offer_pending = False  # (offered, whether a lane takes it or not)
    command = source == _COMMAND
    if command and not lanes._master_settled(index):
        return  # its master is composed in Python: so must it be
    c = p.single
    assert c is not None
    # the lane that accepts it (GearLane, FractionLane, CatchUpLane: the first of
    # ``followers`` whose ``accepts`` holds), without asking each
    followers = lanes.followers[source]
    lane: BatchedLane
    ramp = p._ramp
    if ramp is not None:
        lane = followers[2]  # type: ignore[assignment]
        assert type(lane) is CatchUpLane and type(ramp) is RateRamp
        # CatchUpLane.FIELDS: base, ratio, v_prev, accel, decel, pos, vel, acc
        row: tuple[Any, ...] = (
            ax.base, c.ratio, c.v_prev, ramp.accel, ramp.decel, ramp.position,
            ramp.velocity, ramp.acceleration,
        )  # fmt: skip
    elif not c.exact:
        lane = followers[0]  # type: ignore[assignment]
        assert type(lane) is GearLane
        # GearLane.FIELDS: base, at_lock, lock_pos, num, den, ratio, v_prev, pos, vel, acc
        row = (
            ax.base, p.at_lock, c.lock_pos, c.num, c.den, c.ratio, c.v_prev, p.position,
            p.velocity, p.acceleration,
        )  # fmt: skip
    else:
        fraction = followers[1]
        if fraction.accepts(p):
            # (a fraction gear locked at once: admitted and loaded as usual)
            fraction.admit(p, ax)
        return
    p.lane = lane
    j = batch.joining.get(id(lane))
    if j is None:
        j = batch.joining[id(lane)] = _Joining(lane)
    j.members.append((p, ax))
    j.rows.append(row)
    j.masters.append(index)
    if not levelled:
        j.at_zero = False
    elif j.at_zero and command:
        j.at_zero = _at_level_zero(lanes, ax, index, batch)


def _at_level_zero(lanes: GroupLanes, ax: Axis, index: int, batch: _Batch) -> bool:
    """A command follower of the master at ``index`` just joining a lane on ``ax``
    (which had no motion) steps at level 0 and changes no other follower's level: the
    master is in another group or its one process is in a lane stepped before every
    follower (``GroupLanes._order_command_followers``: a time-driven lane or a follower
    of an actual position), and no follower in the lanes reads ``ax``."""
    group = lanes.group.number
    master_ok = batch.masters_at_zero.get(index)
    if master_ok is None:
        first = batch.first.get(group)
        if first is None:
            first = batch.first[group] = {
                id(lane)
                for lane in (lanes.cruise, lanes.profiles, lanes.stops, lanes.scurves,
                             *lanes.followers[MasterReference.ACTUAL])
            }  # fmt: skip
        master = lanes.group.by_index.get(index)
        if master is None:
            master_ok = True
        else:
            mprocs = master._processes if master.stop_rows is None else master.processes
            master_ok = len(mprocs) == 1 and id(mprocs[0].lane) in first
        batch.masters_at_zero[index] = master_ok
    if not master_ok:
        return False
    read = batch.readers.get(group)
    if read is None:
        read = set()
        for lane in lanes.followers[_COMMAND]:
            read.update(lane.midx.tolist())
            for q, _ in lane._joining:
                read.add(lane.master_index(q))
        batch.readers[group] = read
    return ax.index not in read
