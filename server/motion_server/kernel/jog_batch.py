"""Jogs started on many axes in one call: MAJ or MC_MoveVelocity executed on N axes in
the same scan, each trapezoidal, from the same limits.

:func:`start_jogs` does what ``Controller.start`` does for each axis in order, with the
factory ``lambda v, a: JogProcess(axis period, target, limits, v, a, owner)`` and
``replace=(ProcessKind.JOG,)``, and leaves the very same state (the tests compare the
two attribute by attribute and step them side by side). What it saves is the per-axis
work that does not depend on the axis: the limits are judged once, and on an axis
without motion, override or preloaded cam the process and its profile are copied from
the first one built by the constructors, then given their target, judged as the
constructor judges it (:func:`.trapezoid.judge_velocity_plan`, the same errors), and
admitted to their profile lanes together. Other axes are started through
``Motion.start`` with the factory. As with the loop, a
:class:`.errors.MotionError` on an axis leaves the axes before it started.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .axis import Axis
from .enums import ProcessKind
from .errors import ErrorCode, MotionError
from .lanes import GroupLanes
from .limits import Limits
from .motion import Motion
from .processes import JogProcess, Process, ProcessFactory
from .trapezoid import TrapezoidProfile, judge_velocity_plan

#: what a jog replaces (Logix MAJ: another jog; the PLCopen aborting mode uses start)
_REPLACE = (ProcessKind.JOG,)


def start_jogs(
    motion: Motion,
    axes: Sequence[Axis],
    targets: Sequence[float],
    limits: Limits,
    owners: Sequence[object] | None = None,
) -> list[Process]:
    """Start a jog at ``targets[k]`` (signed velocity) on ``axes[k]``, owned by
    ``owners[k]`` (None: no owner), for every k in order: the processes started."""
    if len(targets) != len(axes) or (owners is not None and len(owners) != len(axes)):
        raise ValueError("one target (and one owner, if any) per axis")
    limits = limits.validated()
    started: list[Process] = []
    # jogs from rest bound for a profile lane, admitted together (before anything else
    # is started, so that every lane's members join in the loop's order)
    joining: list[tuple[GroupLanes, Process, Axis]] = []
    # the first jog built by the constructors on an axis at rest: its state, and its
    # profile's, right after construction (before it starts: nothing else set yet)
    proto: tuple[float, dict[str, object], dict[str, object], tuple[float, ...]] | None = None
    try:
        for k, ax in enumerate(axes):
            target = targets[k]
            owner = None if owners is None else owners[k]
            procs = ax._processes if ax.stop_rows is None else ax.processes
            at_rest = (
                not procs and not ax.preloaded_cams and ax.override.neutral and limits.trapezoidal
            )
            if not at_rest:
                _admit(joining)
                started.append(
                    motion.start(ax, _factory(ax.period, target, limits, owner), _REPLACE)
                )
                continue
            if proto is None or proto[0] != ax.period:
                p = JogProcess(ax.period, target, limits, 0.0, 0.0, owner)
                prof = p.profile
                assert isinstance(prof, TrapezoidProfile) and prof.request is not None
                proto = (ax.period, dict(vars(p)), dict(vars(prof)), prof.request)
            else:
                p = _copy(proto, target, limits, owner)
                lanes = motion.lanes_for(ax)
                if lanes is not None and ax.buffered is None:
                    # Motion.start_from_rest of a trapezoidal jog just built, with its
                    # admission (to the profile lane: planned, not finished) deferred
                    procs.append(p)
                    i = ax.index
                    motion.s.scalars.busy[i] = True
                    motion.s.dirty.add(i)
                    p.offer_pending = False
                    joining.append((lanes, p, ax))
                    started.append(p)
                    continue
            _admit(joining)
            motion.start_from_rest(ax, procs, p, _REPLACE)
            started.append(p)
    finally:
        # (also when a jog is refused: those before it started, as in the loop)
        _admit(joining)
    return started


def _admit(joining: list[tuple[GroupLanes, Process, Axis]]) -> None:
    """Admit the deferred jogs to their groups' profile lanes, in order; empty the list."""
    for lanes, p, ax in joining:
        lanes.profiles.admit(p, ax)
    joining.clear()


def _copy(
    proto: tuple[float, dict[str, object], dict[str, object], tuple[float, ...]],
    target: float,
    limits: Limits,
    owner: object,
) -> JogProcess:
    """``JogProcess(dt, target, limits, 0.0, 0.0, owner)`` from the state of another
    built from rest with the same dt and limits: the attributes that depend on the
    target (and owner) set as the constructors set them, the target judged as
    ``TrapezoidProfile.to_velocity`` judges it."""
    if not math.isfinite(target):
        raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target velocity must be finite")
    _, state, prof_state, request = proto
    velocity = float(target)
    req = (request[0], request[1], velocity, limits.acceleration, limits.deceleration)
    judge_velocity_plan(*req)
    prof = object.__new__(TrapezoidProfile)
    prof.__dict__.update(prof_state)
    prof.request = req
    prof._target_velocity = velocity
    p = object.__new__(JogProcess)
    p.__dict__.update(state)
    p.owner = owner
    p.target_velocity = target
    p.profile = prof
    return p


def _factory(dt: float, target: float, limits: Limits, owner: object) -> ProcessFactory:
    def make(v: float, a: float) -> JogProcess:
        return JogProcess(dt, target, limits, v, a, owner)

    return make
