"""Moves started on many axes in one call: MAM, MC_MoveAbsolute or MC_MoveRelative
executed on N axes in the same scan, with the same limits.

:func:`start_moves` does what ``Controller.start`` does for each axis in order, with the
factory ``lambda v, a: MoveProcess(axis period, distance, limits, v, a, owner,
landing)`` and ``replace=(ProcessKind.MOVE,)`` (MAM without Merge; None, every process,
for the PLCopen aborting mode), and leaves the very same state (the tests compare the
two attribute by attribute and step them side by side). What it saves is the per-axis
work that does not depend on the axis:

- a trapezoidal move from rest is a function of the period and the distance only: it is
  built by the constructors (its plan by :func:`.trapezoid.plan_position`) once per
  (period, distance) and copied for every other axis (the plan is immutable: copies
  share it); when the axes at rest have many distances (absolute moves to one target
  from different positions), their plans are built together
  (:func:`.move_plan.position_plans`) and each move is a copy of the first with its own
  plan;
- so is a jerk-limited move from rest, planned in closed form
  (:mod:`.scurve_position`; many distances together:
  :func:`.scurve_position_plan.plans_from_rest`);
- the moves from rest bound for the profile lane or the S-curve lane join it as one
  batch, their lane rows read once per prototype (:meth:`.lanes.ramps.PlanLane.
  admit_planned`), so the first step takes them as they are instead of reading every
  move's plan.

- a move that replaces the one process of an axis already moving (the aborting mode on
  a jogging axis; :mod:`.take_over`) is built from that process's velocity and
  acceleration, once per (period, distance, velocity, acceleration) and copied (when
  its plan is a closed form's), and joins the batch as a move from rest does.

Other axes (overridden, with a preloaded cam, more than one process or a process not
replaced) are started through ``Motion.start`` or ``Motion.start_from_rest`` as the
loop starts them, and so are the jerk-limited moves ruckig plans.
As with the loop, a :class:`.errors.MotionError` on an axis leaves the axes before it
started.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np

from .axis import Axis
from .enums import ProcessKind
from .jog_batch import _Joining
from .lanes import GroupLanes
from .lanes.scurve import plan_row, planned_row
from .limits import Limits
from .motion import Motion
from .move_plan import position_plans
from .override import NEUTRAL
from .processes import MoveProcess, Process, ProcessFactory
from .scurve import JerkPlan, SCurveProfile
from .scurve_position_plan import plans_from_rest
from .take_over import LastStart, sole_replaced, take_over
from .trapezoid import Plan, TrapezoidProfile

#: what a move replaces (Logix MAM without Merge)
_REPLACE = (ProcessKind.MOVE,)
#: distinct distances from rest from which their plans are built together
AHEAD = 4


class _Proto:
    """A move built by the constructors: its state and its profile's right after
    construction, and its row of its lane's ``FIELDS`` after the base (None: not
    copied): a trapezoidal move's in the profile lane, a jerk-limited move planned in
    closed form in the S-curve lane (a move ruckig plans is not copied)."""

    __slots__ = ("lane_kind", "prof_state", "prof_type", "row", "state")

    def __init__(self, p: MoveProcess) -> None:
        prof = p.profile
        self.state = dict(vars(p))
        self.prof_state = dict(vars(prof))
        self.prof_type = type(prof)
        self.row: tuple[Any, ...] | None = None
        #: the lane copies of this move join as a batch, if it has a row there
        self.lane_kind: str | None = None
        if type(prof) is TrapezoidProfile and prof.request is None:
            plan = prof.plan
            assert plan is not None  # (to_position plans at once)
            self.row = _row(p, prof, plan)
            self.lane_kind = "profiles"
        elif type(prof) is SCurveProfile and prof.ruckig is None and prof.planned:
            self.row = planned_row(p)
            self.lane_kind = "scurves"

    @classmethod
    def planned(cls, template: _Proto, distance: float, plan: Plan | JerkPlan) -> _Proto:
        """The prototype of a move from rest of ``distance`` planned ahead (``plan``): the
        template's (a move from rest of the same period and limits, trapezoidal or
        jerk-limited as ``plan``) but its plan and target (what ``to_position`` sets from
        them)."""
        head = template.row
        assert head is not None  # (a template has a lane row)
        proto = cls.__new__(cls)
        proto.prof_type = template.prof_type
        proto.lane_kind = template.lane_kind
        proto.state = template.state  # (the distance is set in every copy)
        proto.prof_state = {
            **template.prof_state,
            "_plan": plan,
            "_target_position": float(distance),
        }
        if isinstance(plan, JerkPlan):
            # (the template's cycles, dt and kinematics, before and after its plan)
            proto.row = plan_row(head[0], head[1], head[-6:-3], plan)
        else:
            proto.row = (*head[:2], plan.done, plan.start, plan.pos, plan.vel, plan.acc,
                         plan.half, *head[8:11], plan.end, plan.end_position,
                         plan.end_velocity, plan.landing)  # fmt: skip
        return proto


def _row(p: MoveProcess, prof: TrapezoidProfile, plan: Plan) -> tuple[Any, ...]:
    """``ProfileLane._load`` of a move from rest after the base."""
    return (
        float(prof.cycles), prof.dt, plan.done, plan.start, plan.pos, plan.vel, plan.acc,
        plan.half, p.position, p.velocity, p.acceleration, plan.end, plan.end_position,
        plan.end_velocity, plan.landing,
    )  # fmt: skip


def _key(period: float, distance: float) -> tuple[float, str] | None:
    """What a move from rest depends on besides the limits: the period and the
    distance's bits (None: not a float, the constructor refuses or converts it)."""
    try:
        return (period, float(distance).hex())
    except (OverflowError, TypeError, ValueError):
        return None


