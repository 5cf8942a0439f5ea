"""Kernel pieces of gearing: the lock-on quintic, sync occurrences, catch-up ramps."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig, MotionError
from motion_server.kernel.gear_in_pos import Quintic, next_occurrence
from motion_server.kernel.gearing import (
    GearProcess,
    GearTerm,
    JerkRamp,
    MasterSource,
    RateRamp,
    VelocityHold,
    gearing_direction,
)

finite = st.floats(-100.0, 100.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(v0=finite, a0=finite, p1=finite, v1=finite, a1=finite)
def test_quintic_meets_its_boundary_conditions(
    v0: float, a0: float, p1: float, v1: float, a1: float
) -> None:
    q = Quintic(v0, a0, p1, v1, a1)
    tol = 1e-9 * (1.0 + abs(v0) + abs(a0) + abs(p1) + abs(v1) + abs(a1))
    assert q(0.0) == (0.0, v0, pytest.approx(a0, abs=tol))
    at1 = q(1.0)
    assert at1[0] == pytest.approx(p1, abs=tol)
    assert at1[1] == pytest.approx(v1, abs=tol)
    assert at1[2] == pytest.approx(a1, abs=tol)
    # the analytic peak of |q''| matches a dense sampling of the cubic q''
    dense = max(abs(q(u)[2]) for u in np.linspace(0.0, 1.0, 2001))
    assert q.peak_curvature() == pytest.approx(dense, rel=1e-4, abs=tol)


@pytest.mark.parametrize(
    ("position", "reference", "direction", "expected"),
    [
        (0.0, 90.0, 1, 360.0),  # the seed's rotary example: next 0 beyond 0 + 90
        (90.0, 45.0, 1, 90.0),
        (90.0, 90.0, 1, 450.0),  # strictly beyond: at the reference is not beyond
        (0.0, 720.0, 1, 1080.0),
        (350.0, -20.0, 1, -10.0),
        (0.0, -90.0, -1, -360.0),
        (300.0, 10.0, -1, -60.0),
        (10.0, 10.0, -1, -350.0),
    ],
)
def test_next_occurrence_of_a_sync_position(
    position: float, reference: float, direction: int, expected: float
) -> None:
    assert next_occurrence(position, reference, direction, 360.0) == expected


def test_rate_ramp_is_trapezoidal() -> None:
    """0 -> 50 units/s at 1000 units/s^2 with 2 ms cycles: 25 cycles, 1.25 units."""
    r = RateRamp(1000.0)
    r.start(0.0, 0.0)
    steps = 0
    while not r.step(50.0, 0.0, 0.002):
        steps += 1
        assert r.velocity == pytest.approx(2.0 * steps)
        assert r.acceleration == pytest.approx(1000.0)
    assert steps + 1 == 25 and r.velocity == 50.0
    assert r.position == pytest.approx(50.0**2 / (2 * 1000.0))


def test_rate_ramp_uses_deceleration_to_slow_down_and_reverse() -> None:
    r = RateRamp(1000.0, 250.0)
    r.start(10.0, 0.0)
    r.step(-10.0, 0.0, 0.002)
    assert r.acceleration == pytest.approx(-250.0)
    r = RateRamp(1000.0, 250.0)
    r.start(10.0, 0.0)
    r.step(30.0, 0.0, 0.002)
    assert r.acceleration == pytest.approx(1000.0)


def test_jerk_ramp_follows_an_accelerating_target_and_locks() -> None:
    """A target that keeps accelerating at 200 units/s^2: the ramp (accel 1000, jerk
    20000) catches it while it moves, with a bounded acceleration step at the lock."""
    dt = 0.002
    r = JerkRamp(dt, 1000.0, 1000.0, 20_000.0)
    r.start(0.0, 0.0)
    acc = [0.0]
    for k in range(1, 1000):
        target = 20.0 + 200.0 * k * dt
        if r.step(target, 200.0, dt):
            break
        acc.append(r.acceleration)
    else:
        raise AssertionError("never caught up")
    acc.append(r.acceleration)
    assert r.velocity == target and r.acceleration == 200.0
    assert max(abs(a) for a in acc) <= 1000.0 + 1e-9
    assert np.max(np.abs(np.diff(acc))) <= 20_000.0 * dt * (1 + 1e-9)


def test_ramps_refuse_bad_limits() -> None:
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(MotionError):
            RateRamp(bad)
    with pytest.raises(MotionError):
        JerkRamp(0.002, 1000.0, 1000.0, -1.0)


def two_axes() -> Controller:
    ctl = Controller(
        [AxisConfig(1, "M", AxisType.VIRTUAL), AxisConfig(2, "S", AxisType.VIRTUAL)],
        [GroupConfig(1, "G", (1, 2), 0.002)],
    )
    for n in (1, 2):
        ctl.servo_on(ctl.axis(n))
    return ctl


def test_gear_terms_are_validated() -> None:
    for n, d in ((0, 1), (1, 0), (math.nan, 1), (1, math.inf)):
        with pytest.raises(MotionError):
            GearTerm(1, MasterSource.COMMAND, n, d).validated()
    with pytest.raises(MotionError):
        GearTerm(1, MasterSource.COMMAND, 1.5, 3, counts=True).validated()


def test_the_controller_composes_the_master_before_its_slave() -> None:
    """Gear axis 1 to axis 2 (the slave listed first): with the command reference the
    slave still reads its master's command of the same cycle."""
    ctl = Controller(
        [AxisConfig(1, "S", AxisType.VIRTUAL), AxisConfig(2, "M", AxisType.VIRTUAL)],
        [GroupConfig(1, "G", (1, 2), 0.002)],
    )
    for n in (1, 2):
        ctl.servo_on(ctl.axis(n))
    s, m = ctl.axis(1), ctl.axis(2)
    ctl.start(s, lambda v, a: GearProcess(ctl, s, (GearTerm(2, MasterSource.COMMAND, 3, 1),)))
    ctl.start(m, lambda v, a: VelocityHold(10.0))
    for k in range(1, 6):
        ctl.step()
        assert m.command_position_unwound == pytest.approx(10.0 * k * 0.002)
        assert s.command_position_unwound == pytest.approx(3 * m.command_position_unwound)
    assert s.command_velocity == pytest.approx(30.0)


def test_velocity_hold_is_velocity_times_time() -> None:
    ctl = two_axes()
    ax = ctl.axis(2)
    hold = ctl.start(ax, lambda v, a: VelocityHold(0.1))
    ctl.run(1000)
    assert hold.position == 0.1 * (1000 * 0.002)
    assert hold.reached and hold.active


def test_gearing_direction_is_remembered_per_slave() -> None:
    ctl = two_axes()
    s = ctl.axis(2)
    assert gearing_direction(s) == 1
    ctl.start(
        s,
        lambda v, a: GearProcess(
            ctl, s, (GearTerm(1, MasterSource.COMMAND, -1),), None, direction=-1
        ),
    )
    assert gearing_direction(s) == -1
    assert gearing_direction(ctl.axis(1)) == 1
