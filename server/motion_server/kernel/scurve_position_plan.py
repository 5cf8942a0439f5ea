"""Jerk-limited moves from rest of many distances in one pass.

Absolute moves to one target from different positions give every axis a distance of its
own: :func:`plans_from_rest` plans them together, as arrays, with the floating-point
operations of :func:`.scurve.plan_jerk_position` from rest (``position_segments``,
``peak_rise``'s Newton steps element by element, ``solve_phases`` of the ramp to rest,
``_build``) in the same order, so every plan is bit-identical to the one built one by
one (the reference path and any move started alone build it so). A distance the scalar
planner would refuse, or leave to ruckig, has no plan here: the caller builds it one by
one, which raises or falls back as usual.

Pure: numpy only.
"""

from __future__ import annotations

import math

import numpy as np

from .jerk_phases import _A_EPS, _A_PRECISION, _T_EPS, _V_PRECISION, uddu_end
from .limits import Limits
from .scurve import POSITION_SEGMENTS, JerkPlan
from .scurve_position import _MAX_ITERATIONS, P_PRECISION, newton_rise
from .trapezoid import END_TOLERANCE, MAX_DURATION

#: below this many moves still searching for their peak, the search goes on one by one
#: (a few converge slowly, by bisection: a pass of arrays per step would cost more)
_STRAGGLERS = 8


def _ramp(dv: np.ndarray, a: float, jerk: float) -> tuple[np.ndarray, np.ndarray]:
    """``scurve_position._ramp`` of every element (within ``np.errstate``: 1 / 0)."""
    hold = dv * jerk >= a * a
    root = np.sqrt(dv * jerk)
    slope = np.where(root > 0.0, 1.0 / root, math.inf)
    t = np.where(hold, dv / a + a / jerk, 2.0 * root / jerk)
    return t, np.where(hold, 1.0 / a, slope)


def _distance(
    dv: np.ndarray, v0: np.ndarray, acc: float, dec: float, jerk: float
) -> tuple[np.ndarray, np.ndarray]:
    """``scurve_position.distance`` of every element (within ``np.errstate``: 0 * inf at
    a rise of 0, nan as in Python floats)."""
    t1, s1 = _ramp(dv, acc, jerk)
    vp = v0 + dv
    t2, s2 = _ramp(vp, dec, jerk)
    mean = v0 + dv / 2
    return mean * t1 + vp / 2 * t2, t1 / 2 + mean * s1 + t2 / 2 + vp / 2 * s2


def _peak_rise(
    d: np.ndarray, v0: np.ndarray, vmax: float, acc: float, dec: float, jerk: float
) -> np.ndarray:
    """``scurve_position.peak_rise`` of every element: the same Newton and bisection
    steps, each element stopping where the scalar loop stops; the last few still
    searching finish one by one (``newton_rise``, from where they are)."""
    lo = np.zeros_like(d)
    hi = vmax - v0
    dv = hi / 2
    active = np.ones(len(d), dtype=bool)
    for done in range(_MAX_ITERATIONS):
        left = np.flatnonzero(active)
        if len(left) <= _STRAGGLERS:
            for i in left.tolist():
                dv[i] = newton_rise(
                    float(d[i]), float(v0[i]), acc, dec, jerk, float(lo[i]), float(hi[i]),
                    float(dv[i]), _MAX_ITERATIONS - done,
                )  # fmt: skip
            break
        f, slope = _distance(dv, v0, acc, dec, jerk)
        f = f - d
        found = active & (f == 0.0)
        active &= ~found
        above = active & (f > 0.0)
        below = active & ~(f > 0.0)
        hi = np.where(above, dv, hi)
        lo = np.where(below, dv, lo)
        usable = (slope > 0.0) & np.isfinite(slope)
        step = np.where(usable, dv - f / slope, math.nan)
        inside = (lo < step) & (step < hi)
        nxt = np.where(inside, step, (lo + hi) / 2)
        stop = (nxt == dv) | ~((lo < nxt) & (nxt < hi))
        active &= ~stop
        dv = np.where(active, nxt, dv)
    return dv


