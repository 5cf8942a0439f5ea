"""Jerk-limited moves to a position in closed form: the moves the instructions start.

A jerk-limited MAM, MC_MoveAbsolute or MC_MoveRelative asks ruckig's third-order
position interface for a rest-to-rest profile: from the current state to the target at
zero velocity and acceleration, the velocity within ``vmax``, the acceleration within
[``a_min``, ``a_max``] (the pair of the direction of travel, :func:`.scurve.limit_pair`:
``acceleration`` while speeding up toward the target, ``deceleration`` while braking)
and the jerk within ``jerk``. This module plans the states a move starts from in
practice in closed form: toward the target, no faster than ``vmax``, far enough from it
to come to rest there without passing it, and either at a constant velocity (at rest,
or cruising) or accelerating within the limits without being carried beyond ``vmax``
(a move started while another one ramps). From such a state the time-optimal profile is

1. a ramp from (v0, a0) to a peak velocity vp at zero acceleration (three phases of
   constant jerk or two: :func:`.jerk_phases.solve_phases`, as the velocity plans),
2. a cruise at vp,
3. a ramp from vp to rest.

From a constant velocity, a ramp between two velocities at rest acceleration is
point-symmetric about its middle, so it covers the mean of its two velocities times its
duration: the distance of the whole profile is ``D(vp) = (v0 + vp) / 2 * T(vp - v0,
acceleration) + vp / 2 * T(vp, deceleration)``, where a ramp of a velocity change
``dv`` at the limit ``a`` lasts ``T = dv / a + a / jerk`` when ``dv >= a^2 / jerk``
(the limit is held) and ``2 sqrt(dv / jerk)`` otherwise. ``D`` increases with vp on
[v0, vmax]. When the distance is at least ``D(vmax)`` the peak is ``vmax`` and the
cruise covers the rest; otherwise there is no cruise and vp is the root of ``D(vp) =
distance`` (Newton's method inside a bisection bracket, on the rise vp - v0, which keeps
its precision when it is small). From an accelerating state the first ramp's distance
is integrated from its phases and the root found by a secant search, the peak no lower
than ``v0 + a0 |a0| / (2 jerk)``, where the acceleration can first be zero. The profile
is integrated as the velocity plans are (:func:`.scurve._build`); it must end within
ruckig's position precision (1e-8) of the target, where the last sample lands exactly,
as ruckig's does.

Every other state (moving away from the target, too close to stop before it, faster
than ``vmax`` or about to be, an acceleration beyond its limit) is ruckig's, and
counted (:data:`.scurve.FALLBACKS`): ruckig first brakes such a state into its limits,
which is not this profile. Its plan is sampled as this one is (:mod:`.ruckig_plan`).
Pure: no numpy, no clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from .jerk_phases import Phases, solve_phases
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


def distance(dv: float, v0: float, acc: float, dec: float, jerk: float) -> tuple[float, float]:
    """(D, dD/d dv): the distance from v0 (>= 0, at rest acceleration) to rest through
    the peak velocity v0 + ``dv`` (``dv`` >= 0), without a cruise, and its slope. The
    peak is measured from v0: a peak a few ulps above v0 keeps its precision."""
    t1, s1 = _ramp(dv, acc, jerk)
    vp = v0 + dv
    t2, s2 = _ramp(vp, dec, jerk)
    mean = v0 + dv / 2
    return mean * t1 + vp / 2 * t2, t1 / 2 + mean * s1 + t2 / 2 + vp / 2 * s2


def peak_rise(d: float, v0: float, vmax: float, acc: float, dec: float, jerk: float) -> float:
    """The rise dv in [0, vmax - v0] of the peak above v0 with D(dv) = ``d``, for D(0)
    <= d < D(vmax - v0): Newton's method inside a bisection bracket."""
    hi = vmax - v0
    return newton_rise(d, v0, acc, dec, jerk, 0.0, hi, hi / 2, _MAX_ITERATIONS)


def newton_rise(
    d: float,
    v0: float,
    acc: float,
    dec: float,
    jerk: float,
    lo: float,
    hi: float,
    dv: float,
    iterations: int,
) -> float:
    """:func:`peak_rise` from the bracket [``lo``, ``hi``] and the guess ``dv``, at most
    ``iterations`` more steps (where the planning of many moves at once hands over the
    few that converge slowly)."""
    for _ in range(iterations):
        f, slope = distance(dv, v0, acc, dec, jerk)
        f -= d
        if f == 0.0:
            return dv
        if f > 0.0:
            hi = dv
        else:
            lo = dv
        step = dv - f / slope if slope > 0.0 and math.isfinite(slope) else math.nan
        nxt = step if lo < step < hi else (lo + hi) / 2
        if nxt == dv or not lo < nxt < hi:
            break
        dv = nxt
    return dv


