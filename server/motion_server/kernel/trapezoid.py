"""Trapezoidal profiles (jerk unlimited) in closed form, planned once and sampled per cycle.

A jog or move whose jerk is 0 (or infinite) follows a time-optimal profile of piecewise
constant acceleration: the same profiles ruckig computes for second-order limits (its
``PositionSecondOrderStep1`` / ``VelocitySecondOrderStep1``): ramp to a velocity at the
acceleration limit of that direction, or accelerate, cruise at the velocity limit and
decelerate onto a position target, braking first if the current velocity exceeds the
limit, overshooting and coming back if the target is too close to stop on. ruckig re-plans
these from the sampled state every cycle; here the profile is planned once per target (on
a new command or a change of dynamics) and sampled at t = k·dt, k the cycles since the
plan, so the fast lanes can sample many profiles at once with the very same
floating-point operations (:mod:`.lanes`).

Rules kept from the ruckig planner this replaces:

- limits map onto the direction of travel: toward a target (or target velocity) ahead,
  speeding up is limited by the acceleration and slowing down by the deceleration; a
  braking phase that reverses the direction is limited by the acceleration of the new
  direction (one limit pair per plan);
- a velocity target ignores the velocity limit; a position target brakes into it first;
- a plan longer than :data:`MAX_DURATION` (ruckig's maximal trajectory duration) or with
  a non-finite number is refused (``PROFILE_FAILED``), and the previous plan stays.

A sample within :data:`END_TOLERANCE` of a period before the end counts as the end (so a
ramp of exactly n periods ends on the n-th sample): a position target is then met exactly
at rest, a velocity target is held from there on by integrating it (as ruckig's profile
does once finished).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import ErrorCode, MotionError
from .limits import Limits

#: seconds: longer profiles are refused, as ruckig refuses trajectories beyond this
MAX_DURATION = 7.6e3
#: share of a period: a sample this close before the end of a plan is its end
END_TOLERANCE = 1e-9
#: every plan has this many segments (unused ones have zero duration)
SEGMENTS = 4


@dataclass(frozen=True, slots=True)
class Plan:
    """Four segments of constant acceleration from the plan's origin (t = 0), then the end.

    ``start[s]`` is the time segment ``s`` begins (``start[0]`` = 0, non-decreasing),
    ``pos``, ``vel`` the state there, ``acc`` its acceleration and ``half`` = acc / 2.
    A sample at t >= ``done`` is the end: ``end_position``, ``end_velocity`` (reached at
    ``end``); ``landing`` plans end exactly on ``end_position`` at rest.
    """

    start: tuple[float, float, float, float]
    pos: tuple[float, float, float, float]
    vel: tuple[float, float, float, float]
    acc: tuple[float, float, float, float]
    half: tuple[float, float, float, float]
    end: float
    done: float
    end_position: float
    end_velocity: float
    landing: bool

    def segment(self, t: float) -> int:
        """The segment a sample at ``t`` < ``done`` falls in (the count of later starts
        passed: what the lanes compute with three comparisons)."""
        st = self.start
        return (t >= st[1]) + (t >= st[2]) + (t >= st[3])

    def sample(self, t: float) -> tuple[float, float, float]:
        """Position, velocity and acceleration at ``t`` (before ``done``)."""
        s = self.segment(t)
        tau = t - self.start[s]
        v = self.vel[s]
        return self.pos[s] + tau * (v + tau * self.half[s]), v + tau * self.acc[s], self.acc[s]


def _too_long(duration: float) -> MotionError:
    return MotionError(
        ErrorCode.PROFILE_FAILED,
        f"the profile would last {duration:g} s (more than {MAX_DURATION:g} s) for these limits",
    )


def judge_ramp(velocity: float, deceleration: float) -> None:
    """Refuse a ramp from ``velocity`` to rest that no plan could hold, as
    :func:`plan_velocity` would (too long, or beyond any float), without building one."""
    duration = abs(velocity) / deceleration
    if not math.isfinite(duration) or duration > MAX_DURATION:
        raise _too_long(duration)
    if not math.isfinite(duration * velocity):
        raise MotionError(ErrorCode.PROFILE_FAILED, "the profile overflows for these limits")


def _build(
    dt: float,
    p0: float,
    v0: float,
    segments: list[tuple[float, float]],
    end_velocity: float,
    target: float | None,
) -> Plan:
    """Integrate ``segments`` ((duration, acceleration), real frame) from (p0, v0)."""
    start, pos, vel, acc, half = [], [], [], [], []
    t, p, v = 0.0, p0, v0
    for duration, a in segments:
        h = 0.5 * a
        start.append(t)
        pos.append(p)
        vel.append(v)
        acc.append(a)
        half.append(h)
        p = p + duration * (v + duration * h)
        v = v + duration * a
        t = t + duration
    if not math.isfinite(t) or t > MAX_DURATION:
        raise _too_long(t)
    if not all(math.isfinite(x) for x in (p, v, *pos, *vel)):
        raise MotionError(ErrorCode.PROFILE_FAILED, "the profile overflows for these limits")
    return Plan(
        (start[0], start[1], start[2], start[3]),
        (pos[0], pos[1], pos[2], pos[3]),
        (vel[0], vel[1], vel[2], vel[3]),
        (acc[0], acc[1], acc[2], acc[3]),
        (half[0], half[1], half[2], half[3]),
        t,
        t - END_TOLERANCE * dt,
        p if target is None else target,
        end_velocity,
        target is not None,
    )


def judge_velocity_plan(
    p0: float, v0: float, target: float, acceleration: float, deceleration: float
) -> None:
    """Refuse what :func:`plan_velocity` would refuse (too long, or beyond any float),
    with the same error, without building the plan: its one segment's duration and end,
    computed as :func:`_build` computes them (the segments after it last 0 and change
    nothing a finite plan holds)."""
    direction = target if target != 0.0 else v0
    a_max, a_min = _limit_pair(direction, acceleration, deceleration)
    gap = target - v0
    a = a_max if gap > 0.0 else a_min
    duration = max(gap / a, 0.0)
    t = 0.0 + duration
    if not math.isfinite(t) or t > MAX_DURATION:
        raise _too_long(t)
    p = p0 + duration * (v0 + duration * (0.5 * a))
    v = v0 + duration * a
    if not (math.isfinite(p) and math.isfinite(v) and math.isfinite(p0) and math.isfinite(v0)):
        raise MotionError(ErrorCode.PROFILE_FAILED, "the profile overflows for these limits")


def _limit_pair(direction: float, acceleration: float, deceleration: float) -> tuple[float, float]:
    """(largest positive, largest negative) acceleration for travel in ``direction``."""
    if direction >= 0.0:
        return acceleration, -deceleration
    return deceleration, -acceleration


def plan_velocity(
    dt: float,
    p0: float,
    v0: float,
    target: float,
    acceleration: float,
    deceleration: float,
) -> Plan:
    """Ramp from ``v0`` to the velocity ``target`` and hold it."""
    direction = target if target != 0.0 else v0
    a_max, a_min = _limit_pair(direction, acceleration, deceleration)
    gap = target - v0
    a = a_max if gap > 0.0 else a_min
    duration = max(gap / a, 0.0)
    zero = (0.0, 0.0)
    return _build(dt, p0, v0, [(duration, a), zero, zero, zero], target, None)


def plan_position(
    dt: float,
    p0: float,
    v0: float,
    target: float,
    velocity: float,
    acceleration: float,
    deceleration: float,
) -> Plan:
    """Come to rest exactly on ``target`` in the least time within the limits."""
    s = 1.0 if target - p0 >= 0.0 else -1.0
    # work in the frame of travel toward the target: a in [-dec, acc], |v| <= vmax
    acc, dec = acceleration, deceleration
    vmax = velocity
    u = s * v0
    remaining = s * (target - p0)
    brake = (0.0, 0.0)
    if u > vmax:
        t = (u - vmax) / dec
        brake = (t, -dec)
        remaining -= t * (u + t * (0.5 * -dec))
        u = vmax
    elif u < -vmax:
        t = (-vmax - u) / acc
        brake = (t, acc)
        remaining -= t * (u + t * (0.5 * acc))
        u = -vmax
    stop = u * u / (2.0 * dec) if u >= 0.0 else -(u * u) / (2.0 * acc)
    if remaining >= stop:
        # forward: accelerate toward the target, cruise, decelerate onto it
        peak = math.sqrt(max((2.0 * acc * dec * remaining + dec * u * u) / (acc + dec), 0.0))
        if peak > vmax:
            cruise = remaining - (vmax * vmax - u * u) / (2.0 * acc) - vmax * vmax / (2.0 * dec)
            phases = [
                ((vmax - u) / acc, acc),
                (max(cruise, 0.0) / vmax, 0.0),
                (vmax / dec, -dec),
            ]
        else:
            phases = [(max(peak - u, 0.0) / acc, acc), (0.0, 0.0), (peak / dec, -dec)]
    else:
        # too close (or behind): brake through rest, come back and stop on the target
        peak = math.sqrt(max((acc * u * u - 2.0 * acc * dec * remaining) / (acc + dec), 0.0))
        if peak > vmax:
            back = (u * u - vmax * vmax) / (2.0 * dec) - vmax * vmax / (2.0 * acc)
            phases = [
                ((u + vmax) / dec, -dec),
                (max(back - remaining, 0.0) / vmax, 0.0),
                (vmax / acc, acc),
            ]
        else:
            phases = [(max(u + peak, 0.0) / dec, -dec), (0.0, 0.0), (peak / acc, acc)]
    segments = [(brake[0], s * brake[1])] + [(t, s * a) for t, a in phases]
    return _build(dt, p0, v0, segments, 0.0, target)


#: what :func:`plan_velocity` needs besides dt: (p0, v0, target, acceleration, deceleration)
VelocityRequest = tuple[float, float, float, float, float]


class TrapezoidProfile:
    """A trapezoidal profile with the interface of :class:`.profiles.Profile`.

    ``position`` is the displacement from the profile's origin; ``cycles`` counts the
    samples since the current plan.

    A velocity target is judged at once (:func:`judge_velocity_plan`: a plan that could
    not be held is refused when it is commanded) and planned when the plan is first
    needed: ``plan`` builds it then, from the ``request`` kept, unless the fast lanes have
    planned every velocity target admitted in a scan in one pass before the step
    (:mod:`.move_plan`); both give the very same numbers.
    """

    #: the plan, once built (``plan`` builds it from ``request``)
    _plan: Plan | None = None
    #: a velocity target judged but not planned yet
    request: VelocityRequest | None = None

    def __init__(
        self, dt: float, velocity: float = 0.0, acceleration: float = 0.0, position: float = 0.0
    ) -> None:
        self._dt = dt
        self.position = float(position)
        self.velocity = float(velocity)
        self.acceleration = float(acceleration)
        self.finished = False
        self.cycles = 0
        self._plan = None
        self.request = None
        self._target_position: float | None = None
        self._target_velocity = 0.0

    # -- targets --------------------------------------------------------------------------
    def to_position(self, displacement: float, limits: Limits) -> None:
        """Plan to rest at ``displacement`` from the origin."""
        if not math.isfinite(displacement):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target position must be finite")
        limits = limits.validated()
        plan = plan_position(
            self._dt,
            self.position,
            self.velocity,
            float(displacement),
            limits.velocity,
            limits.acceleration,
            limits.deceleration,
        )
        self._start(plan, float(displacement), 0.0)

    def to_velocity(self, velocity: float, limits: Limits) -> None:
        """Ramp to a constant ``velocity`` (signed) and hold it."""
        if not math.isfinite(velocity):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target velocity must be finite")
        limits = limits.validated()
        request = (
            self.position,
            self.velocity,
            float(velocity),
            limits.acceleration,
            limits.deceleration,
        )
        judge_velocity_plan(*request)
        # what _start(None, None, velocity) does, then the request kept
        self._plan = None
        self.request = request
        self.cycles = 0
        self.finished = False
        self._target_position = None
        self._target_velocity = request[2]

    @property
    def plan(self) -> Plan | None:
        """The current plan (built now if only requested); None once none is needed."""
        request = self.request
        if request is not None:
            self._plan = plan_velocity(self._dt, *request)
            self.request = None
        return self._plan

    @plan.setter
    def plan(self, plan: Plan | None) -> None:
        self._plan = plan
        self.request = None

    @property
    def planned(self) -> bool:
        """A plan is running (built, or requested and not built yet)."""
        return self.request is not None or self._plan is not None

    def __setstate__(self, state: dict[str, object]) -> None:
        # saved before plans were built on demand: the plan was an attribute
        if "plan" in state:
            state["_plan"] = state.pop("plan")
        self.__dict__.update(state)

    def _start(
        self, plan: Plan | None, target_position: float | None, target_velocity: float
    ) -> None:
        self.plan = plan
        self.cycles = 0
        self.finished = False
        self._target_position = target_position
        self._target_velocity = target_velocity

    # -- stepping -------------------------------------------------------------------------
    def step(self) -> None:
        # (finished first: a finished plan is not needed, so not built)
        plan = None if self.finished else self.plan
        if plan is None:
            # holding the target velocity: integrate it (no plan needed)
            self.acceleration = 0.0
            self.position += self.velocity * self._dt
            return
        self.cycles += 1
        t = self.cycles * self._dt
        if t >= plan.done:
            self.finish_plan(t)
            return
        self.position, self.velocity, self.acceleration = plan.sample(t)

    def finish_plan(self, t: float) -> None:
        """The sample at ``t`` (>= ``plan.done``) ends the plan."""
        plan = self.plan
        assert plan is not None
        self.finished = True
        self.acceleration = 0.0
        self.velocity = plan.end_velocity
        if plan.landing:
            self.position = plan.end_position
        else:
            self.position = plan.end_position + max(t - plan.end, 0.0) * plan.end_velocity

    @property
    def dt(self) -> float:
        return self._dt

    @property
    def target_position(self) -> float | None:
        return self._target_position

    @property
    def target_velocity(self) -> float:
        return self._target_velocity