def _accepted(
    t0: np.ndarray,
    t1: np.ndarray,
    t2: np.ndarray,
    a0: float,
    v0: np.ndarray,
    vf: float,
    jf: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> np.ndarray:
    """``jerk_phases._accepted`` of every element."""
    j0 = np.where(t0 > 0.0, jf, 0.0)
    j2 = np.where(t2 > 0.0, -jf, 0.0)
    a1, a3, v3 = uddu_end(t0, t1, t2, a0, v0, j0, j2)
    return (
        (np.abs(v3 - vf) < _V_PRECISION)
        & (np.abs(a3) < _A_PRECISION)
        & (lo <= a1)
        & (a1 <= hi)
        & (lo <= a3)
        & (a3 <= hi)
    )


def _to_rest(
    v0: np.ndarray, a_max: np.ndarray, a_min: np.ndarray, jerk: float, top: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``solve_phases(0.0, v0, 0.0, a_max, a_min, jerk)`` of every element: (t0, t1,
    t2, jerk, found), the candidates tried in its order, the first accepted kept.
    ``top`` is ``max(a_max, -a_min)``, the same for every element (the larger of the
    two limits, whichever the direction)."""
    a0, vf = 0.0, 0.0
    n = len(v0)
    vd = vf - v0
    up = vd >= 0.0
    a_eps = _A_EPS + 8.0 * math.ulp(top)
    lo = a_min - a_eps
    hi = a_max + a_eps
    out = [np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)]
    found = np.zeros(n, dtype=bool)

    def keep(ok: np.ndarray, t0: np.ndarray, t1: np.ndarray, t2: np.ndarray, j: np.ndarray) -> None:
        take = ok & ~found
        for k, x in enumerate((t0, t1, t2, j)):
            out[k] = np.where(take, x, out[k])
        found[:] = found | take

    for first in (True, False):
        use_max = up == first  # (toward a higher velocity: a_max first)
        peak = np.where(use_max, a_max, a_min)
        j = np.where(use_max, jerk, -jerk)
        h1 = a0 * a0 / 2 + j * vd
        real = h1 >= 0.0
        h = np.sqrt(np.where(real, h1, 0.0))
        zero = np.zeros(n)
        t0 = -(a0 + h) / j
        t2 = -h / j
        ok = real & (t0 >= 0.0) & (t2 >= 0.0)
        ok &= _accepted(t0, zero, t2, a0, v0, vf, j, lo, hi)
        keep(ok, t0, zero, t2, j)
        t0 = (-a0 + h) / j
        t2 = h / j
        ok = real & (t0 >= 0.0) & (t2 >= 0.0)
        ok &= _accepted(t0, zero, t2, a0, v0, vf, j, lo, hi)
        keep(ok, t0, zero, t2, j)
        t1 = a0 * a0 / (2 * peak * j) - peak / j + vd / peak
        t0 = (peak - a0) / j
        t2 = peak / j
        ok = (t1 >= _T_EPS) & (t0 >= 0.0) & (t2 >= 0.0)
        ok &= _accepted(t0, t1, t2, a0, v0, vf, j, lo, hi)
        keep(ok, t0, t1, t2, j)
    return out[0], out[1], out[2], out[3], found


def plans_from_rest(dt: float, distances: list[float], limits: Limits) -> list[JerkPlan | None]:
    """``plan_jerk_position(dt, 0.0, 0.0, 0.0, d, limits)`` for every finite distance
    ``d`` (``limits`` validated, with a jerk limit), or None where that would not give a
    plan (a refusal or ruckig's: the caller plans those one by one)."""
    # (Python floats give inf and nan where numpy warns: 1 / 0, 0 * inf)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _plans_from_rest(dt, distances, limits)


def _plans_from_rest(dt: float, distances: list[float], limits: Limits) -> list[JerkPlan | None]:
    d = np.array(distances, dtype=float)
    n = len(d)
    vmax, acc, dec, jerk = limits.velocity, limits.acceleration, limits.deceleration, limits.jerk
    forward = d >= 0.0
    sign = np.where(forward, 1.0, -1.0)
    a_max = np.where(forward, acc, dec)
    a_min = np.where(forward, -dec, -acc)
    dist = sign * d
    v = sign * 0.0
    stop, _ = _distance(np.zeros(n), v, acc, dec, jerk)
    top, _ = _distance(vmax - v, v, acc, dec, jerk)
    cruising = dist >= top
    resting = ~cruising & (dist == stop)
    searching = ~cruising & ~resting
    dv = np.where(cruising, vmax - v, 0.0)
    cruise = np.where(cruising, (dist - top) / vmax, 0.0)
    if searching.any():
        at = np.flatnonzero(searching)
        dv[at] = _peak_rise(dist[at], v[at], vmax, acc, dec, jerk)
    hold = dv * jerk >= acc * acc
    t0 = np.where(hold, acc / jerk, np.sqrt(dv * jerk) / jerk)
    t1 = np.where(hold, dv / acc - acc / jerk, 0.0)
    j = sign * jerk
    u0, u1, u2, k, found = _to_rest(sign * (v + dv), a_max, a_min, jerk, max(acc, dec))
    zero = np.zeros(n)
    durations = (zero, t0, t1, t0, cruise, u0, u1, u2)
    jerks = (zero, j, zero, -j, zero, k, zero, -k)
    # _build's integration, one segment after the other
    rows: list[list[np.ndarray]] = [[] for _ in range(8)]
    t = np.zeros(n)
    p = np.zeros(n)
    vel = np.zeros(n)
    a = np.zeros(n)
    for s in range(POSITION_SEGMENTS):
        duration, js = durations[s], jerks[s]
        for field, x in zip(rows, (t, p, vel, a, a / 2, js, js / 2, js / 6), strict=True):
            field.append(x)
        p = p + duration * (vel + duration * (a / 2 + duration * js / 6))
        vel = vel + duration * (a + duration * js / 2)
        a = a + duration * js
        t = t + duration
    finite = np.isfinite(t) & ~(t > MAX_DURATION) & np.isfinite(p) & np.isfinite(vel)
    for field in rows[1:4]:
        for x in field:
            finite &= np.isfinite(x)
    ok = found & finite & (np.abs(p - d) <= P_PRECISION)
    done = t - END_TOLERANCE * dt
    columns = [np.stack(field, axis=1).tolist() for field in rows]
    t_list, done_list, targets = t.tolist(), done.tolist(), d.tolist()
    plans: list[JerkPlan | None] = [None] * n
    c0, c1, c2, c3, c4, c5, c6, c7 = columns
    for i in np.flatnonzero(ok).tolist():
        plans[i] = JerkPlan(
            tuple(c0[i]), tuple(c1[i]), tuple(c2[i]), tuple(c3[i]), tuple(c4[i]),
            tuple(c5[i]), tuple(c6[i]), tuple(c7[i]), t_list[i], done_list[i], targets[i],
            0.0,
        )  # fmt: skip
    return plans