def _plans_ahead(
    axes: Sequence[Axis], distances: Sequence[float], limits: Limits
) -> dict[tuple[float, str], Plan | JerkPlan]:
    """The plans of the moves from rest of ``axes`` (those without motion, override or
    preloaded cam, as :func:`start_moves` finds them) by :func:`_key`, built together
    when they have at least :data:`AHEAD` distinct distances: trapezoidal
    (:func:`.move_plan.position_plans`) or jerk-limited
    (:func:`.scurve_position_plan.plans_from_rest`); only those the scalar planner would
    build (the others are planned, and refused or left to ruckig, by the constructor in
    the loop's order)."""
    wanted: dict[tuple[float, str], float] = {}
    for ax, distance in zip(axes, distances, strict=True):
        if ax.stop_rows is not None or ax._processes or ax.preloaded_cams:
            continue
        if ax.override is not NEUTRAL and not ax.override.neutral:
            continue
        key = _key(ax.period, distance)
        if key is not None:
            wanted.setdefault(key, float(distance))
    if len(wanted) < AHEAD:
        return {}
    if not limits.trapezoidal:
        return _jerk_plans_ahead(wanted, limits)
    keys = list(wanted)
    n = len(keys)
    zeros = np.zeros(n)
    plans = position_plans(
        np.array([k[0] for k in keys]),
        zeros,
        zeros,
        np.array(list(wanted.values())),
        np.full(n, limits.velocity),
        np.full(n, limits.acceleration),
        np.full(n, limits.deceleration),
    )
    start, pos, vel = plans.start.tolist(), plans.pos.tolist(), plans.vel.tolist()
    acc, half = plans.acc.tolist(), plans.half.tolist()
    end, done = plans.end.tolist(), plans.done.tolist()
    ahead: dict[tuple[float, str], Plan | JerkPlan] = {}
    for j in np.flatnonzero(plans.ok).tolist():
        key = keys[j]
        ahead[key] = Plan(
            tuple(start[j]), tuple(pos[j]), tuple(vel[j]), tuple(acc[j]), tuple(half[j]),
            end[j], done[j], wanted[key], 0.0, True,
        )  # fmt: skip
    return ahead


