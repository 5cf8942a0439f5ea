"""Jogs started on many axes in one call: MAJ or MC_MoveVelocity executed on N axes in
the same scan, from the same limits (trapezoidal or jerk-limited).

:func:`start_jogs` does what ``Controller.start`` does for each axis in order, with the
factory ``lambda v, a: JogProcess(axis period, target, limits, v, a, owner)`` and
``replace=(ProcessKind.JOG,)``, and leaves the very same state (the tests compare the
two attribute by attribute and step them side by side). What it saves is the per-axis
work that does not depend on the axis:

- the limits are judged once; on an axis without motion, override or preloaded cam a
  jog from rest is a function of the period and the target only, so it is built by the
  constructors once per (period, target) (:class:`_Protos`) and copied for every other
  axis (a trapezoidal jog's profile is also copied to a new target, judged as the
  constructor judges it: :func:`.trapezoid.judge_velocity_plan`, the same errors);
- the jogs from rest bound for a profile lane (trapezoidal) or the S-curve lane
  (jerk-limited, closed form) join it as one batch: their lane columns, plans included,
  are computed here, one plan per prototype spread over the batch's rows
  (:meth:`.lanes.ramps.ProfileLane.admit_batch`,
  :meth:`.lanes.scurve.SCurveLane.admit_batch`), so the first step takes them as they
  are instead of reading every jog's request and planning it.

- a jog that replaces the one process of an axis already moving (MAJ on a jogging
  axis: a new speed) is built from that process's velocity and acceleration, once per
  (target, velocity, acceleration) and copied, and joins the batch as a jog from rest
  does; the process it replaces leaves its time-driven lane without levelling the
  followers again (``Lane.pass_on``: the axis is in a time-driven lane before and after).

The jogs are still one object each (a copy costs about a microsecond): the rows of a
lane whose objects are made only when read, as a group stop's (:mod:`.lanes.stop_rows`),
are not done for jogs.

Other axes (overridden, with a preloaded cam, buffered, more than one process, a jog
whose plan the constructor had to build or hand to ruckig) are started through
``Motion.start`` or ``Motion.start_from_rest`` as the loop starts them. As with the
loop, a :class:`.errors.MotionError` on an axis leaves the axes before it started.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np

from .axis import Axis
from .enums import ProcessKind
from .errors import ErrorCode, MotionError
from .lanes import GroupLanes
from .limits import Limits
from .motion import Motion
from .override import NEUTRAL
from .processes import JogProcess, Process, ProcessFactory
from .scurve import SCurveProfile
from .take_over import LastStart, join, sole_replaced, take_over
from .trapezoid import TrapezoidProfile, judge_velocity_plan

#: a group whose lanes were not looked up yet
_UNKNOWN: Any = object()

#: what a jog replaces (Logix MAJ: another jog; the PLCopen aborting mode uses start)
_REPLACE = (ProcessKind.JOG,)


class _Proto:
    """A jog from rest built by the constructors: its state and its profile's right
    after construction, and whether copies of it join a lane as a batch (``lane_kind``:
    "profiles", "scurves" or None: admitted one by one, or not copied at all)."""

    __slots__ = ("copyable", "lane_kind", "period", "prof_state", "request", "row", "state")

    def __init__(self, p: JogProcess, period: float) -> None:
        prof = p.profile
        self.period = period
        self.state = dict(vars(p))
        self.prof_state = dict(vars(prof))
        self.request: tuple[float, ...] | None = getattr(prof, "request", None)
        # a profile whose plan is still a request holds nothing mutable: copies share it
        self.copyable = False
        self.lane_kind: str | None = None
        #: the lane row after the base (what the lane's batch reads of every copy)
        self.row: tuple[float, ...] = ()
        kinematics = (p.position, p.velocity, p.acceleration)
        if isinstance(prof, TrapezoidProfile) and prof.request is not None:
            self.copyable = True
            self.lane_kind = "profiles"
            self.row = (prof.dt, *kinematics, *prof.request)
        elif isinstance(prof, SCurveProfile) and prof.request is not None and prof.ruckig is None:
            self.copyable = True
            self.lane_kind = "scurves"
            self.row = (float(prof.cycles), prof.dt, *kinematics, *prof.request)


class _Protos:
    """The jogs from rest built so far, by (period, target's bits), and the trapezoidal
    one of each period that copies take a new target from."""

    def __init__(self, limits: Limits) -> None:
        self.limits = limits
        self.by_target: dict[tuple[float, str], _Proto] = {}
        self.trapezoid: dict[float, _Proto] = {}
        #: the jogs from motion built so far, by (period, target's, velocity's and
        #: acceleration's bits)
        self.moving: dict[tuple[float, str, str, str], _Proto] = {}
        #: the jog from motion last made
        self.last: LastStart[_Proto] = LastStart()

    def make(self, period: float, target: float, owner: object) -> tuple[JogProcess, _Proto]:
        """``JogProcess(period, target, limits, 0.0, 0.0, owner)`` and its prototype."""
        if not math.isfinite(target):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target velocity must be finite")
        velocity = float(target)
        key = (period, velocity.hex())
        proto = self.by_target.get(key)
        if proto is not None and proto.copyable:
            return _copy(proto, target, owner), proto
        if proto is None:
            base = self.trapezoid.get(period)
            if base is not None:
                # a trapezoidal jog from rest to another target: the constructor's
                # judgement and request, the rest copied
                req = (base.request[0], base.request[1], velocity, *base.request[3:])  # type: ignore[index]
                judge_velocity_plan(*req)
                p = _copy(base, target, owner, req)
                proto = self._keep(key, p, period)
                return p, proto
        p = JogProcess(period, target, self.limits, 0.0, 0.0, owner)
        proto = self._keep(key, p, period)
        return p, proto

    def make_moving(
        self, period: float, target: float, owner: object, v: float, a: float
    ) -> tuple[JogProcess, _Proto]:
        """``JogProcess(period, target, limits, v, a, owner)`` and its prototype: built
        once per (period, target, v, a) and copied, when it can be copied (a
        jerk-limited one whose plan the constructor handed to ruckig is built each
        time). A trapezoidal profile's request is the only part that depends on ``v``
        (the acceleration ``a`` is kept as the profile's): a trapezoidal jog from rest
        of the same period, if one was built, is copied with its velocity,
        acceleration and request replaced, judged as the constructor judges it."""
        proto = self.last.get(target, period, v, a)
        if proto is not None:
            return _copy(proto, target, owner), proto
        if not math.isfinite(target):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target velocity must be finite")
        velocity = float(target)
        key = (period, velocity.hex(), v.hex(), a.hex())
        proto = self.moving.get(key)
        if proto is not None:
            self.last.keep(target, period, v, a, proto)
            return _copy(proto, target, owner), proto
        base = self.trapezoid.get(period)
        if base is None:
            p = JogProcess(period, target, self.limits, v, a, owner)
        else:
            req = (base.request[0], float(v), velocity, *base.request[3:])  # type: ignore[index]
            judge_velocity_plan(*req)
            p = _copy(base, target, owner, req, (v, a))
        proto = _Proto(p, period)
        if proto.copyable:
            self.moving[key] = proto
            self.last.keep(target, period, v, a, proto)
        return p, proto

    def _keep(self, key: tuple[float, str], p: JogProcess, period: float) -> _Proto:
        proto = _Proto(p, period)
        self.by_target[key] = proto
        if proto.lane_kind == "profiles":
            self.trapezoid.setdefault(period, proto)
        return proto


def _copy(
    proto: _Proto,
    target: float,
    owner: object,
    request: tuple[float, ...] | None = None,
    kinematics: tuple[float, float] | None = None,
) -> JogProcess:
    """A copy of ``proto``'s jog with its own owner, target (as given: an int stays an
    int) and profile (``request``: a new trapezoidal request to another target;
    ``kinematics``: the velocity and acceleration it starts from, the profile's as
    floats, as its constructor keeps them)."""
    prof = object.__new__(type(proto.state["profile"]))
    prof.__dict__.update(proto.prof_state)
    if request is not None:
        prof.request = request
        prof._target_velocity = request[2]
    p = object.__new__(JogProcess)
    p.__dict__.update(proto.state)
    if kinematics is not None:
        p.velocity, p.acceleration = kinematics
        prof.velocity, prof.acceleration = float(kinematics[0]), float(kinematics[1])
    p.owner = owner
    p.target_velocity = target
    p.profile = prof
    return p


class _Joining:
    """Jogs from rest whose admission to their group's lanes is deferred, so that those
    bound for the same lane join as one batch (in the loop's order: the batch is closed,
    :meth:`admit`, before anything else is started)."""

    def __init__(self, motion: Motion) -> None:
        self._motion = motion
        self._s = motion.s
        #: Motion.lanes_for, its group's part looked up once per group
        self._offered: dict[int, GroupLanes | None] = {}
        self.lanes: GroupLanes | None = None
        self.kind: str | None = None
        self.pairs: list[tuple[Process, Axis]] = []
        #: the prototype of each process of the batch (what its lane row is copied from)
        self.protos: list[Any] = []

    def take(self, ax: Axis, procs: list[Process], p: Process, proto: Any, kind: str) -> bool:
        """``Motion.start_from_rest`` of ``p``, just built on ``ax`` (without motion,
        nothing buffered; ``procs`` its empty process list), with its admission to its
        group's ``kind`` lane and its axis's busy flag deferred to the batch (``proto``:
        what its lane row is copied from); False when the group's lanes do not take it
        now (the caller starts it)."""
        group = ax.group
        lanes = self._offered.get(group, _UNKNOWN)
        if lanes is _UNKNOWN:
            motion = self._motion
            lanes = self._offered[group] = motion.lanes[group] if motion.offers(group) else None
        if lanes is None or not self._s.drive_on.item(ax.index):
            return False
        procs.append(p)
        p.offer_pending = False
        if lanes is not self.lanes or kind != self.kind:
            self.open(lanes, kind)
        self.pairs.append((p, ax))
        self.protos.append(proto)
        return True

    def take_moving(
        self,
        ax: Axis,
        new: list[Process],
        p: Process,
        proto: Any,
        kind: str | None,
        lanes: GroupLanes | None,
    ) -> None:
        """The rest of a start :func:`.take_over.take_over` began on ``ax`` (``new`` the
        axis's new process list, ``lanes`` what it returned): ``p`` joins this batch
        when its ``kind`` of lane takes it, else it starts as ``Motion.start`` ends, the
        lanes marked for the full rebuild if the process it replaced left a
        time-driven lane."""
        if kind is not None and self.take(ax, new, p, proto, kind):
            return
        if lanes is not None:
            lanes.dirty = True
        self.admit()
        join(self._motion, ax, new, p)

    def take_from_rest(
        self,
        ax: Axis,
        procs: list[Process],
        p: Process,
        proto: Any,
        kind: str | None,
        replace: Collection[ProcessKind] | None,
    ) -> None:
        """The rest of a start on ``ax`` without motion (``procs`` its empty process
        list), once ``p`` is built: ``p`` joins this batch when its ``kind`` of lane
        takes it and nothing is buffered, else it starts as ``Motion.start_from_rest``
        starts it, after the batch held is admitted (the loop's order)."""
        if kind is not None and ax.buffered is None and self.take(ax, procs, p, proto, kind):
            return
        self.admit()
        self._motion.start_from_rest(ax, procs, p, replace)

    def open(self, lanes: GroupLanes, kind: str) -> None:
        """Close the batch held (:meth:`admit`) and start one for ``lanes``' ``kind``."""
        self.admit()
        self.lanes, self.kind = lanes, kind

    def admit(self) -> None:
        """Admit the batch held: its axes busy (``Axis.motion_changed``), the jogs'
        columns computed once per prototype; empty it."""
        pairs, lanes = self.pairs, self.lanes
        if not pairs or lanes is None:
            return
        protos = self.protos
        axes = [ax for _, ax in pairs]
        idx = [ax.index for ax in axes]
        self._s.busy[idx] = True
        self._s.dirty.update(idx)
        first = protos[0]
        which: np.ndarray | None = None
        kinds: list[tuple[float, ...]] = [first.row]
        if protos.count(first) != len(protos):
            seen: dict[int, int] = {}
            order = []
            for q in protos:
                j = seen.get(id(q))
                if j is None:
                    j = seen[id(q)] = len(seen)
                    if j:
                        kinds.append(q.row)
                order.append(j)
            which = np.array(order, dtype=np.intp)
        base = np.array([ax.base for ax in axes], dtype=float)
        self._hand_to(lanes, pairs, base, kinds, which)
        self.pairs = []
        self.protos = []
        self.lanes = self.kind = None

    def _hand_to(
        self,
        lanes: GroupLanes,
        pairs: list[tuple[Process, Axis]],
        base: np.ndarray,
        kinds: list[tuple[float, ...]],
        which: np.ndarray | None,
    ) -> None:
        """The lane's admission of the batch: ``kinds`` the distinct rows of its
        prototypes (:attr:`_Proto.row`), ``which`` the kind of each (None: the first)."""
        self._lane(lanes).admit_batch(pairs, base, kinds, which)

    def _lane(self, lanes: GroupLanes) -> Any:
        """The lane of ``lanes`` the batch is bound for (its ``kind``)."""
        return lanes.profiles if self.kind == "profiles" else lanes.scurves


def start_jogs(
    motion: Motion,
    axes: Sequence[Axis],
    targets: Sequence[float],
    limits: Limits,
    owners: Sequence[object] | None = None,
    replace: Collection[ProcessKind] | None = _REPLACE,
) -> list[Process]:
    """Start a jog at ``targets[k]`` (signed velocity) on ``axes[k]``, owned by
    ``owners[k]`` (None: no owner), for every k in order: the processes started.
    ``replace``: what each jog supersedes, as for ``Motion.start`` (another jog, as MAJ;
    None: every process, MC_MoveVelocity's aborting mode)."""
    if len(targets) != len(axes) or (owners is not None and len(owners) != len(axes)):
        raise ValueError("one target (and one owner, if any) per axis")
    limits = limits.validated()
    started: list[Process] = []
    joining = _Joining(motion)
    protos = _Protos(limits)
    # the jog last built or copied: the next axis with the same target (the same
    # object, as a batch of equal targets has) and period is a copy of it
    last: tuple[object, float, _Proto] | None = None
    try:
        for k, ax in enumerate(axes):
            target = targets[k]
            owner = None if owners is None else owners[k]
            procs = ax._processes if ax.stop_rows is None else ax.processes
            if (
                procs
                or ax.preloaded_cams
                or (ax.override is not NEUTRAL and not ax.override.neutral)
            ):
                p = _from_motion(motion, ax, procs, target, owner, protos, replace, joining)
                if p is not None:
                    started.append(p)
                    continue
                joining.admit()
                started.append(
                    motion.start(ax, _factory(ax.period, target, limits, owner), replace)
                )
                continue
            if last is not None and last[0] is target and last[1] == ax.period:
                proto = last[2]
                p = _copy(proto, target, owner)
            else:
                p, proto = protos.make(ax.period, target, owner)
                last = (target, ax.period, proto) if proto.copyable else None
            # (to its lane: planned, not finished)
            joining.take_from_rest(ax, procs, p, proto, proto.lane_kind, replace)
            started.append(p)
    finally:
        # (also when a jog is refused: those before it started, as in the loop)
        joining.admit()
    return started


def _from_motion(
    motion: Motion,
    ax: Axis,
    procs: list[Process],
    target: float,
    owner: object,
    protos: _Protos,
    replace: Collection[ProcessKind] | None,
    joining: _Joining,
) -> JogProcess | None:
    """``Motion.start`` of a jog on ``ax`` when it replaces the axis's one
    process (:func:`.take_over.sole_replaced`: what the usual MAJ on a jogging axis
    finds): built from that process's velocity and acceleration
    (:meth:`_Protos.make_moving`), it joins the batch of its lane as a jog from rest
    does. None, with nothing done, for any other axis (the caller starts it)."""
    q = sole_replaced(ax, procs, replace)
    if q is None:
        return None
    p, proto, new, lanes = take_over(
        motion, ax, q, lambda v, a: protos.make_moving(ax.period, target, owner, v, a)
    )
    joining.take_moving(ax, new, p, proto, proto.lane_kind, lanes)
    return p


def _factory(dt: float, target: float, limits: Limits, owner: object) -> ProcessFactory:
    def make(v: float, a: float) -> JogProcess:
        return JogProcess(dt, target, limits, v, a, owner)

    return make
