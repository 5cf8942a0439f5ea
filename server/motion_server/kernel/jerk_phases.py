"""The phases of a jerk-limited velocity ramp in closed form: ruckig's
``VelocityThirdOrderStep1`` from (v0, a0) to a velocity at rest acceleration, tried in its
order and accepted by its own checks. The velocity plans (:mod:`.scurve`) and the
position plans (:mod:`.scurve_position`, a ramp up to a peak and one down to rest) are
made of these ramps.
"""

from __future__ import annotations

import math
import sys
from typing import TypeVar

import numpy as np

#: ruckig's acceptance tolerances of a velocity profile (``Profile::check_for_velocity``)
_A_EPS = 1e-12
_V_PRECISION = 1e-8
_A_PRECISION = 1e-10
_T_EPS = sys.float_info.epsilon

#: a float, or an array of them (:func:`uddu_end`)
_T = TypeVar("_T", float, np.ndarray)

#: (t0, t1, t2, jerk of phase 0): the phases of a ramp (phase 2's jerk is minus phase 0's)
Phases = tuple[float, float, float, float]


def _accepted(
    t0: float,
    t1: float,
    t2: float,
    a0: float,
    v0: float,
    vf: float,
    jf: float,
    lo: float,
    hi: float,
) -> bool:
    """ruckig's ``check_for_velocity`` (UDDU) of the phases (``t0``, ``t1``, ``t2``), each
    >= 0, with jerk ``jf``; the acceleration within [``lo``, ``hi``] (the limits with
    their tolerance, :func:`solve_phases`)."""
    j0 = jf if t0 > 0.0 else 0.0
    j2 = -jf if t2 > 0.0 else 0.0
    a1, a3, v3 = uddu_end(t0, t1, t2, a0, v0, j0, j2)
    return (
        abs(v3 - vf) < _V_PRECISION and abs(a3) < _A_PRECISION and lo <= a1 <= hi and lo <= a3 <= hi
    )


def uddu_end(t0: _T, t1: _T, t2: _T, a0: float | _T, v0: _T, j0: _T, j2: _T) -> tuple[_T, _T, _T]:
    """The acceleration after the first phase, and the acceleration and velocity after
    the last, of the phases (``t0`` at jerk ``j0``, ``t1`` at none, ``t2`` at ``j2``) from
    (``v0``, ``a0``): the same operations on floats as on arrays (the many-distance
    planner, :mod:`.scurve_position_plan`, checks its phases with them)."""
    a1 = a0 + t0 * j0
    v1 = v0 + t0 * (a0 + t0 * j0 / 2)
    v2 = v1 + t1 * a1
    a3 = a1 + t2 * j2
    v3 = v2 + t2 * (a1 + t2 * j2 / 2)
    return a1, a3, v3


def solve_phases(
    a0: float, v0: float, vf: float, a_max: float, a_min: float, jerk: float
) -> Phases | None:
    """(t0, t1, t2, jerk of phase 0) from (v0, a0), a0 within the limits, to vf at rest
    acceleration: the first profile ruckig's ``VelocityThirdOrderStep1`` accepts, tried in
    its order; None when none is accepted."""
    vd = vf - v0
    if vd >= 0.0:
        order = ((a_max, jerk), (a_min, -jerk))
    else:
        order = ((a_min, -jerk), (a_max, jerk))
    # ruckig's 1e-12 is a few ulps of an acceleration of 1e4: a peak computed to land on
    # the limit may round beyond it by more; allow those few ulps too
    a_eps = _A_EPS + 8.0 * math.ulp(max(a_max, -a_min))
    lo = a_min - a_eps
    hi = a_max + a_eps
    for peak, j in order:
        # no acceleration hold: the peak is where the two jerk phases meet (phases of
        # negative (or NaN) duration are never accepted: not checked further)
        h1 = a0 * a0 / 2 + j * vd
        if h1 >= 0.0:
            h = math.sqrt(h1)
            t0 = -(a0 + h) / j
            t2 = -h / j
            if t0 >= 0.0 and t2 >= 0.0 and _accepted(t0, 0.0, t2, a0, v0, vf, j, lo, hi):
                return t0, 0.0, t2, j
            t0 = (-a0 + h) / j
            t2 = h / j
            if t0 >= 0.0 and t2 >= 0.0 and _accepted(t0, 0.0, t2, a0, v0, vf, j, lo, hi):
                return t0, 0.0, t2, j
        # the acceleration limit held between the two jerk phases
        t1 = a0 * a0 / (2 * peak * j) - peak / j + vd / peak
        t0 = (peak - a0) / j
        t2 = peak / j
        if (
            t1 >= _T_EPS
            and t0 >= 0.0
            and t2 >= 0.0
            and _accepted(t0, t1, t2, a0, v0, vf, j, lo, hi)
        ):
            return t0, t1, t2, j
    return None