def _jerk_plans_ahead(
    wanted: dict[tuple[float, str], float], limits: Limits
) -> dict[tuple[float, str], Plan | JerkPlan]:
    """:func:`_plans_ahead` of jerk-limited moves: one pass per period."""
    ahead: dict[tuple[float, str], Plan | JerkPlan] = {}
    for period in {key[0] for key in wanted}:
        keys = [key for key in wanted if key[0] == period and math.isfinite(wanted[key])]
        plans = plans_from_rest(period, [wanted[key] for key in keys], limits)
        ahead.update((key, plan) for key, plan in zip(keys, plans, strict=True) if plan)
    return ahead


def _copy(proto: _Proto, distance: float, owner: object, landing: float | None) -> MoveProcess:
    """A copy of ``proto``'s move with its own owner, distance (as given: an int stays
    an int), landing and profile (its plan shared: plans are immutable)."""
    prof = object.__new__(proto.prof_type)
    prof.__dict__.update(proto.prof_state)
    p = object.__new__(MoveProcess)
    p.__dict__.update(proto.state)
    p.owner = owner
    p.displacement = distance
    p.landing = landing
    p.profile = prof
    return p


class _FromRest:
    """The moves from rest built so far, by (period, distance's bits): the others alike
    are copies. With many distances planned ahead (:func:`_plans_ahead`), a distance's
    first move is a copy of its period's first with its own plan. The last one is kept
    for the usual batch (one distance object for every axis)."""

    def __init__(self, limits: Limits, ahead: dict[tuple[float, str], Plan | JerkPlan]) -> None:
        self.limits = limits
        self.ahead = ahead
        self.by_key: dict[tuple[float, str], _Proto] = {}
        #: per period, the first move from rest the constructors built with a lane row
        self.templates: dict[float, _Proto] = {}
        self.last: LastStart[_Proto] = LastStart()

    def make(
        self, period: float, distance: float, owner: object, landing: float | None
    ) -> tuple[MoveProcess, _Proto]:
        """``MoveProcess(period, distance, limits, 0.0, 0.0, owner, landing)`` and its
        prototype, when ``last`` does not hold it (the caller asks it first)."""
        key = _key(period, distance)
        proto = None if key is None else self.by_key.get(key)
        if proto is None and key is not None and key in self.ahead:
            template = self.templates.get(period)
            if template is not None:
                proto = _Proto.planned(template, distance, self.ahead[key])
                self.by_key[key] = proto
        if proto is not None and proto.row is not None:
            p = _copy(proto, distance, owner, landing)
        else:
            # (a distance that is not a finite number raises here)
            p = MoveProcess(period, distance, self.limits, 0.0, 0.0, owner, landing)
            proto = _Proto(p)
            if key is not None:
                self.by_key.setdefault(key, proto)
            if proto.row is not None:
                self.templates.setdefault(period, proto)
        if proto.row is not None and key is not None:
            self.last.keep(distance, period, 0.0, 0.0, proto)
        return p, proto


class _FromMotion:
    """The moves from motion built so far (a move replacing the one process
    of an axis already moving: :mod:`.take_over`), by (period, distance's, velocity's
    and acceleration's bits): the others alike are copies. The last one is kept for the
    usual batch (one distance object, every axis at the same speed)."""

    def __init__(self, limits: Limits) -> None:
        self.limits = limits
        self.by_key: dict[tuple[float, str, str, str], _Proto] = {}
        self.last: LastStart[_Proto] = LastStart()

    def make(
        self,
        period: float,
        distance: float,
        owner: object,
        landing: float | None,
        v: float,
        a: float,
    ) -> tuple[MoveProcess, _Proto]:
        """``MoveProcess(period, distance, limits, v, a, owner, landing)`` and its
        prototype."""
        proto = self.last.get(distance, period, v, a)
        if proto is not None:
            return _copy(proto, distance, owner, landing), proto
        key = _key(period, distance)
        full = None if key is None else (*key, v.hex(), a.hex())
        proto = None if full is None else self.by_key.get(full)
        if proto is not None:
            p = _copy(proto, distance, owner, landing)
        else:
            # (a distance that is not a finite number raises here)
            p = MoveProcess(period, distance, self.limits, v, a, owner, landing)
            proto = _Proto(p)
            if full is None or proto.row is None:
                return p, proto
            self.by_key[full] = proto
        self.last.keep(distance, period, v, a, proto)
        return p, proto


