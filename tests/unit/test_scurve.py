"""The closed-form jerk-limited velocity profiles (:mod:`motion_server.kernel.scurve`).

Two kinds of checks:

- kinematics from first principles: from rest to v at acceleration a and jerk j the ramp
  lasts v/a + a/j when v >= a²/j (three phases), 2·sqrt(v/j) otherwise (two phases, the
  peak acceleration sqrt(v·j)); an acceleration beyond its limit is first brought back at
  full jerk; the acceleration limit of a ramp is the one of the direction of the velocity
  change, as ruckig's velocity interface bounds max_acceleration / min_acceleration;
- ruckig (the online profile the kernel used before, :class:`~motion_server.kernel.profiles.
  Profile`) as the reference, for random start states, targets and limits: the same
  position, velocity and acceleration at every cycle within ruckig's documented precision,
  and the same end within one cycle.
"""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    Limits,
    MotionError,
    scurve,
)
from motion_server.kernel.profiles import Profile, SCurveProfile, profile_for
from motion_server.kernel.scurve import FALLBACKS, plan_jerk_velocity

DT = 0.001

#: ruckig's documented precision ("Tests and Numerical Stability" in its README): final
#: position and velocity within 1e-8, final acceleration within 1e-10, absolute values
#: meant for inputs scaled to the system (we scale them by the magnitude compared)
P_PRECISION = 1e-8
V_PRECISION = 1e-8
A_PRECISION = 1e-10
#: ruckig's brake ends this late (``BrakeProfile::eps``): a time shift of the samples
BRAKE_EPS = 2.2e-14


def time_slack(k: int, dt: float) -> float:
    """How far ruckig's clock can be from k·dt after k cycles: it is a running sum of dt,
    each addition rounded by up to an ulp of the sum; plus the brake's shift."""
    return k * math.ulp(k * dt) + BRAKE_EPS


def run(prof: SCurveProfile | Profile, cycles: int) -> list[tuple[float, float, float, bool]]:
    out = []
    for _ in range(cycles):
        prof.step()
        out.append((prof.position, prof.velocity, prof.acceleration, prof.finished))
    return out


def end_cycle(trace: list[tuple[float, float, float, bool]]) -> int:
    """The 1-based cycle whose sample ended the profile."""
    return next(k + 1 for k, s in enumerate(trace) if s[3])


# -- kinematics from first principles ---------------------------------------------------
@pytest.mark.parametrize(
    ("v", "a", "j"),
    [(100.0, 1000.0, 20_000.0), (50.0, 500.0, 10_000.0), (250.0, 2000.0, 1e6)],
)
def test_from_rest_with_the_acceleration_limit_reached(v: float, a: float, j: float) -> None:
    """v >= a²/j: jerk up for a/j, hold a for v/a - a/j, jerk down for a/j."""
    assert v >= a * a / j
    plan = plan_jerk_velocity(DT, 0.0, 0.0, 0.0, v, a, -a, j)
    assert plan is not None
    assert plan.end == pytest.approx(v / a + a / j, rel=1e-12)
    assert plan.acc[2] == pytest.approx(a, rel=1e-12)  # the hold
    assert plan.jerk[1:] == (j, 0.0, -j)
    # the position at the end: the mean velocity is v/2 over the symmetric ramp
    assert plan.end_position == pytest.approx(v * plan.end / 2, rel=1e-12)
    prof = SCurveProfile(DT)
    prof.to_velocity(v, Limits(v, a, a, j))
    trace = run(prof, 2000)
    assert end_cycle(trace) == math.ceil((v / a + a / j) / DT - 1e-9)
    assert trace[-1][1:3] == (v, 0.0)


@pytest.mark.parametrize(("v", "a", "j"), [(10.0, 1000.0, 20_000.0), (1.0, 500.0, 1e4)])
def test_from_rest_without_reaching_the_acceleration_limit(v: float, a: float, j: float) -> None:
    """v < a²/j: two jerk phases of sqrt(v/j) each, the peak acceleration sqrt(v·j)."""
    assert v < a * a / j
    plan = plan_jerk_velocity(DT, 0.0, 0.0, 0.0, v, a, -a, j)
    assert plan is not None
    assert plan.end == pytest.approx(2.0 * math.sqrt(v / j), rel=1e-12)
    assert plan.acc[3] == pytest.approx(math.sqrt(v * j), rel=1e-12)  # the peak
    prof = SCurveProfile(DT)
    prof.to_velocity(v, Limits(v, a, a, j))
    trace = run(prof, 200)
    peak = max(abs(s[2]) for s in trace)
    assert peak <= math.sqrt(v * j) * (1 + 1e-12)
    assert end_cycle(trace) == math.ceil(2.0 * math.sqrt(v / j) / DT - 1e-9)


