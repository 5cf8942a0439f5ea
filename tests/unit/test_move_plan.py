"""Velocity plans built together (:func:`motion_server.kernel.move_plan.velocity_plans`)
are the plans :func:`motion_server.kernel.trapezoid.plan_velocity` builds one by one, bit
for bit (signed zeros included); what it refuses is refused when the jog is commanded
(:func:`~motion_server.kernel.trapezoid.judge_velocity_plan`), with the same error.
Position plans built together (:func:`~motion_server.kernel.move_plan.position_plans`)
are those of :func:`~motion_server.kernel.trapezoid.plan_position`, and are marked
refused exactly where it refuses one."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import ErrorCode, Limits, MotionError
from motion_server.kernel.move_plan import position_plans, velocity_plan_row, velocity_plans
from motion_server.kernel.trapezoid import (
    MAX_DURATION,
    TrapezoidProfile,
    judge_velocity_plan,
    plan_position,
    plan_velocity,
)

velocities = st.one_of(
    st.sampled_from([0.0, -0.0, 1.0, -1.0, 100.0, -250.0]),
    st.floats(-1e4, 1e4, allow_nan=False),
)
rates = st.one_of(st.sampled_from([1.0, 1000.0, 5000.0]), st.floats(1e-3, 1e6))
dts = st.sampled_from([0.0005, 0.001, 0.002, 0.004, 0.032])

Request = tuple[float, float, float, float, float, float]


def bits(x: object) -> bytes:
    return np.asarray(x, dtype=float).tobytes()


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(dts, st.floats(-1e3, 1e3), velocities, velocities, rates, rates),
        min_size=1,
        max_size=20,
    )
)
def test_plans_built_together_are_the_plans_built_one_by_one(requests: list[Request]) -> None:
    built = []
    for r in requests:
        # (one refused when commanded is never planned with the others)
        with contextlib.suppress(MotionError):
            built.append((r, plan_velocity(*r)))
    if not built:
        return
    cols = [np.array(c, dtype=float) for c in zip(*(r for r, _ in built), strict=True)]
    plans = velocity_plans(*cols)
    for k, (_, one) in enumerate(built):
        for field in ("start", "pos", "vel", "acc", "half"):
            assert bits(getattr(plans, field)[k]) == bits(getattr(one, field)), (k, field)
        assert bits(plans.done[k]) == bits(one.done), k


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(dts, st.floats(-1e3, 1e3), velocities, velocities, rates, rates),
                min_size=1, max_size=8))  # fmt: skip
def test_a_plan_built_alone_in_python_floats_is_the_arrays_row(requests: list[Request]) -> None:
    """``velocity_plan_row`` (the plan of a batch of jogs from rest to one target)
    gives, bit for bit, the row ``velocity_plans`` gives for the same request."""
    judged = []
    for r in requests:
        with contextlib.suppress(MotionError):
            judge_velocity_plan(*r[1:])
            judged.append(r)
    if not judged:
        return
    plans = velocity_plans(*(np.array(c, dtype=float) for c in zip(*judged, strict=True)))
    for k, r in enumerate(judged):
        start, pos, vel, acc, half, (done, end, end_pos) = velocity_plan_row(*r)
        assert bits(start) == bits(plans.start[k]), k
        assert bits(pos) == bits(plans.pos[k]), k
        assert bits(vel) == bits(plans.vel[k]), k
        assert bits(acc) == bits(plans.acc[k]), k
        assert bits(half) == bits(plans.half[k]), k
        assert bits((done, end, end_pos)) == bits(
            (plans.done[k], plans.end[k], plans.end_pos[k])
        ), k


def test_a_ramp_of_a_whole_number_of_periods_ends_on_its_last_period() -> None:
    """100 mm/s at 1000 mm/s² lasts 0.1 s: its end, ``done``, lies a hair (1e-9 of a
    period) before 0.1 s, so that the 100th sample of 1 ms ends the ramp whatever the
    rounding of 100 x 0.001."""
    plans = velocity_plans(*(np.array([x]) for x in (0.001, 0.0, 0.0, 100.0, 1000.0, 1000.0)))
    assert plans.done[0] == 0.1 - 1e-9 * 0.001
    assert plans.done[0] <= 100 * 0.001


@pytest.mark.parametrize(
    ("v0", "target", "rate"),
    [
        (0.0, 1e6, 1e-3),  # 1e9 s: beyond the longest plan
        (0.0, 1.0, MAX_DURATION**-1 / 2),  # just beyond
        (0.0, 1e300, 1e-300),  # not finite
        (1e308, -1e308, 1.0),
    ],
)
def test_what_a_plan_refuses_is_refused_when_commanded(
    v0: float, target: float, rate: float
) -> None:
    with pytest.raises(MotionError) as planned:
        plan_velocity(0.001, 0.0, v0, target, rate, rate)
    with pytest.raises(MotionError) as judged:
        judge_velocity_plan(0.0, v0, target, rate, rate)
    assert (judged.value.code, str(judged.value)) == (planned.value.code, str(planned.value))
    prof = TrapezoidProfile(0.001, v0)
    with pytest.raises(MotionError):
        prof.to_velocity(target, Limits(1.0, rate, rate))
    assert prof.plan is None and prof.request is None  # nothing changed


@settings(max_examples=300, deadline=None)
@given(st.floats(-1e3, 1e3), velocities, velocities, rates, rates)
def test_a_requested_plan_is_the_plan(
    p0: float, v0: float, target: float, acc: float, dec: float
) -> None:
    """A profile given a velocity target judges it and builds the very same plan when it
    is first read."""
    prof = TrapezoidProfile(0.002, v0, 0.0, p0)
    try:
        one = plan_velocity(0.002, p0, v0, target, acc, dec)
    except MotionError:
        with pytest.raises(MotionError):
            prof.to_velocity(target, Limits(1.0, acc, dec))
        return
    prof.to_velocity(target, Limits(1.0, acc, dec))
    assert prof.request is not None and prof.planned
    assert prof.plan == one and prof.request is None


# -- position plans ---------------------------------------------------------------------

positions = st.one_of(
    st.sampled_from([0.0, -0.0, 1.0, -1.0, 25.5, -250.0, 1e-300]),
    st.floats(-1e4, 1e4),
    st.sampled_from([1e300, -1e300, 1e308]),  # beyond any plan: refused
)
#: velocities beyond the limits drawn often: the braking branches
starts = st.one_of(
    st.sampled_from([0.0, -0.0, 50.0, -50.0, 500.0, -500.0]),
    st.floats(-1e4, 1e4),
)
limits_of = st.one_of(st.sampled_from([1e-6, 1.0, 100.0, 1000.0]), st.floats(1e-3, 1e6))

PositionRequest = tuple[float, float, float, float, float, float, float]


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(dts, positions, starts, positions, limits_of, limits_of, limits_of),
        min_size=1,
        max_size=20,
    )
)
def test_position_plans_built_together_are_the_plans_built_one_by_one(
    requests: list[PositionRequest],
) -> None:
    """Every branch (from rest, from motion toward and away from the target, beyond the
    velocity limit either way, too close to stop on it, cruising or not): the same
    numbers bit for bit where the scalar planner builds a plan, and ``ok`` False exactly
    where it refuses one (too long, or beyond any float)."""
    cols = [np.array(c, dtype=float) for c in zip(*requests, strict=True)]
    dt, p0, v0, target, vmax, acc, dec = cols
    plans = position_plans(dt, p0, v0, target, vmax, acc, dec)
    for k, r in enumerate(requests):
        try:
            one = plan_position(r[0], r[1], r[2], r[3], r[4], r[5], r[6])
        except MotionError as exc:
            assert exc.code == ErrorCode.PROFILE_FAILED
            assert not plans.ok[k], (k, r)
            continue
        assert plans.ok[k], (k, r)
        for field in ("start", "pos", "vel", "acc", "half"):
            assert bits(getattr(plans, field)[k]) == bits(getattr(one, field)), (k, field)
        assert bits(plans.end[k]) == bits(one.end), k
        assert bits(plans.done[k]) == bits(one.done), k


def test_a_position_plan_from_rest_is_the_textbook_trapezoid() -> None:
    """50 units at 100 units/s, 1,000 units/s² up and 2,000 down, from rest: 0.1 s up
    (5 units), 0.05 s down (2.5 units), 42.5 units at speed (0.425 s); and 1 unit at
    10^-6 units/s² both ways, a triangle of 2 sqrt(1 / 10^-6) = 2,000 s, while 100
    units would take 20,000 s, beyond the longest plan."""
    one = np.ones(3)
    plans = position_plans(
        0.001 * one,
        0.0 * one,
        0.0 * one,
        np.array([50.0, 1.0, 100.0]),
        np.array([100.0, 1000.0, 1000.0]),
        np.array([1000.0, 1e-6, 1e-6]),
        np.array([2000.0, 1e-6, 1e-6]),
    )
    assert plans.ok.tolist() == [True, True, False]
    assert plans.start[0].tolist() == pytest.approx([0.0, 0.0, 0.1, 0.525])
    assert plans.end[0] == pytest.approx(0.575)
    assert plans.end[1] == pytest.approx(2000.0)
    assert MAX_DURATION < 2 * (100 / 1e-6) ** 0.5
