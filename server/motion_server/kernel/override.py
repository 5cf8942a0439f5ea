"""Velocity, acceleration and jerk overrides of an axis (PLCopen MC_SetOverride).

An axis holds one :class:`Override`; while it differs from 1 it scales the programmed
dynamics of the axis's time-driven motion, the moves and jogs (:class:`~.processes.MoveProcess`,
:class:`~.processes.JogProcess`): velocity by ``velocity``, acceleration and deceleration
by ``acceleration``, jerk by ``jerk``. A change of factors re-plans each such process from
where it is, toward its own target, with its programmed limits scaled; a process started
while an override is set starts with scaled limits. A re-planned profile is an ordinary
profile: the fast lanes step it like any other.

Velocity factor 0 brings the motion to rest without ending it (PLCopen: "VelFactor = 0.0
... stops the axis without changing the state"): a move pauses short of its target, a
jog ramps to zero; a later factor above 0 resumes them. Stops, gears and other
master-driven motion, superimposed moves and homing are not scaled.
"""

from __future__ import annotations

from dataclasses import dataclass

from .errors import MotionError
from .limits import Limits
from .processes import JogProcess, MoveProcess, Process


@dataclass(frozen=True)
class Override:
    """Factors of an axis's override (1.0 = 100 %)."""

    velocity: float = 1.0
    acceleration: float = 1.0
    jerk: float = 1.0

    @property
    def neutral(self) -> bool:
        return self.velocity == 1.0 and self.acceleration == 1.0 and self.jerk == 1.0


NEUTRAL = Override()


def overridable(p: Process) -> bool:
    """Only plain moves and jogs: subclasses (superimposed moves) are not scaled."""
    return type(p) in (MoveProcess, JogProcess) and p.active


def scaled(limits: Limits, f: Override) -> Limits:
    """``limits`` with the factors applied; at velocity factor 0 the velocity limit keeps
    its programmed value (the target is rest, the limit is not used)."""
    v = limits.velocity * f.velocity if f.velocity > 0.0 else limits.velocity
    return Limits(
        v, limits.acceleration * f.acceleration, limits.deceleration * f.acceleration,
        limits.jerk * f.jerk,
    )  # fmt: skip


def apply(p: Process, f: Override) -> None:
    """Re-plan ``p`` (a move or a jog, see :func:`overridable`) from where it is with its
    programmed dynamics scaled by ``f``. If it cannot be planned nothing changes and
    MotionError is raised."""
    assert isinstance(p, MoveProcess | JogProcess)
    nominal = p.override_nominal
    if nominal is None:
        if f.neutral:
            return
        # a jog's programmed velocity; a move's: 1 running, 0 paused by MCD speed 0
        if isinstance(p, JogProcess):
            nominal = (p.limits, p.target_velocity)
        else:
            nominal = (p.limits, 0.0 if p.paused else 1.0)
    limits, target = nominal
    if isinstance(p, JogProcess):
        before = (p.target_velocity, p.at_speed)
        p.target_velocity = target * f.velocity
        try:
            p.change_dynamics(scaled(limits, f))
        except MotionError:
            p.target_velocity, p.at_speed = before
            raise
    else:
        paused = p.paused
        p.paused = target == 0.0 or f.velocity == 0.0
        try:
            p.change_dynamics(scaled(limits, f))
        except MotionError:
            p.paused = paused
            raise
    p.override_nominal = None if f.neutral else nominal
