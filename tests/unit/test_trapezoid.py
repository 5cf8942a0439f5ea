"""The closed-form trapezoidal profiles (jerk 0) are the profiles ruckig plans for the same
second-order limits: same duration, same samples up to rounding, for any start velocity
(including beyond the limit, or away from the target) and asymmetric limits."""

from __future__ import annotations

import math

import pytest
import ruckig
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import ErrorCode, Limits, MotionError
from motion_server.kernel.trapezoid import (
    MAX_DURATION,
    TrapezoidProfile,
    plan_position,
    plan_velocity,
)

DT = 0.002


def ruckig_trajectory(
    v0: float, limits: Limits, target_position: float | None, target_velocity: float
) -> ruckig.Trajectory:
    """ruckig's offline plan from (0, v0) with the limits mapped as the kernel maps them."""
    inp = ruckig.InputParameter(1)
    inp.current_position = [0.0]
    inp.current_velocity = [v0]
    inp.current_acceleration = [0.0]
    if target_position is None:
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.target_velocity = [target_velocity]
        direction = target_velocity if target_velocity != 0.0 else v0
    else:
        inp.target_position = [target_position]
        inp.target_velocity = [0.0]
        direction = target_position
    inp.target_acceleration = [0.0]
    inp.max_velocity = [limits.velocity]
    if direction >= 0.0:
        inp.max_acceleration = [limits.acceleration]
        inp.min_acceleration = [-limits.deceleration]
    else:
        inp.max_acceleration = [limits.deceleration]
        inp.min_acceleration = [-limits.acceleration]
    inp.max_jerk = [math.inf]
    traj = ruckig.Trajectory(1)
    assert ruckig.Ruckig(1).calculate(inp, traj) in (ruckig.Result.Working, ruckig.Result.Finished)
    return traj


def close(a: float, b: float, scale: float) -> bool:
    return abs(a - b) <= 1e-9 * max(1.0, scale)


#: ruckig's documented precision: the final position and velocity within 1e-8, absolute
#: ("Numerical Stability", docs.ruckig.com/background.html)
RUCKIG_FINAL = 1e-8


def same_end(plan_end: float, traj: ruckig.Trajectory, target: float) -> bool:
    """The plan ends when ruckig's trajectory does; or, where ruckig's duration is off by
    more than rounding, ruckig's own state at the plan's end is the target (at rest)
    within ruckig's documented precision."""
    if close(plan_end, traj.duration, traj.duration):
        return True
    p, v, _ = (x[0] for x in traj.at_time(plan_end))
    return abs(p - target) <= RUCKIG_FINAL * max(1.0, abs(target)) and abs(v) <= RUCKIG_FINAL


speeds = st.floats(-400.0, 400.0, allow_nan=False)
rates = st.floats(50.0, 20_000.0)


@settings(max_examples=300, deadline=None)
@given(
    v0=speeds,
    target=st.floats(-200.0, 200.0),
    vmax=st.floats(5.0, 300.0),
    acc=rates,
    dec=rates,
)
def test_a_move_follows_ruckigs_second_order_profile(
    v0: float, target: float, vmax: float, acc: float, dec: float
) -> None:
    limits = Limits(vmax, acc, dec)
    plan = plan_position(DT, 0.0, v0, target, vmax, acc, dec)
    traj = ruckig_trajectory(v0, limits, target, 0.0)
    assert same_end(plan.end, traj, target), (plan.end, traj.duration)
    scale = abs(target) + abs(v0) * plan.end + 1.0
    for k in range(int(plan.done / DT) + 1):
        t = k * DT
        if t >= plan.done:
            break
        p, v, _ = plan.sample(t)
        rp, rv, _ = (x[0] for x in traj.at_time(t))
        assert close(p, rp, scale), (k, p, rp)
        assert close(v, rv, abs(v0) + vmax), (k, v, rv)


def test_a_move_from_beyond_the_limit_with_no_cruise_takes_its_exact_time() -> None:
    """From 100 to 5 units/s at 100 units/s^2 takes 0.95 s over (100 + 5) / 2 x 0.95 =
    49.875 units; from 5 to rest takes 0.05 s over 0.125 units: a move of exactly 50 has
    no cruise and ends at 1.0 s (ruckig plans 1.000000016 s here, within its documented
    1e-8 of the target)."""
    plan = plan_position(DT, 0.0, 100.0, 50.0, 5.0, 50.0, 100.0)
    assert plan.end == pytest.approx(1.0, abs=1e-12)
    p, v, _ = plan.sample(plan.end)
    assert p == pytest.approx(50.0, abs=1e-12) and abs(v) <= 1e-12
    traj = ruckig_trajectory(100.0, Limits(5.0, 50.0, 100.0), 50.0, 0.0)
    assert same_end(plan.end, traj, 50.0)


@settings(max_examples=300, deadline=None)
@given(v0=speeds, target=speeds, acc=rates, dec=rates)
def test_a_velocity_ramp_follows_ruckigs_second_order_profile(
    v0: float, target: float, acc: float, dec: float
) -> None:
    limits = Limits(1.0, acc, dec)
    plan = plan_velocity(DT, 0.0, v0, target, acc, dec)
    traj = ruckig_trajectory(v0, limits, None, target)
    assert close(plan.end, traj.duration, traj.duration)
    t = 0.5 * plan.end
    p, v, _ = plan.sample(t)
    rp, rv, _ = (x[0] for x in traj.at_time(t))
    assert close(p, rp, abs(v0) + abs(target)) and close(v, rv, abs(v0) + abs(target))


def test_a_ramp_of_whole_periods_ends_on_its_last_period() -> None:
    """0 -> 100 units/s at 5000 units/s^2 takes 0.02 s: exactly 10 periods of 2 ms, the
    10th sample is at speed and the position is the triangle's area, 1 unit."""
    prof = TrapezoidProfile(DT)
    prof.to_velocity(100.0, Limits(100.0, 5000.0, 5000.0))
    for _ in range(9):
        prof.step()
    assert not prof.finished and prof.velocity == pytest.approx(90.0)
    prof.step()
    assert prof.finished and prof.velocity == 100.0
    assert prof.position == pytest.approx(0.5 * 100.0 * 0.02)


def test_a_move_lands_exactly_and_at_rest() -> None:
    prof = TrapezoidProfile(DT)
    prof.to_position(10.0, Limits(50.0, 500.0, 500.0))
    # 0.1 s up to 50, 0.1 s cruise (5 units), 0.1 s down: 0.3 s, 150 periods
    for k in range(150):
        assert not prof.finished, k
        prof.step()
    assert prof.finished and (prof.position, prof.velocity) == (10.0, 0.0)


def test_a_profile_longer_than_ruckigs_limit_is_refused_and_the_old_plan_stays() -> None:
    prof = TrapezoidProfile(DT, velocity=4.0)
    prof.to_velocity(0.0, Limits(8.0, 1.0, 1.0))
    old = prof.plan
    with pytest.raises(MotionError) as err:
        prof.to_velocity(0.0, Limits(8.0, 1.6e-157, 1.6e-157))
    assert err.value.code == ErrorCode.PROFILE_FAILED
    assert prof.plan is old
    with pytest.raises(MotionError):
        prof.to_position(4.0 * (MAX_DURATION + 1.0), Limits(4.0, 1e3, 1e3))
    assert prof.plan is old
