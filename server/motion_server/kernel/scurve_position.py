"""Jerk-limited moves to a position in closed form: the moves the instructions start.

A jerk-limited MAM, MC_MoveAbsolute or MC_MoveRelative asks ruckig's third-order
position interface for a rest-to-rest profile: from the current state to the target at
zero velocity and acceleration, the velocity within ``vmax``, the acceleration within
[``a_min``, ``a_max``] (the pair of the direction of travel, :func:`.scurve.limit_pair`:
``acceleration`` while speeding up toward the target, ``deceleration`` while braking)
and the jerk within ``jerk``. This module plans the states a move starts from in
practice in closed form: at a constant velocity (zero acceleration: at rest, or
cruising) toward the target, no faster than ``vmax``, and far enough from it to come
to rest there without passing it. From such a state the time-optimal profile is

1. a ramp from the velocity v0 to a peak velocity vp (three phases of constant jerk or
   two: :func:`.jerk_phases.solve_phases`, as the velocity plans),
2. a cruise at vp,
3. a ramp from vp to rest.

A ramp between two velocities at rest acceleration is point-symmetric about its middle,
so it covers the mean of its two velocities times its duration: the distance of the
whole profile is ``D(vp) = (v0 + vp) / 2 * T(vp - v0, acceleration) + vp / 2 *
T(vp, deceleration)``, where a ramp of a velocity change ``dv`` at the limit ``a`` lasts
``T = dv / a + a / jerk`` when ``dv >= a^2 / jerk`` (the limit is held) and
``2 sqrt(dv / jerk)`` otherwise. ``D`` increases with vp on [v0, vmax]. When the
distance is at least ``D(vmax)`` the peak is ``vmax`` and the cruise covers the rest;
otherwise there is no cruise and vp is the root of ``D(vp) = distance`` (Newton's
method inside a bisection bracket). The profile is integrated as the velocity plans are
(:func:`.scurve._build`); it must end within ruckig's position precision (1e-8) of the
target, where the last sample lands exactly, as ruckig's does.

Every other state (accelerating, moving away from the target, too close to stop
before it, faster than ``vmax``) is ruckig's, and counted (:data:`.scurve.FALLBACKS`).
Pure: no numpy, no clock.
"""

from __future__ import annotations

import math

from .jerk_phases import solve_phases
from .limits import Limits

#: ruckig's position precision of a planned profile (``Profile::check``)
P_PRECISION = 1e-8
#: iterations of the peak's root search (Newton converges in well under ten)
_MAX_ITERATIONS = 200

#: (duration, jerk) of each segment of a plan
Segments = list[tuple[float, float]]


def _ramp(dv: float, a: float, jerk: float) -> tuple[float, float]:
    """(duration, d duration / d dv) of a ramp of the velocity change ``dv`` >= 0 from
    and to zero acceleration, the acceleration within ``a``, the jerk within ``jerk``."""
    if dv * jerk >= a * a:
        return dv / a + a / jerk, 1.0 / a
    root = math.sqrt(dv * jerk)
    return 2.0 * root / jerk, (1.0 / root if root > 0.0 else math.inf)


def distance(vp: float, v0: float, acc: float, dec: float, jerk: float) -> tuple[float, float]:
    """(D(vp), D'(vp)): the distance from v0 (>= 0, at rest acceleration) to rest through
    the peak velocity ``vp`` >= v0, without a cruise, and its slope in vp."""
    t1, s1 = _ramp(vp - v0, acc, jerk)
    t2, s2 = _ramp(vp, dec, jerk)
    mean = (v0 + vp) / 2
    return mean * t1 + vp / 2 * t2, t1 / 2 + mean * s1 + t2 / 2 + vp / 2 * s2


def peak_velocity(d: float, v0: float, vmax: float, acc: float, dec: float, jerk: float) -> float:
    """The peak vp in [v0, vmax] with D(vp) = ``d``, for D(v0) <= d < D(vmax)."""
    lo, hi = v0, vmax
    vp = (lo + hi) / 2
    for _ in range(_MAX_ITERATIONS):
        f, slope = distance(vp, v0, acc, dec, jerk)
        f -= d
        if f == 0.0:
            return vp
        if f > 0.0:
            hi = vp
        else:
            lo = vp
        step = vp - f / slope if slope > 0.0 and math.isfinite(slope) else math.nan
        nxt = step if lo < step < hi else (lo + hi) / 2
        if nxt == vp or not lo < nxt < hi:
            break
        vp = nxt
    return vp


def position_segments(
    v0: float, a0: float, d: float, limits: Limits, a_max: float, a_min: float
) -> Segments | None:
    """The segments (duration, jerk) of the move by ``d`` from (``v0``, ``a0``) to rest,
    in the order :func:`.scurve._build` integrates them (a brake segment first, always
    empty here, so that every plan of the S-curve lane has the same layout: the three of
    the ramp to the peak, the cruise, the three of the ramp to rest); None when the
    closed form does not cover the state (ruckig plans it then). ``a_max`` and ``a_min``
    are the limits of the direction of ``d`` (:func:`.scurve.limit_pair`)."""
    if a0 != 0.0 or not (math.isfinite(d) and math.isfinite(v0)):
        return None
    sign = 1.0 if d >= 0.0 else -1.0
    dist, v = sign * d, sign * v0  # the move in its own direction
    vmax, acc, dec, jerk = limits.velocity, limits.acceleration, limits.deceleration, limits.jerk
    if v < 0.0 or v > vmax:
        return None
    stop, _ = distance(v, v, acc, dec, jerk)
    if dist < stop:
        return None  # it would pass the target: ruckig's
    top, _ = distance(vmax, v, acc, dec, jerk)
    if dist >= top:
        vp, cruise = vmax, (dist - top) / vmax
    elif dist == stop:
        vp, cruise = v, 0.0  # straight to rest (at rest on the target: no motion)
    else:
        vp, cruise = peak_velocity(dist, v, vmax, acc, dec, jerk), 0.0
    up = solve_phases(0.0, v0, sign * vp, a_max, a_min, jerk)
    down = solve_phases(0.0, sign * vp, 0.0, a_max, a_min, jerk)
    if up is None or down is None:
        return None
    t0, t1, t2, j = up
    u0, u1, u2, k = down
    return [(0.0, 0.0), (t0, j), (t1, 0.0), (t2, -j), (cruise, 0.0), (u0, k), (u1, 0.0), (u2, -k)]