class _MoveJoining(_Joining):
    """The moves bound for one profile or S-curve lane, admitted as one batch."""

    def _hand_to(
        self,
        lanes: GroupLanes,
        pairs: list[tuple[Process, Axis]],
        base: np.ndarray,
        kinds: list[tuple[float, ...]],
        which: np.ndarray | None,
    ) -> None:
        self._lane(lanes).admit_planned(pairs, base, kinds, which)


def start_moves(
    motion: Motion,
    axes: Sequence[Axis],
    distances: Sequence[float],
    limits: Limits,
    owners: Sequence[object] | None = None,
    landings: Sequence[float | None] | None = None,
    replace: Collection[ProcessKind] | None = _REPLACE,
) -> list[Process]:
    """Start a move of ``distances[k]`` on ``axes[k]``, owned by ``owners[k]`` (None: no
    owner), landing on ``landings[k]`` (the unwound target of an absolute or rotary
    move; None: none), for every k in order: the processes started. ``replace``: what
    each move supersedes, as for ``Motion.start`` (a move, as MAM; None: every process,
    the PLCopen aborting mode)."""
    n = len(axes)
    if (
        len(distances) != n
        or (owners is not None and len(owners) != n)
        or (landings is not None and len(landings) != n)
    ):
        raise ValueError("one distance (and one owner and landing, if any) per axis")
    limits = limits.validated()
    started: list[Process] = []
    joining = _MoveJoining(motion)
    resting = _FromRest(limits, _plans_ahead(axes, distances, limits))
    last = resting.last
    moving = _FromMotion(limits)
    try:
        for k, ax in enumerate(axes):
            distance = distances[k]
            owner = None if owners is None else owners[k]
            landing = None if landings is None else landings[k]
            procs = ax._processes if ax.stop_rows is None else ax.processes
            if (
                procs
                or ax.preloaded_cams
                or (ax.override is not NEUTRAL and not ax.override.neutral)
            ):
                q = sole_replaced(ax, procs, replace)
                if q is not None:
                    started.append(
                        _from_motion(motion, ax, q, joining, moving, distance, owner, landing)
                    )
                    continue
                joining.admit()
                make = _factory(ax.period, distance, limits, owner, landing)
                started.append(motion.start(ax, make, replace))
                continue
            # (the usual batch, one distance object for every axis, finds its prototype
            # here, without a call per axis)
            proto = last.get(distance, ax.period, 0.0, 0.0)
            if proto is not None:
                p = _copy(proto, distance, owner, landing)
            else:
                p, proto = resting.make(ax.period, distance, owner, landing)
            joining.take_from_rest(ax, procs, p, proto, proto.lane_kind, replace)
            started.append(p)
    finally:
        # (also when a move is refused: those before it started, as in the loop)
        joining.admit()
    return started


def _from_motion(
    motion: Motion,
    ax: Axis,
    q: Process,
    joining: _MoveJoining,
    moving: _FromMotion,
    distance: float,
    owner: object,
    landing: float | None,
) -> MoveProcess:
    """``Motion.start`` of a move of ``distance`` on ``ax``, replacing its one process
    ``q`` (:func:`.take_over.sole_replaced`): built by ``moving`` from ``q``'s velocity
    and acceleration, it joins the batch of its lane as a move from rest does."""
    p, proto, new, lanes = take_over(
        motion, ax, q, lambda v, a: moving.make(ax.period, distance, owner, landing, v, a)
    )
    joining.take_moving(ax, new, p, proto, proto.lane_kind, lanes)
    return p


def _factory(
    dt: float, distance: float, limits: Limits, owner: object, landing: float | None
) -> ProcessFactory:
    def make(v: float, a: float) -> MoveProcess:
        return MoveProcess(dt, distance, limits, v, a, owner, landing)

    return make