def test_the_jerk_never_exceeds_its_limit_and_the_samples_are_continuous() -> None:
    """Finite differences of the sampled acceleration stay within j (the acceleration is
    piecewise linear in time, so a difference over one cycle is at most j·dt)."""
    j = 20_000.0
    prof = SCurveProfile(DT, velocity=-40.0, acceleration=300.0)
    prof.to_velocity(120.0, Limits(1.0, 1000.0, 700.0, j))
    trace = run(prof, 400)
    accs = [300.0] + [s[2] for s in trace]
    for a0, a1 in itertools.pairwise(accs):
        assert abs(a1 - a0) <= j * DT * (1 + 1e-9)


def test_an_acceleration_beyond_its_limit_is_brought_back_at_full_jerk() -> None:
    """From a = 2·a_max the first segment lowers the acceleration at -j for a_max/j, then
    the ramp goes on at the limit."""
    a_max, j = 1000.0, 20_000.0
    plan = plan_jerk_velocity(DT, 0.0, 0.0, 2 * a_max, 500.0, a_max, -a_max, j)
    assert plan is not None
    assert plan.jerk[0] == -j
    assert plan.start[1] == pytest.approx(a_max / j, rel=1e-12)
    assert plan.acc[1] == a_max
    for s in range(1, 4):
        assert -a_max <= plan.acc[s] <= a_max


def test_asymmetric_limits_follow_the_direction_of_the_velocity_change() -> None:
    """ruckig's velocity interface bounds the acceleration by max_acceleration and
    min_acceleration, which the kernel maps on the direction of the target (of the current
    velocity toward rest). A jog to -v speeds up at the acceleration A (a_min = -A); a
    stop from +v slows down at the deceleration D (a_min = -D)."""
    v, acc, dec, j = 200.0, 1000.0, 400.0, 1e6
    jog = SCurveProfile(DT)
    jog.to_velocity(-v, Limits(v, acc, dec, j))
    assert jog.plan is not None and jog.plan.end == pytest.approx(v / acc + acc / j, rel=1e-12)
    assert min(jog.plan.acc) == pytest.approx(-acc, rel=1e-12)
    stop = SCurveProfile(DT, velocity=v)
    stop.to_velocity(0.0, Limits(v, acc, dec, j))
    assert stop.plan is not None and stop.plan.end == pytest.approx(v / dec + dec / j, rel=1e-12)
    assert min(stop.plan.acc) == pytest.approx(-dec, rel=1e-12)


def test_a_jerk_no_plan_can_hold_is_refused_and_the_plan_stays() -> None:
    prof = SCurveProfile(DT)
    prof.to_velocity(100.0, Limits(100.0, 1000.0, 1000.0, 20_000.0))
    plan = prof.plan
    run(prof, 3)
    with pytest.raises(MotionError) as err:
        prof.to_velocity(50.0, Limits(100.0, 1000.0, 1000.0, 1e-300))
    assert err.value.code == ErrorCode.PROFILE_FAILED
    assert prof.plan is plan and prof.cycles == 3


def test_jerk_limits_give_the_closed_form() -> None:
    assert isinstance(profile_for(Limits(1.0, 1.0, 1.0, 5.0), DT), SCurveProfile)


def test_a_position_target_is_ruckigs_own_profile() -> None:
    """to_position from beyond the velocity limit is planned by ruckig (the states the
    closed form plans: ``test_scurve_position.py``) and sampled from its plan: every
    cycle within ruckig's precision of a bare Profile's samples, both landing on the
    target within a cycle of each other, ours exactly."""
    limits = Limits(100.0, 1000.0, 800.0, 20_000.0)
    ours, ref = SCurveProfile(DT, 130.0, 100.0, 2.0), Profile(DT, 130.0, 100.0, 2.0)
    ours.to_position(50.0, limits)
    ref.to_position(50.0, limits)
    assert ours.plan is not None and ours.ruckig is None
    step_beside_ruckig(ours, ref, 800, DT, (130.0, 1000.0, 20_000.0))
    assert (ours.position, ours.velocity, ours.acceleration) == (50.0, 0.0, 0.0)
    # and back to a velocity target from where the move is: the closed form again
    ours.to_velocity(-10.0, limits)
    assert ours.plan is not None and ours.ruckig is None


