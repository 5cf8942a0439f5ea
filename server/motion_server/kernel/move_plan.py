"""Trapezoidal plans of many axes in one pass: the jogs and moves commanded in a scan.

A command that ramps an axis to a velocity (MAJ, MC_MoveVelocity, an MCD change of a
jog, the ramp of a paused move) is judged when it is commanded
(:func:`.trapezoid.judge_velocity_plan`: a plan that could not be held is refused at
once) and keeps its request (:attr:`.trapezoid.TrapezoidProfile.request`). When the
fast lanes take the processes commanded since the last step (``ProfileLane`` at its
rebuild, before the step), the plans of all of them are built here as arrays, with the
floating-point operations of :func:`.trapezoid.plan_velocity` and ``_build`` in the same
order, so every sample is bit-identical to the plan built one by one (which the reference
path, ``Controller(lanes=False)``, and any process that leaves the lane still build from
the same request).

Moves to a position are judged and planned when they are commanded (a move's plan is
its judgement): :func:`position_plans` builds the plans of many moves at once with the
operations of :func:`.trapezoid.plan_position` and ``_build``, and says which of them
the scalar planner would refuse (those are planned one by one, which raises as usual).

Pure: numpy only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .trapezoid import END_TOLERANCE, MAX_DURATION, SEGMENTS


class VelocityPlans(NamedTuple):
    """The plans of n velocity targets as ``ProfileLane`` holds them: ``start``,
    ``pos``, ``vel``, ``acc`` and ``half`` with one row of ``SEGMENTS`` values each, and
    ``done`` (a sample at t >= done ends the plan), ``end`` (when the target velocity is
    reached) and ``end_pos`` (the position there)."""

    start: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    half: np.ndarray
    done: np.ndarray
    end: np.ndarray
    end_pos: np.ndarray


def velocity_plans(
    dt: np.ndarray,
    p0: np.ndarray,
    v0: np.ndarray,
    target: np.ndarray,
    acceleration: np.ndarray,
    deceleration: np.ndarray,
) -> VelocityPlans:
    """``plan_velocity(dt, p0, v0, target, acceleration, deceleration)`` for every row
    of the arrays (each of shape (n,)), as arrays. The requests were judged when they were
    commanded: every plan here is finite and within the longest duration."""
    n = len(p0)
    # the limit pair of the direction of travel (_limit_pair) and the ramp's acceleration
    direction = np.where(target != 0.0, target, v0)
    forward = direction >= 0.0
    a_max = np.where(forward, acceleration, deceleration)
    a_min = np.where(forward, -deceleration, -acceleration)
    gap = target - v0
    a = np.where(gap > 0.0, a_max, a_min)
    q = gap / a
    # Python's max(q, 0.0): 0.0 only when q < 0.0 (a -0.0 or a NaN stays)
    duration = np.where(q < 0.0, 0.0, q)
    # _build over the segments (duration, a), then three of (0.0, 0.0)
    start = np.empty((n, SEGMENTS))
    pos = np.empty((n, SEGMENTS))
    vel = np.empty((n, SEGMENTS))
    acc = np.zeros((n, SEGMENTS))
    half = np.zeros((n, SEGMENTS))
    t = np.zeros(n)
    p = p0.astype(float, copy=True)
    v = v0.astype(float, copy=True)
    h = 0.5 * a
    start[:, 0], pos[:, 0], vel[:, 0], acc[:, 0], half[:, 0] = t, p, v, a, h
    p = p + duration * (v + duration * h)
    v = v + duration * a
    t = t + duration
    # then segments of zero duration and acceleration (h = 0.5 * 0.0 = 0.0): each adds
    # 0.0 * (v + 0.0 * 0.0), 0.0 * 0.0 and 0.0, which for the finite values of a judged
    # plan changes a -0.0 into 0.0 the first time and nothing after
    start[:, 1], pos[:, 1], vel[:, 1] = t, p, v
    t = t + 0.0
    p = p + 0.0 * (v + 0.0)
    v = v + 0.0
    for k in range(2, SEGMENTS):
        start[:, k], pos[:, k], vel[:, k] = t, p, v
    done = t - END_TOLERANCE * dt
    return VelocityPlans(start, pos, vel, acc, half, done, t, p)


def velocity_plan_row(
    dt: float, p0: float, v0: float, target: float, acceleration: float, deceleration: float
) -> tuple[tuple[float, ...], ...]:
    """:func:`velocity_plans` of one row, in Python floats (the same IEEE operations in
    the same order, each rounded as numpy rounds it): ``(start, pos, vel, acc, half)``
    as tuples of ``SEGMENTS`` values, then ``((done, end, end_pos),)``. Cheaper than the
    arrays for the few distinct plans of a batch of jogs from rest, whose plans depend
    only on their target (:func:`..jog_batch.start_jogs`)."""
    direction = target if target != 0.0 else v0
    if direction >= 0.0:
        a_max, a_min = acceleration, -deceleration
    else:
        a_max, a_min = deceleration, -acceleration
    gap = target - v0
    a = a_max if gap > 0.0 else a_min
    q = gap / a
    duration = 0.0 if q < 0.0 else q
    t = 0.0
    p = float(p0)
    v = float(v0)
    h = 0.5 * a
    start = [t]
    pos = [p]
    vel = [v]
    p = p + duration * (v + duration * h)
    v = v + duration * a
    t = t + duration
    start.append(t)
    pos.append(p)
    vel.append(v)
    t = t + 0.0
    p = p + 0.0 * (v + 0.0)
    v = v + 0.0
    for _ in range(2, SEGMENTS):
        start.append(t)
        pos.append(p)
        vel.append(v)
    zeros = (0.0,) * (SEGMENTS - 1)
    done = t - END_TOLERANCE * dt
    return (tuple(start), tuple(pos), tuple(vel), (a, *zeros), (h, *zeros), (done, t, p))


class PositionPlans(NamedTuple):
    """The plans of n position targets: ``start``, ``pos``, ``vel``, ``acc`` and
    ``half`` with one row of ``SEGMENTS`` values each (what ``trapezoid.Plan`` holds),
    ``end`` (when the target is reached, at rest), ``done`` (a sample at t >= done ends
    the plan) and ``ok``: the plan is one :func:`.trapezoid.plan_position` returns
    (False: it refuses it, too long or beyond any float; the other fields of that row
    mean nothing)."""

    start: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    half: np.ndarray
    end: np.ndarray
    done: np.ndarray
    ok: np.ndarray


def _floor0(x: np.ndarray) -> np.ndarray:
    """Python's ``max(x, 0.0)``: 0.0 only when x < 0.0 (a -0.0 or a NaN stays)."""
    return np.where(x < 0.0, 0.0, x)