def position_segments(
    v0: float, a0: float, d: float, limits: Limits, a_max: float, a_min: float
) -> Segments | None:
    """The segments (duration, jerk) of the move by ``d`` from (``v0``, ``a0``) to rest,
    in the order :func:`.scurve._build` integrates them (a brake segment first, always
    empty here, so that every plan of the S-curve lane has the same layout: the three of
    the ramp to the peak, the cruise, the three of the ramp to rest); None when the
    closed form does not cover the state (ruckig plans it then). ``a_max`` and ``a_min``
    are the limits of the direction of ``d`` (:func:`.scurve.limit_pair`)."""
    if not (math.isfinite(d) and math.isfinite(v0) and math.isfinite(a0)):
        return None
    sign = 1.0 if d >= 0.0 else -1.0
    dist, v = sign * d, sign * v0  # the move in its own direction
    vmax, acc, dec, jerk = limits.velocity, limits.acceleration, limits.deceleration, limits.jerk
    if a0 != 0.0:
        return _from_motion(v0, a0, d, limits, a_max, a_min)
    if v < 0.0 or v > vmax:
        return None
    stop, _ = distance(0.0, v, acc, dec, jerk)
    if dist < stop:
        return None  # it would pass the target: ruckig's
    top, _ = distance(vmax - v, v, acc, dec, jerk)
    if dist >= top:
        dv, cruise = vmax - v, (dist - top) / vmax
    elif dist == stop:
        dv, cruise = 0.0, 0.0  # straight to rest (at rest on the target: no motion)
    else:
        dv, cruise = peak_rise(dist, v, vmax, acc, dec, jerk), 0.0
    # the ramp up from dv itself (solve_phases from the peak would lose dv's precision
    # to v0 + dv - v0), as solve_phases gives it from rest acceleration
    if dv * jerk >= acc * acc:
        t0, t1 = acc / jerk, dv / acc - acc / jerk
    else:
        t0, t1 = math.sqrt(dv * jerk) / jerk, 0.0
    j = sign * jerk
    down = solve_phases(0.0, sign * (v + dv), 0.0, a_max, a_min, jerk)
    if down is None:
        return None
    u0, u1, u2, k = down
    return [(0.0, 0.0), (t0, j), (t1, 0.0), (t0, -j), (cruise, 0.0), (u0, k), (u1, 0.0), (u2, -k)]


def _ramp_to(
    v0: float, a0: float, vp: float, a_max: float, a_min: float, jerk: float
) -> tuple[Phases, float] | None:
    """The phases of the ramp from (``v0``, ``a0``) to ``vp`` at rest acceleration
    (:func:`.jerk_phases.solve_phases`) and the distance it covers; None when there is
    no such ramp within the limits."""
    phases = solve_phases(a0, v0, vp, a_max, a_min, jerk)
    if phases is None:
        return None
    t0, t1, t2, j = phases
    p, v, a = 0.0, v0, a0
    for duration, jj in ((t0, j), (t1, 0.0), (t2, -j)):
        p = p + duration * (v + duration * (a / 2 + duration * jj / 6))
        v = v + duration * (a + duration * jj / 2)
        a = a + duration * jj
    return phases, p


def _from_motion(
    v0: float, a0: float, d: float, limits: Limits, a_max: float, a_min: float
) -> Segments | None:
    """:func:`position_segments` from an accelerating state (``a0`` within its limits):
    the same three parts, the first ramp from (v0, a0) (whose distance has no closed
    expression in the peak: a secant search), the peak no lower than where the
    acceleration can first be zero, ``v_lo = v0 + a0 |a0| / (2 jerk)`` (the direction
    of ``d`` taken as positive). None when the target is too close for that, ``v_lo``
    is a move away from the target, or the velocity is (or will be) beyond ``vmax``."""
    if not a_min <= a0 <= a_max:
        return None
    sign = 1.0 if d >= 0.0 else -1.0
    dist = sign * d
    vmax, dec, jerk = limits.velocity, limits.deceleration, limits.jerk
    v, a = sign * v0, sign * a0
    v_lo = v + a * abs(a) / (2 * jerk)
    if v > vmax or not 0.0 <= v_lo <= vmax or (a > 0.0 and v_lo >= vmax):
        # beyond the velocity limit (ruckig brakes into it first, its own way), or about
        # to be (at it and still speeding up, too), or a move away from the target
        return None

    def excess(vp: float) -> tuple[float, Phases] | None:
        """D(vp) - dist without a cruise, and the first ramp's phases."""
        ramp = _ramp_to(v0, a0, sign * vp, a_max, a_min, jerk)
        if ramp is None:
            return None
        phases, p = ramp
        t2, _ = _ramp(vp, dec, jerk)
        return sign * p + vp / 2 * t2 - dist, phases

    top = excess(vmax)
    if top is None:
        return None
    if top[0] <= 0.0:
        vp, cruise, up = vmax, -top[0] / vmax, top[1]
    else:
        bottom = excess(v_lo)
        if bottom is None or bottom[0] > 0.0:
            return None  # it would pass the target: ruckig's
        found = _secant(excess, v_lo, bottom[0], vmax, top[0])
        if found is None:
            return None
        vp, up = found
        cruise = 0.0
    down = solve_phases(0.0, sign * vp, 0.0, a_max, a_min, jerk)
    if down is None:
        return None
    t0, t1, t2, j = up
    u0, u1, u2, k = down
    return [(0.0, 0.0), (t0, j), (t1, 0.0), (t2, -j), (cruise, 0.0), (u0, k), (u1, 0.0), (u2, -k)]


def _secant(
    excess: Callable[[float], tuple[float, Phases] | None],
    lo: float,
    f_lo: float,
    hi: float,
    f_hi: float,
) -> tuple[float, Phases] | None:
    """The root of ``excess`` in [``lo``, ``hi``] (``f_lo`` <= 0 < ``f_hi``) by the
    Illinois variant of regula falsi: an excess within 1e-14 of the bracket's first
    span of excesses (well within ruckig's position precision), or a bracket a few
    ulps wide."""
    tolerance = 1e-14 * max(1.0, f_hi - f_lo)
    side = 0
    for _ in range(_MAX_ITERATIONS):
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        if not lo <= x <= hi:
            x = (lo + hi) / 2
        got = excess(x)
        if got is None:
            return None
        f, phases = got
        if abs(f) <= tolerance or hi - lo <= 4 * math.ulp(hi):
            return x, phases
        if f > 0.0:
            hi, f_hi = x, f
            if side == 1:
                f_lo /= 2
            side = 1
        else:
            lo, f_lo = x, f
            if side == -1:
                f_hi /= 2
            side = -1
    return None