def test_a_case_the_closed_form_leaves_is_planned_by_ruckig_and_counted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When no closed-form candidate is accepted ruckig plans the velocity target, the
    fallback is counted, and the plan is sampled within ruckig's precision of its own
    samples, holding the target velocity at the end."""
    monkeypatch.setattr(scurve, "_phases", lambda *args: None)
    limits = Limits(100.0, 1000.0, 1000.0, 20_000.0)
    ctl = Controller(
        [AxisConfig(1, "A1", AxisType.VIRTUAL)], [GroupConfig(1, "G", (1,), DT)], lanes=False
    )
    before = ctl.profile_fallbacks
    ours, ref = SCurveProfile(DT, 5.0), Profile(DT, 5.0)
    ours.to_velocity(80.0, limits)
    ref.to_velocity(80.0, limits)
    assert FALLBACKS.count == before + 1 == ctl.profile_fallbacks
    assert ours.plan is not None and ours.ruckig is None
    step_beside_ruckig(ours, ref, 200, DT, (80.0, 1000.0, 20_000.0))
    assert (ours.velocity, ours.acceleration, ours.finished) == (80.0, 0.0, True)


# -- ruckig as the reference ------------------------------------------------------------
velocities = st.floats(-500.0, 500.0, allow_nan=False)
rates = st.floats(100.0, 10_000.0)
jerks = st.floats(1_000.0, 1e6)


@settings(max_examples=300, deadline=None)
@given(
    v0=velocities,
    a_share=st.floats(-2.0, 2.0),
    target=velocities,
    acc=rates,
    dec=rates,
    jerk=jerks,
    dt=st.sampled_from([0.0005, 0.001, 0.002, 0.004]),
)
def test_the_closed_form_samples_what_ruckig_samples(
    v0: float, a_share: float, target: float, acc: float, dec: float, jerk: float, dt: float
) -> None:
    """Any start (velocity, acceleration: within its limit or up to twice beyond it), any
    target, asymmetric limits: every cycle's position, velocity and acceleration agree
    with ruckig's online profile within its precision (plus what a sample-time difference
    of :func:`time_slack` makes of the next derivative), and both end within one cycle."""
    a0 = a_share * min(acc, dec)
    limits = Limits(1.0, acc, dec, jerk)
    ours, ref = SCurveProfile(dt, v0, a0), Profile(dt, v0, a0)
    ours.to_velocity(target, limits)
    assert ours.ruckig is None  # the closed form covered it
    try:
        ref.to_velocity(target, limits)
    except MotionError:
        # ruckig refuses a few of these (its peak acceleration lands on the limit plus a
        # rounding beyond its absolute 1e-12): the closed form must still end on target
        trace = run(ours, math.ceil(ours.plan.end / dt) + 2 if ours.plan else 2)
        assert trace[-1][1:] == (target, 0.0, True)
        return
    horizon = ours.plan.end if ours.plan is not None else 0.0
    a_top = max(acc, dec, abs(a0))
    v_top = max(abs(v0), abs(target)) + a_top * a_top / jerk + a_top * horizon
    step_beside_ruckig(ours, ref, math.ceil(horizon / dt) + 3, dt, (v_top, a_top, jerk))
    assert ours.velocity == target and ours.acceleration == 0.0


def step_beside_ruckig(
    ours: SCurveProfile,
    ref: Profile,
    cycles: int,
    dt: float,
    tops: tuple[float, float, float],
    after_end: bool = True,
) -> None:
    """Step both ``cycles`` times: every cycle's position, velocity and acceleration
    within ruckig's precision (scaled by ``tops``, the largest velocity, acceleration
    and jerk, and widened by what a sample-time difference of :func:`time_slack` makes
    of them), also once either has ended if ``after_end``; both end within one cycle."""
    v_top, a_top, jerk = tops
    ends = []
    for k in range(1, cycles + 1):
        ours.step()
        ref.step()
        slack = time_slack(k, dt)
        p_tol = P_PRECISION * max(1.0, abs(ref.position)) + v_top * slack
        v_tol = V_PRECISION * max(1.0, v_top) + a_top * slack
        a_tol = A_PRECISION * max(1.0, a_top) + jerk * slack
        if after_end or not (ours.finished or ref.finished):
            assert abs(ours.position - ref.position) <= p_tol, k
            assert abs(ours.velocity - ref.velocity) <= v_tol, k
            assert abs(ours.acceleration - ref.acceleration) <= a_tol, k
        ends.append((ours.finished, ref.finished))
    ours_end = next(k for k, e in enumerate(ends) if e[0])
    ref_end = next(k for k, e in enumerate(ends) if e[1])
    assert abs(ours_end - ref_end) <= 1
