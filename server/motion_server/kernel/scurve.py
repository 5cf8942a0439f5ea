"""Jerk-limited velocity profiles (S-curves) in closed form, planned once and sampled per cycle.

A jog, a change of its speed (MAJ, MC_MoveVelocity, MCD, an override), a jerk-limited
stop (MAS with DecelJerk, MC_Stop / MC_Halt with Jerk) and a jerk-limited catch-up ramp
all ask for the same thing: from the current velocity and acceleration, reach a target
velocity with zero acceleration in the least time, the acceleration within
[``a_min``, ``a_max``] and the jerk within ``jerk``. This is ruckig's third-order velocity
interface (``VelocityThirdOrderStep1`` and the velocity brake of ``BrakeProfile``), which
this module reproduces in closed form so that the fast lanes can sample many profiles at
once with the same floating-point operations (:mod:`.lanes.scurve`):

1. **Brake.** An acceleration beyond its limit (``a0 > a_max`` or ``a0 < a_min``) is first
   brought back onto the limit at full jerk (ruckig's ``get_velocity_brake_trajectory``).
2. **Three phases or two.** From (v, a) to the target: jerk up (or down) to a peak
   acceleration, hold it, jerk back to zero. The peak is the acceleration limit of the
   direction of the velocity change (``a_max`` toward a higher velocity, ``a_min`` toward a
   lower one: ruckig's ``max_acceleration`` and ``min_acceleration`` of the velocity
   interface, which bound the acceleration itself whatever the sign of the velocity);
   when the limit is not reached the hold vanishes and the peak is ``sqrt(a^2/2 + j dv)``.
   When the current acceleration would overshoot the target even if it were brought to
   zero at once, the profile jerks through zero to the other side (ruckig tries the
   opposite direction next, in the same order).

Which limit is ``a_max`` and which ``a_min`` for a Logix acceleration / deceleration pair is
decided by the caller (:meth:`SCurveProfile.to_velocity`) exactly as
:class:`~.profiles.Profile` decides it for ruckig: on the direction of the target velocity
(of the current velocity when the target is rest), one limit pair per plan.

The plan is sampled at t = k·dt, k the cycles since the plan (no running sum), with
ruckig's integration formula. A sample within :data:`~.trapezoid.END_TOLERANCE` of a period
before the end counts as the end: from there on the target velocity is held by
integrating it, as ruckig's profile does once finished. A plan longer than
:data:`~.trapezoid.MAX_DURATION` or with a non-finite number is refused
(``PROFILE_FAILED``), as ruckig refuses it. A case no candidate covers within ruckig's
own acceptance tests (the acceleration limits with a few ulps more room than ruckig's
absolute 1e-12, which is less than an ulp of 1e5) is planned by ruckig instead and
counted in :data:`FALLBACKS`, as are the position targets :mod:`.scurve_position` does
not cover; ruckig's plan is then sampled as a closed form's (:func:`plan_from_ruckig`).

The command does only what decides its outcome: the segments (:func:`jerk_segments`,
which tells whether the closed form covers the target) and the refusal of a plan too
long (:func:`judge_request`); the plan itself is built when first needed
(``SCurveProfile.plan``), or for every ramp of a scan at once by the S-curve lane
(:mod:`.scurve_plan`), with the same operations.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, replace

from .errors import ErrorCode, MotionError
from .jerk_phases import Phases, solve_phases
from .limits import Limits
from .ruckig_plan import V_PRECISION, ruckig_segments
from .ruckig_profile import Profile
from .scurve_position import P_PRECISION, position_segments
from .trapezoid import END_TOLERANCE, MAX_DURATION

#: every plan has this many segments of constant jerk (unused ones have zero duration):
#: the brake, jerk toward the peak, the hold, jerk back to zero
SEGMENTS = 4
#: a position plan's segments: an (empty) brake, the ramp to the peak velocity (three),
#: the cruise, the ramp to rest (three)
POSITION_SEGMENTS = 8


class Fallbacks:
    """How many jerk-limited targets (velocity or position) the closed forms left to
    ruckig, since the process started (one scan process runs one controller:
    ``Controller.profile_fallbacks``)."""

    count = 0


#: the process-wide count of jerk-limited plans handed to ruckig
FALLBACKS = Fallbacks()


@dataclass(frozen=True, slots=True)
class JerkPlan:
    """Segments of constant jerk from the plan's origin (t = 0), then the end: four for
    a velocity target (:data:`SEGMENTS`), eight for a position target
    (:data:`POSITION_SEGMENTS`, :mod:`.scurve_position`).

    ``start[s]`` is the time segment ``s`` begins (``start[0]`` = 0, non-decreasing),
    ``pos``, ``vel``, ``acc`` the state there, ``jerk`` its jerk; ``half`` = acc / 2,
    ``jhalf`` = jerk / 2 and ``jsixth`` = jerk / 6 (the factors of ruckig's integration,
    computed once). A sample at t >= ``done`` is the end: ``end_position`` and
    ``end_velocity`` are reached at ``end``.
    """

    start: tuple[float, ...]
    pos: tuple[float, ...]
    vel: tuple[float, ...]
    acc: tuple[float, ...]
    half: tuple[float, ...]
    jerk: tuple[float, ...]
    jhalf: tuple[float, ...]
    jsixth: tuple[float, ...]
    end: float
    done: float
    end_position: float
    end_velocity: float

    def segment(self, t: float) -> int:
        """The segment a sample at ``t`` < ``done`` falls in."""
        st = self.start
        s = (t >= st[1]) + (t >= st[2]) + (t >= st[3])
        if len(st) > SEGMENTS:
            s += (t >= st[4]) + (t >= st[5]) + (t >= st[6]) + (t >= st[7])
        return s

    def sample(self, t: float) -> tuple[float, float, float]:
        """Position, velocity and acceleration at ``t`` (before ``done``)."""
        s = self.segment(t)
        tau = t - self.start[s]
        v = self.vel[s]
        a = self.acc[s]
        p = self.pos[s] + tau * (v + tau * (self.half[s] + tau * self.jsixth[s]))
        return p, v + tau * (a + tau * self.jhalf[s]), a + tau * self.jerk[s]


#: the inputs of :func:`_phases` as bytes: equal bytes are the same floats, bit for bit
#: (signed zeros and NaNs included), so they give the same phases
_KEY = struct.Struct("6d").pack
#: the last phases computed and the bytes of their inputs
_last: tuple[bytes, Phases | None] = (b"", None)


def _phases(
    a0: float, v0: float, vf: float, a_max: float, a_min: float, jerk: float
) -> Phases | None:
    """(t0, t1, t2, jerk of phase 0) from (v0, a0), a0 within the limits, to vf at rest
    acceleration (:func:`.jerk_phases.solve_phases`). The targets commanded in one scan
    are often the same (many axes ramped alike from rest): the last answer is kept and
    given again for the very same inputs."""
    global _last  # (one pair, replaced at once)
    key = _KEY(a0, v0, vf, a_max, a_min, jerk)
    last = _last
    if key == last[0]:
        return last[1]
    phases = solve_phases(a0, v0, vf, a_max, a_min, jerk)
    _last = (key, phases)
    return phases


def _too_long(duration: float) -> MotionError:
    return MotionError(
        ErrorCode.PROFILE_FAILED,
        f"the profile would last {duration:g} s (more than {MAX_DURATION:g} s) for these limits",
    )


#: (brake, jerk of the brake, phase 0, its jerk, the hold, phase 2): the segments of a
#: plan as :func:`jerk_segments` gives them (phase 2's jerk is minus phase 0's)
JerkSegments = tuple[float, float, float, float, float, float]

#: what :func:`build_request` needs besides dt: (p0, v0, a0, target, *JerkSegments)
JerkRequest = tuple[float, float, float, float, float, float, float, float, float, float]

#: inputs below this (in magnitude) cannot overflow a plan of at most MAX_DURATION
#: seconds: every term of the integration is below it times (1 + t + t^2 + t^3), t <= 7.6e3
_SAFE = 1e200


def jerk_segments(
    v0: float, a0: float, target: float, a_max: float, a_min: float, jerk: float
) -> JerkSegments | None:
    """The segments of :func:`plan_jerk_velocity` (its brake and phases, not yet
    integrated); None when the closed form does not cover the case.
    MotionError(PROFILE_FAILED) when the brake cannot be held."""
    if a0 > a_max or a0 < a_min:
        if a0 > a_max:
            tb, jb = (a0 - a_max) / jerk, -jerk
        else:
            tb, jb = (a_min - a0) / jerk, jerk
        ab = a0 + tb * jb
        vb = v0 + tb * (a0 + tb * jb / 2)
        if tb > 0.0:
            ab = a_max if jb < 0.0 else a_min  # exactly on the limit the brake aimed at
        if not math.isfinite(tb):
            raise _too_long(tb)
    else:
        # no brake: the same expressions for tb = jb = 0.0 (a0 + 0.0 * 0.0, ...)
        tb = jb = 0.0
        ab = a0 + 0.0
        vb = v0 + 0.0 * (a0 + 0.0)
    if not math.isfinite(vb):
        raise MotionError(ErrorCode.PROFILE_FAILED, "the profile overflows for these limits")
    phases = _phases(ab, vb, target, a_max, a_min, jerk)
    if phases is None:
        return None
    t0, t1, t2, j = phases
    return tb, jb, t0, j, t1, t2


def _segment_list(segs: JerkSegments) -> list[tuple[float, float]]:
    tb, jb, t0, j, t1, t2 = segs
    return [(tb, jb), (t0, j), (t1, 0.0), (t2, -j)]


def plan_jerk_velocity(
    dt: float,
    p0: float,
    v0: float,
    a0: float,
    target: float,
    a_max: float,
    a_min: float,
    jerk: float,
) -> JerkPlan | None:
    """Ramp from (``p0``, ``v0``, ``a0``) to the velocity ``target`` at zero acceleration,
    the acceleration within [``a_min``, ``a_max``] (``a_min`` < 0 < ``a_max``), the jerk
    within ``jerk`` (> 0, finite). None when the closed form does not cover the case
    (ruckig plans it then); MotionError(PROFILE_FAILED) when no plan can hold it."""
    segs = jerk_segments(v0, a0, target, a_max, a_min, jerk)
    if segs is None:
        return None
    return _build(dt, p0, v0, a0, _segment_list(segs), target)


def judge_request(request: JerkRequest) -> bool:
    """Whether the plan of ``request`` (segments from :func:`jerk_segments`) can be built
    later without an error (True: it will be finite and within MAX_DURATION). Raises the
    error :func:`_build` would raise for a plan too long; False when only building it
    tells (inputs too large to bound: build it now)."""
    p0, v0, a0, target, tb, jb, t0, j, t1, t2 = request
    t = 0.0 + tb + t0 + t1 + t2  # the plan's duration as _build sums it
    if not math.isfinite(t) or t > MAX_DURATION:
        raise _too_long(t)
    s = _SAFE  # (each False for a NaN as well)
    return (
        -s < p0 < s and -s < v0 < s and -s < a0 < s and -s < target < s and -s < j < s
        and -s < jb < s
    )  # fmt: skip


def build_request(dt: float, request: JerkRequest) -> JerkPlan:
    """The plan of a judged ``request`` (:func:`judge_request`), as
    :func:`plan_jerk_velocity` builds it."""
    p0, v0, a0, target, *segs = request
    tb, jb, t0, j, t1, t2 = segs
    return _build(dt, p0, v0, a0, [(tb, jb), (t0, j), (t1, 0.0), (t2, -j)], target)


def _build(
    dt: float, p0: float, v0: float, a0: float, segments: list[tuple[float, float]], vf: float
) -> JerkPlan:
    """Integrate ``segments`` ((duration, jerk)) from (p0, v0, a0) as ruckig does."""
    start, pos, vel, acc, half, jerk, jhalf, jsixth = ([] for _ in range(8))
    t, p, v, a = 0.0, p0, v0, a0
    for duration, j in segments:
        start.append(t)
        pos.append(p)
        vel.append(v)
        acc.append(a)
        half.append(a / 2)
        jerk.append(j)
        jhalf.append(j / 2)
        jsixth.append(j / 6)
        p = p + duration * (v + duration * (a / 2 + duration * j / 6))
        v = v + duration * (a + duration * j / 2)
        a = a + duration * j
        t = t + duration
    if not math.isfinite(t) or t > MAX_DURATION:
        raise _too_long(t)
    if not all(map(math.isfinite, (p, v, *pos, *vel, *acc))):
        raise MotionError(ErrorCode.PROFILE_FAILED, "the profile overflows for these limits")
    return JerkPlan(
        tuple(start),
        tuple(pos),
        tuple(vel),
        tuple(acc),
        tuple(half),
        tuple(jerk),
        tuple(jhalf),
        tuple(jsixth),
        t,
        t - END_TOLERANCE * dt,
        p,
        vf,
    )


#: the inputs of :func:`plan_jerk_position` as bytes, and its last plan (a batch of moves
#: from rest by one distance asks every axis the same question; plans are immutable)
_POSITION_KEY = struct.Struct("9d").pack
_last_position: tuple[bytes, JerkPlan | None] = (b"", None)


def plan_jerk_position(
    dt: float, p0: float, v0: float, a0: float, target: float, limits: Limits
) -> JerkPlan | None:
    """The move from (``p0``, ``v0``, ``a0``) to rest at ``target`` within ``limits``
    (validated, with a jerk limit) in closed form (:mod:`.scurve_position`); None when
    the closed form does not cover the state or its end misses the target by more than
    ruckig's position precision (ruckig plans it then). MotionError(PROFILE_FAILED) when
    no plan can hold it."""
    global _last_position  # (one pair, replaced at once)
    key = _POSITION_KEY(
        dt, p0, v0, a0, target, limits.velocity, limits.acceleration, limits.deceleration,
        limits.jerk,
    )  # fmt: skip
    last = _last_position
    if key == last[0]:
        return last[1]
    d = target - p0
    a_max, a_min = limit_pair(d, limits.acceleration, limits.deceleration)
    segments = position_segments(v0, a0, d, limits, a_max, a_min)
    plan = None
    if segments is not None:
        built = _build(dt, p0, v0, a0, segments, 0.0)
        if abs(built.end_position - target) <= P_PRECISION:
            # the last sample lands on the target exactly, as ruckig's does
            plan = replace(built, end_position=target)
    _last_position = (key, plan)
    return plan


#: the key of the last target ruckig planned (:func:`ruckig_planned`) and its plan
_last_ruckig: tuple[bytes, JerkPlan | None] = (b"", None)


def ruckig_planned(
    dt: float, p0: float, v0: float, a0: float, target: float | None, velocity: float,
    limits: Limits,
) -> tuple[JerkPlan | None, Profile | None]:  # fmt: skip
    """A target the closed forms leave (a position ``target``, or None and a
    ``velocity``) planned by ruckig from (``p0``, ``v0``, ``a0``): its plan as segments
    (:func:`plan_from_ruckig`), or None and the ruckig profile to step when it has none.
    The plan of the last such question is kept: the axes of a batch in one state (an MCD
    on every axis of a machine) ask ruckig once. MotionError(PROFILE_FAILED) when ruckig
    cannot plan it."""
    global _last_ruckig  # (one pair, replaced at once)
    key = _POSITION_KEY(
        dt, p0, v0, a0, velocity if target is None else target, limits.velocity,
        limits.acceleration, limits.deceleration, limits.jerk,
    ) + (b"v" if target is None else b"p")  # fmt: skip
    last = _last_ruckig
    if key == last[0] and last[1] is not None:
        return last[1], None
    prof = Profile(dt, v0, a0, p0)
    if target is None:
        prof.to_velocity(velocity, limits)
    else:
        prof.to_position(target, limits)
    plan = plan_from_ruckig(dt, p0, v0, a0, prof)
    _last_ruckig = (key, plan)
    return plan, (prof if plan is None else None)


def plan_from_ruckig(dt: float, p0: float, v0: float, a0: float, prof: Profile) -> JerkPlan | None:
    """The plan ruckig made for ``prof`` (a :class:`~.ruckig_profile.Profile` just given
    its target, from (``p0``, ``v0``, ``a0``)) as segments of constant jerk
    (:mod:`.ruckig_plan`), ending on its target exactly (a position target at rest, or
    the target velocity) when the integrated end is within ruckig's precision of it;
    None otherwise (ruckig steps the profile then)."""
    trajectory = prof.trajectory
    if trajectory is None:
        return None
    segments = ruckig_segments(trajectory, POSITION_SEGMENTS)
    if segments is None:
        return None
    size = SEGMENTS if len(segments) <= SEGMENTS else POSITION_SEGMENTS
    segments += [(0.0, 0.0)] * (size - len(segments))
    target = prof.target_position
    velocity = 0.0 if target is not None else prof.target_velocity
    try:
        built = _build(dt, p0, v0, a0, segments, velocity)
    except MotionError:
        # a plan ruckig accepts but the closed forms would refuse (it may last beyond
        # MAX_DURATION: ruckig plans such states too): ruckig steps it, as it always did
        return None
    # (the velocity the last segment reaches, integrated as _build integrates it)
    v_end = built.vel[-1] + (built.end - built.start[-1]) * (
        built.acc[-1] + (built.end - built.start[-1]) * built.jhalf[-1]
    )
    if abs(v_end - velocity) > V_PRECISION:
        return None
    if target is None:
        return built
    if abs(built.end_position - target) > P_PRECISION:
        return None
    return replace(built, end_position=target)


def limit_pair(direction: float, acceleration: float, deceleration: float) -> tuple[float, float]:
    """(``a_max``, ``a_min``) for travel in ``direction``: what :class:`~.profiles.Profile`
    gives ruckig as ``max_acceleration`` and ``min_acceleration``."""
    if direction >= 0.0:
        return acceleration, -deceleration
    return deceleration, -acceleration


class SCurveProfile:
    """A jerk-limited profile with the interface of :class:`~.profiles.Profile`: velocity
    targets in closed form (``plan``), position targets (and velocity targets the closed
    form leaves over) through ruckig (``ruckig``).

    ``position`` is the displacement from the profile's origin; ``cycles`` counts the
    samples since the current closed-form plan.

    A velocity target is judged when it is commanded: its segments are found
    (:func:`jerk_segments`: whether the closed form covers it, else ruckig plans it at
    once) and a plan that could not be held is refused (:func:`judge_request`). The plan
    itself is built when it is first needed: ``plan`` builds it then from the ``request``
    kept, unless the S-curve lane has built every plan admitted in a scan in one pass
    before the step (:mod:`.scurve_plan`); both give the very same numbers.
    """

    #: the closed-form plan, once built (``plan`` builds it from ``request``)
    _plan: JerkPlan | None = None
    #: a velocity target judged but not built yet
    request: JerkRequest | None = None

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
        #: the ruckig profile that plans a position target (or a fallback), else None
        self.ruckig: Profile | None = None
        self._target_position: float | None = None
        self._target_velocity = 0.0

    @property
    def plan(self) -> JerkPlan | None:
        """The current closed-form plan (built now if only requested); None when there
        is none (ruckig plans, or nothing was planned)."""
        request = self.request
        if request is not None:
            self._plan = build_request(self._dt, request)
            self.request = None
        return self._plan

    @plan.setter
    def plan(self, plan: JerkPlan | None) -> None:
        self._plan = plan
        self.request = None

    @property
    def planned(self) -> bool:
        """A closed-form plan is running (built, or requested and not built yet)."""
        return self.request is not None or self._plan is not None

    def __setstate__(self, state: dict[str, object]) -> None:
        # saved before plans were built on demand: the plan was an attribute
        if "plan" in state:
            state["_plan"] = state.pop("plan")
        self.__dict__.update(state)

    # -- targets --------------------------------------------------------------------------
    def to_position(self, displacement: float, limits: Limits) -> None:
        """Plan to rest at ``displacement`` from the origin: in closed form from the
        states :mod:`.scurve_position` covers, else through ruckig (counted in
        :data:`FALLBACKS`). If it cannot be planned nothing changes and MotionError is
        raised."""
        if not math.isfinite(displacement):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target position must be finite")
        limits = limits.validated()
        target = float(displacement)
        plan = None
        if not limits.trapezoidal:
            plan = plan_jerk_position(
                self._dt, self.position, self.velocity, self.acceleration, target, limits
            )
        if plan is None:
            plan, prof = ruckig_planned(
                self._dt, self.position, self.velocity, self.acceleration, target, 0.0, limits
            )
            FALLBACKS.count += 1
            if prof is not None:
                self._use_ruckig(prof, target, 0.0)
                return
        self.plan = plan
        self._started(None, target, 0.0)

    def to_velocity(self, velocity: float, limits: Limits) -> None:
        """Ramp to a constant ``velocity`` (signed) and hold it. If it cannot be planned
        nothing changes and MotionError is raised."""
        if not math.isfinite(velocity):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target velocity must be finite")
        limits = limits.validated()
        target = float(velocity)
        segs = None
        if not limits.trapezoidal:
            v0 = self.velocity
            direction = target if target != 0.0 else v0
            if direction >= 0.0:  # limit_pair
                a_max, a_min = limits.acceleration, -limits.deceleration
            else:
                a_max, a_min = limits.deceleration, -limits.acceleration
            segs = jerk_segments(v0, self.acceleration, target, a_max, a_min, limits.jerk)
        if segs is None:
            plan, prof = ruckig_planned(
                self._dt, self.position, self.velocity, self.acceleration, None, target, limits
            )
            FALLBACKS.count += 1
            if prof is not None:
                self._use_ruckig(prof, None, target)
                return
            self._plan = plan
            self.request = None
            self._started(None, None, target)
            return
        request = (self.position, self.velocity, self.acceleration, target, *segs)
        if judge_request(request):
            self._plan = None
            self.request = request
        else:
            self._plan = build_request(self._dt, request)  # (may raise: nothing changed)
            self.request = None
        self._started(None, None, target)

    def _use_ruckig(self, prof: Profile, target_position: float | None, velocity: float) -> None:
        self.plan = None
        self._started(prof, target_position, velocity)

    def _started(
        self, ruckig: Profile | None, target_position: float | None, velocity: float
    ) -> None:
        """A new plan from the current state: ``ruckig`` plans it (None: a closed form)."""
        self.ruckig = ruckig
        self.cycles = 0
        self.finished = False
        self._target_position = target_position
        self._target_velocity = velocity

    # -- stepping -------------------------------------------------------------------------
    def step(self) -> None:
        prof = self.ruckig
        if prof is not None:
            prof.step()
            self.position = prof.position
            self.velocity = prof.velocity
            self.acceleration = prof.acceleration
            if prof.finished:
                # from here on the held velocity is integrated here, as ruckig's profile
                # would (a lane may then take the process and write ``position``)
                self.finished = True
                self.ruckig = None
            return
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
