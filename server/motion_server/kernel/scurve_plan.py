"""Jerk-limited velocity plans of many axes in one pass: the S-curve ramps of a scan.

A command that ramps an axis to a velocity with a jerk limit (MAJ, MC_MoveVelocity, an
MCD change of a jog, a jerk-limited stop, a paused move, a clutch's catch-up ramp) is
judged when it is commanded (:meth:`.scurve.SCurveProfile.to_velocity`: the segments of
the closed form are found, :func:`.scurve.jerk_segments`, a case the closed form does
not cover goes to ruckig at once, a plan that could not be held is refused,
:func:`.scurve.judge_request`) and keeps its request
(:attr:`.scurve.SCurveProfile.request`). When the S-curve lane takes the ramps commanded
since the last step (at its rebuild, before the step), their plans are built here as
arrays, with the floating-point operations of :func:`.scurve._build` in the same order,
so every sample is bit-identical to the plan built one by one (which the reference path,
``Controller(lanes=False)``, and any ramp that leaves the lane still build from the same
request).

Pure: numpy only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .scurve import SEGMENTS
from .trapezoid import END_TOLERANCE


class JerkPlans(NamedTuple):
    """The plans of n velocity targets as the S-curve lane holds them: ``start``,
    ``pos``, ``vel``, ``acc``, ``half``, ``jerk``, ``jhalf``, ``jsixth`` with one row of
    ``SEGMENTS`` values each (the fields of :class:`.scurve.JerkPlan`), and ``done`` (a
    sample at t >= done ends the plan), ``end`` (when the target velocity is reached),
    ``end_pos`` (the position there)."""

    start: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    half: np.ndarray
    jerk: np.ndarray
    jhalf: np.ndarray
    jsixth: np.ndarray
    done: np.ndarray
    end: np.ndarray
    end_pos: np.ndarray


#: the columns of a request (:data:`.scurve.JerkRequest`) after dt
P0, V0, A0, TARGET, TB, JB, T0, J, T1, T2 = range(10)


def jerk_plans(dt: np.ndarray, requests: np.ndarray) -> JerkPlans:
    """``build_request(dt, request)`` for every row: ``dt`` of shape (n,), ``requests`` of
    shape (n, 10), one judged :data:`.scurve.JerkRequest` a row. Every plan here is
    finite and within the longest duration (judged when it was commanded)."""
    n = len(dt)
    r = requests.T
    j = r[J]
    # the segments (duration, jerk): the brake, jerk toward the peak, the hold, jerk back
    durations = (r[TB], r[T0], r[T1], r[T2])
    jerk = np.empty((SEGMENTS, n))
    jerk[0] = r[JB]
    jerk[1] = j
    jerk[2] = 0.0
    np.negative(j, out=jerk[3])
    # one row per segment while integrating (each row contiguous), transposed at the end
    start = np.empty((SEGMENTS, n))
    pos = np.empty((SEGMENTS, n))
    vel = np.empty((SEGMENTS, n))
    acc = np.empty((SEGMENTS, n))
    t = np.zeros(n)
    p = r[P0]
    v = r[V0]
    a = r[A0]
    for s in range(SEGMENTS):
        d = durations[s]
        start[s] = t
        pos[s] = p
        vel[s] = v
        acc[s] = a
        # p + d * (v + d * (a / 2 + d * j / 6)), v + d * (a + d * j / 2), a + d * j:
        # d * j / 6 is (d * j) / 6, so d * j is computed once
        dj = d * jerk[s]
        p = p + d * (v + d * (a / 2 + dj / 6))
        v = v + d * (a + dj / 2)
        a = a + dj
        t = t + d
    done = t - END_TOLERANCE * dt
    return JerkPlans(
        start.T, pos.T, vel.T, acc.T, acc.T / 2, jerk.T, jerk.T / 2, jerk.T / 6, done, t, p
    )


def jerk_plan_row(dt: float, request: tuple[float, ...]) -> tuple[tuple[float, ...], ...]:
    """:func:`jerk_plans` of one row, in Python floats (the same IEEE operations in the
    same order, each rounded as numpy rounds it): ``(start, pos, vel, acc, half, jerk,
    jhalf, jsixth)`` as tuples of ``SEGMENTS`` values, then ``((done, end, end_pos),)``.
    Cheaper than the arrays for the few distinct plans of a batch of jogs from rest,
    whose plans depend only on their target (:func:`..jog_batch.start_jogs`)."""
    r = request
    j = r[J]
    durations = (r[TB], r[T0], r[T1], r[T2])
    jerk = (r[JB], j, 0.0, -j)
    start, pos, vel, acc = [], [], [], []
    t = 0.0
    p, v, a = r[P0], r[V0], r[A0]
    for s in range(SEGMENTS):
        d = durations[s]
        start.append(t)
        pos.append(p)
        vel.append(v)
        acc.append(a)
        dj = d * jerk[s]
        p = p + d * (v + d * (a / 2 + dj / 6))
        v = v + d * (a + dj / 2)
        a = a + dj
        t = t + d
    done = t - END_TOLERANCE * dt
    return (
        tuple(start), tuple(pos), tuple(vel), tuple(acc), tuple(x / 2 for x in acc), jerk,
        tuple(x / 2 for x in jerk), tuple(x / 6 for x in jerk), (done, t, p),
    )  # fmt: skip