def position_plans(
    dt: np.ndarray,
    p0: np.ndarray,
    v0: np.ndarray,
    target: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    deceleration: np.ndarray,
) -> PositionPlans:
    """``plan_position(dt, p0, v0, target, velocity, acceleration, deceleration)`` for
    every row of the arrays (each of shape (n,), the limits validated: positive and
    finite), as arrays: each branch computed for every row and chosen per row, so every
    selected value comes from the scalar planner's operations in its order."""
    n = len(p0)
    with np.errstate(all="ignore"):
        s = np.where(target - p0 >= 0.0, 1.0, -1.0)
        acc, dec, vmax = acceleration, deceleration, velocity
        u = s * v0
        remaining = s * (target - p0)
        # braking first, from beyond the velocity limit either way
        over = u > vmax
        under = ~over & (u < -vmax)
        t_over = (u - vmax) / dec
        t_under = (-vmax - u) / acc
        brake_t = np.where(over, t_over, np.where(under, t_under, 0.0))
        brake_a = np.where(over, -dec, np.where(under, acc, 0.0))
        remaining = np.where(
            over,
            remaining - t_over * (u + t_over * (0.5 * -dec)),
            np.where(under, remaining - t_under * (u + t_under * (0.5 * acc)), remaining),
        )
        u = np.where(over, vmax, np.where(under, -vmax, u))
        stop = np.where(u >= 0.0, u * u / (2.0 * dec), -(u * u) / (2.0 * acc))
        forward = remaining >= stop
        # forward: accelerate toward the target, cruise, decelerate onto it
        f_peak = np.sqrt(_floor0((2.0 * acc * dec * remaining + dec * u * u) / (acc + dec)))
        f_cruise = remaining - (vmax * vmax - u * u) / (2.0 * acc) - vmax * vmax / (2.0 * dec)
        f_top = f_peak > vmax
        f1 = np.where(f_top, (vmax - u) / acc, _floor0(f_peak - u) / acc)
        f2 = np.where(f_top, _floor0(f_cruise) / vmax, 0.0)
        f3 = np.where(f_top, vmax / dec, f_peak / dec)
        # too close (or behind): brake through rest, come back and stop on the target
        b_peak = np.sqrt(_floor0((acc * u * u - 2.0 * acc * dec * remaining) / (acc + dec)))
        b_back = (u * u - vmax * vmax) / (2.0 * dec) - vmax * vmax / (2.0 * acc)
        b_top = b_peak > vmax
        b1 = np.where(b_top, (u + vmax) / dec, _floor0(u + b_peak) / dec)
        b2 = np.where(b_top, _floor0(b_back - remaining) / vmax, 0.0)
        b3 = np.where(b_top, vmax / acc, b_peak / acc)
        durations = (
            brake_t,
            np.where(forward, f1, b1),
            np.where(forward, f2, b2),
            np.where(forward, f3, b3),
        )
        accels = (
            s * brake_a,
            s * np.where(forward, acc, -dec),
            s * 0.0,
            s * np.where(forward, -dec, acc),
        )
        # _build
        start = np.empty((n, SEGMENTS))
        pos = np.empty((n, SEGMENTS))
        vel = np.empty((n, SEGMENTS))
        seg_acc = np.empty((n, SEGMENTS))
        half = np.empty((n, SEGMENTS))
        t = np.zeros(n)
        p = p0.astype(float, copy=True)
        v = v0.astype(float, copy=True)
        finite = np.isfinite(p) & np.isfinite(v)
        for k in range(SEGMENTS):
            d, a = durations[k], accels[k]
            h = 0.5 * a
            start[:, k], pos[:, k], vel[:, k], seg_acc[:, k], half[:, k] = t, p, v, a, h
            p = p + d * (v + d * h)
            v = v + d * a
            t = t + d
            finite &= np.isfinite(p) & np.isfinite(v)
        ok = np.isfinite(t) & (t <= MAX_DURATION) & finite
        done = t - END_TOLERANCE * dt
    return PositionPlans(start, pos, vel, seg_acc, half, t, done, ok)
