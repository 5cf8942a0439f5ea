"""Jerk-limited velocity plans built together (:func:`motion_server.kernel.scurve_plan.
jerk_plans`) are the plans :func:`motion_server.kernel.scurve.plan_jerk_velocity` builds one
by one, bit for bit (signed zeros included); a velocity target is judged when it is
commanded (:meth:`~motion_server.kernel.scurve.SCurveProfile.to_velocity`): what the plan
would refuse is refused then, with the same error, a case the closed form does not cover
goes to ruckig then, and the plan built later is the plan. With the fast lanes, the
S-curve ramps commanded in one scan are built together before the step and the motion
stays the reference's after every cycle, whatever reads the plans in between."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    JogProcess,
    Limits,
    MotionError,
    ProcessKind,
    jerk_phases,
    scurve,
)
from motion_server.kernel.lanes.ramps import CruiseLane
from motion_server.kernel.lanes.scurve import SCurveLane
from motion_server.kernel.scurve import (
    MAX_DURATION,
    SCurveProfile,
    jerk_segments,
    judge_request,
    limit_pair,
    plan_jerk_velocity,
)
from motion_server.kernel.scurve_plan import jerk_plan_row, jerk_plans
from motion_server.scan import statecodec

FIELDS = ("start", "pos", "vel", "acc", "half", "jerk", "jhalf", "jsixth")

velocities = st.one_of(
    st.sampled_from([0.0, -0.0, 1.0, -1.0, 100.0, -250.0]),
    st.floats(-1e4, 1e4, allow_nan=False),
)
accelerations = st.one_of(
    st.sampled_from([0.0, -0.0, 500.0, -500.0, 5000.0, -5000.0]),
    st.floats(-1e5, 1e5, allow_nan=False),
)
rates = st.one_of(st.sampled_from([1.0, 1000.0, 5000.0]), st.floats(1e-2, 1e6))
jerks = st.one_of(st.sampled_from([1.0, 20_000.0, 1e5]), st.floats(1e-1, 1e8))
dts = st.sampled_from([0.0005, 0.001, 0.002, 0.004, 0.032])
positions = st.one_of(st.sampled_from([0.0, -0.0]), st.floats(-1e3, 1e3))

#: (dt, p0, v0, a0, target, acceleration, deceleration, jerk)
Case = tuple[float, float, float, float, float, float, float, float]
cases = st.tuples(dts, positions, velocities, accelerations, velocities, rates, rates, jerks)


def bits(x: object) -> bytes:
    return np.asarray(x, dtype=float).tobytes()


def scalar(case: Case) -> tuple[tuple[float, ...] | None, object]:
    """(the request the profile keeps, or None; the plan built one by one, None when the
    closed form does not cover the case, or the MotionError it raises)."""
    dt, p0, v0, a0, target, acc, dec, jerk = case
    a_max, a_min = limit_pair(target if target != 0.0 else v0, acc, dec)
    try:
        plan = plan_jerk_velocity(dt, p0, v0, a0, target, a_max, a_min, jerk)
    except MotionError as e:
        return None, e
    segs = jerk_segments(v0, a0, target, a_max, a_min, jerk)
    return (None if segs is None else (p0, v0, a0, target, *segs)), plan


@settings(max_examples=300, deadline=None)
@given(st.lists(cases, min_size=1, max_size=20))
def test_plans_built_together_are_the_plans_built_one_by_one(batch: list[Case]) -> None:
    built = []
    for case in batch:
        request, plan = scalar(case)
        if request is not None:  # (refused or left to ruckig: never built with the others)
            assert judge_request(request)  # these inputs are small enough to defer
            built.append((case[0], request, plan))
    if not built:
        return
    plans = jerk_plans(
        np.array([dt for dt, _, _ in built]), np.array([r for _, r, _ in built], dtype=float)
    )
    for k, (_, _, one) in enumerate(built):
        for field in FIELDS:
            assert bits(getattr(plans, field)[k]) == bits(getattr(one, field)), (k, field)
        assert bits(plans.done[k]) == bits(one.done), k  # type: ignore[attr-defined]
        assert bits(plans.end[k]) == bits(one.end), k  # type: ignore[attr-defined]
        assert bits(plans.end_pos[k]) == bits(one.end_position), k  # type: ignore[attr-defined]


@settings(max_examples=300, deadline=None)
@given(
    st.tuples(
        dts,
        positions | st.sampled_from([1e250, -1e300]),
        velocities | st.sampled_from([1e200, -1e250, 1e300]),
        accelerations | st.sampled_from([1e201, -1e250]),
        velocities | st.sampled_from([1e200, 1e300, -1e308]),
        rates | st.sampled_from([1e-9, 1e250]),
        rates | st.sampled_from([1e-9, 1e250]),
        jerks | st.sampled_from([1e-9, 1e250, 1e300]),
    )
)
def test_a_velocity_target_is_judged_when_commanded_and_planned_as_one_by_one(
    case: Case,
) -> None:
    """Whatever the inputs (many beyond what a plan can hold): the profile refuses what
    the plan would refuse, with the same error, and nothing changes; it goes to ruckig
    where the closed form does not cover the case; otherwise the plan it builds when the
    plan is first read is the plan built at once."""
    dt, p0, v0, a0, target, acc, dec, jerk = case
    _, one = scalar(case)
    prof = SCurveProfile(dt, v0, a0, p0)
    limits = Limits(1.0, acc, dec, jerk)
    if isinstance(one, MotionError):
        with pytest.raises(MotionError) as judged:
            prof.to_velocity(target, limits)
        assert (judged.value.code, str(judged.value)) == (one.code, str(one))
        assert not prof.planned and prof.ruckig is None  # nothing changed
        return
    with contextlib.suppress(MotionError):  # ruckig may refuse what it is left
        prof.to_velocity(target, limits)
        if one is None:
            assert prof.ruckig is not None and not prof.planned
            return
        assert prof.planned and prof.ruckig is None
        assert prof.plan == one and prof.request is None
        return
    assert one is None


def test_a_plan_too_long_is_refused_when_commanded() -> None:
    """100 mm/s at 1e-3 mm/s² lasts 1e5 s, beyond ruckig's longest trajectory
    (MAX_DURATION): refused by the command, with the message the plan would give."""
    with pytest.raises(MotionError) as planned:
        plan_jerk_velocity(0.001, 0.0, 0.0, 0.0, 100.0, 1e-3, -1e-3, 1.0)
    prof = SCurveProfile(0.001)
    with pytest.raises(MotionError) as judged:
        prof.to_velocity(100.0, Limits(100.0, 1e-3, 1e-3, 1.0))
    assert str(judged.value) == str(planned.value)
    assert f"more than {MAX_DURATION:g} s" in str(judged.value)
    assert prof.request is None and prof.plan is None


def test_a_target_kept_as_a_request_is_built_when_read() -> None:
    """From rest to 100 mm/s at 1000 mm/s² and 20,000 mm/s³: judged, not built; read,
    the plan is the one built at once: v/a + a/j = 0.15 s long."""
    prof = SCurveProfile(0.001)
    prof.to_velocity(100.0, Limits(100.0, 1000.0, 1000.0, 20_000.0))
    assert prof.request is not None and prof.planned
    plan = prof.plan
    assert plan == plan_jerk_velocity(0.001, 0.0, 0.0, 0.0, 100.0, 1000.0, -1000.0, 20_000.0)
    assert plan is not None and plan.end == pytest.approx(0.15, rel=1e-12)
    assert prof.request is None and prof.plan is plan


# -- in the lanes -------------------------------------------------------------------------

N_AXES = 8
DT = 0.002


def pair() -> tuple[Controller, Controller]:
    """Eight virtual axes in one group, lanes on and off."""
    out = []
    for lanes in (True, False):
        cfg = [
            AxisConfig(n, f"V{n}", AxisType.VIRTUAL, max_acceleration=1e4, max_deceleration=1e4)
            for n in range(1, N_AXES + 1)
        ]
        ctl = Controller(cfg, [GroupConfig(1, "G", tuple(range(1, N_AXES + 1)), DT)], lanes=lanes)
        for ax in ctl.axes:
            ctl.servo_on(ax)
        out.append(ctl)
    return out[0], out[1]


#: (axis 0-based, "jog" or "stop", target velocity or deceleration, accel, decel, jerk)
Op = tuple[int, str, float, float, float, float]
lane_rates = st.sampled_from([100.0, 1000.0, 5000.0])
lane_jerks = st.sampled_from([2_000.0, 20_000.0, 1e5]) | st.floats(500.0, 1e6)
ops = st.tuples(
    st.integers(0, N_AXES - 1),
    st.sampled_from(["jog", "jog", "jog", "stop"]),
    st.sampled_from([0.0, -0.0, 20.0, -50.0, 100.0]) | st.floats(-200.0, 200.0),
    lane_rates,
    lane_rates,
    lane_jerks,
)


def command(ctl: Controller, op: Op) -> str:
    """Apply ``op``; what it raised (by name), if anything."""
    k, kind, value, acc, dec, jerk = op
    ax = ctl.axes[k]
    try:
        if kind == "stop":
            ctl.stop(ax, None, acc, jerk)
        else:
            limits = Limits(abs(value) or 1.0, acc, dec, jerk)
            ctl.start(
                ax,
                lambda v, a: JogProcess(DT, value, limits, v, a),
                replace=(ProcessKind.JOG,),
            )
    except MotionError as e:
        return e.code.name
    return ""


def assert_same(fast: Controller, ref: Controller, where: str) -> None:
    for name in ("cmd_pos", "cmd_vel", "cmd_acc"):
        assert bits(getattr(fast, name)) == bits(getattr(ref, name)), (name, where)


def read_plans(ctl: Controller, axes: list[int]) -> None:
    """Read the plans of the axes' processes: built then, if only requested."""
    for k in axes:
        for p in ctl.axes[k].processes:
            prof = getattr(p, "profile", None)
            if isinstance(prof, SCurveProfile):
                _ = prof.plan


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.lists(ops, min_size=1, max_size=12),
            st.integers(1, 60),
            # (cycle 0 often: a plan read before the lane takes the ramps joins built)
            st.lists(
                st.tuples(st.just(0) | st.integers(0, 59), st.integers(0, N_AXES - 1)),
                max_size=4,
            ),
        ),
        min_size=1,
        max_size=5,
    )
)
def test_s_curves_commanded_together_give_the_reference_motion(
    rounds: list[tuple[list[Op], int, list[tuple[int, int]]]],
) -> None:
    """Rounds of jerk-limited jogs (from rest and from motion, reversals, to rest) and
    jerk-limited stops, many in the same scan, each round followed by some cycles; the
    plans of some axes read at random cycles in the fast controller (built one by one
    then, while the lane holds them as arrays)."""
    fast, ref = pair()
    for r, (batch, cycles, reads) in enumerate(rounds):
        for op in batch:
            assert command(fast, op) == command(ref, op), (r, op)
        for c in range(cycles):
            read_plans(fast, [k for at, k in reads if at == c])
            fast.step()
            ref.step()
            assert_same(fast, ref, f"round {r} cycle {c}")


def test_plans_read_before_the_lane_takes_them_join_beside_the_requests() -> None:
    """Jerk-limited jogs commanded in one scan, the plans of every other axis read
    (built one by one) before the step: the lane loads those as they are and builds the
    others, each in its own row, and samples what the reference samples."""
    fast, ref = pair()
    for ctl in (fast, ref):
        for ax in ctl.axes:
            v = 25.0 * ax.number - 110.0
            limits = Limits(abs(v), 1500.0, 700.0, 30_000.0)
            ctl.start(ax, lambda v0, a0, v=v, limits=limits: JogProcess(DT, v, limits, v0, a0))
    read_plans(fast, list(range(0, N_AXES, 2)))
    profiles = [ax.processes[0].profile for ax in fast.axes]  # type: ignore[attr-defined]
    assert [p.request is None for p in profiles] == [k % 2 == 0 for k in range(N_AXES)]
    for c in range(100):
        fast.step()
        ref.step()
        assert_same(fast, ref, f"cycle {c}")


def test_jogs_commanded_together_are_built_together_and_run_in_the_lane() -> None:
    """Eight jerk-limited jogs in one scan: each judged at its command and not built; the
    S-curve lane builds them together before the step and samples what the reference's
    plans sample; 100 mm/s at 1000 mm/s² and 20,000 mm/s³ takes 0.15 s, 75 cycles of
    2 ms: at speed after them."""
    fast, ref = pair()
    limits = Limits(100.0, 1000.0, 1000.0, 20_000.0)
    for ctl in (fast, ref):
        for ax in ctl.axes:
            ctl.start(ax, lambda v, a: JogProcess(DT, 100.0, limits, v, a))
    jogs = [ax.processes[0] for ax in fast.axes]
    for p in jogs:
        assert isinstance(p, JogProcess) and isinstance(p.profile, SCurveProfile)
        assert p.profile.request is not None  # judged, not built: built with the others
    fast.step()
    ref.step()
    assert_same(fast, ref, "first step")
    for p in jogs:
        assert isinstance(p, JogProcess) and isinstance(p.lane, SCurveLane)
        assert p.profile.request is not None  # built as arrays only
    for c in range(80):
        fast.step()
        ref.step()
        assert_same(fast, ref, f"cycle {c}")
    assert np.array_equal(fast.cmd_vel[:N_AXES], np.full(N_AXES, 100.0))
    for p in jogs:
        # ended by the S-curve lane, which handed them to the cruise lane; the plans
        # were never needed one by one
        assert isinstance(p, JogProcess) and p.at_speed and p.profile.finished
        assert isinstance(p.lane, CruiseLane)
        assert p.profile.request is not None


@pytest.mark.parametrize("saved_before_ends", [False, True])
def test_a_snapshot_in_the_middle_of_the_ramps_runs_on_bit_for_bit(
    saved_before_ends: bool,
) -> None:
    """A copy of the controller through the snapshot codec, taken with the jogs' plans
    still requests and in the lane, runs on as the original does; so does one whose lane
    was saved before the lane kept the plans' ends (taken from the members' plans)."""
    fast, ref = pair()
    for ctl in (fast, ref):
        for ax in ctl.axes:
            v = 20.0 * ax.number - 90.0
            limits = Limits(abs(v), 1000.0, 2000.0, 20_000.0)
            ctl.start(ax, lambda v0, a0, v=v, limits=limits: JogProcess(DT, v, limits, v0, a0))
    for _ in range(5):
        fast.step()
        ref.step()
    lane = fast.motion.lanes[1].scurves
    assert len(lane.members) == N_AXES
    saved = {f: lane.arrays.pop(f) for f in ("end", "end_pos", "end_vel")}
    if not saved_before_ends:
        lane.arrays.update(saved)
    copy = statecodec.loads(statecodec.dumps(fast))
    lane.arrays.update(saved)
    for c in range(80):
        for ctl in (fast, ref, copy):
            ctl.step()
        assert_same(fast, ref, f"cycle {c}")
        assert_same(copy, ref, f"copy, cycle {c}")


@settings(max_examples=300, deadline=None)
@given(cases, cases, st.lists(st.booleans(), min_size=4, max_size=4))
def test_the_phases_kept_for_the_same_inputs_are_the_phases_computed_for_them(
    first: Case, second: Case, flips: list[bool]
) -> None:
    """The last phases are kept for inputs of the very same bits: after any other
    target, and after the same numbers with zeros of the other sign, the answer is the
    one computed afresh."""
    for case in (first, second):
        _, _, v0, a0, target, acc, dec, jerk = case
        args = (a0, v0, target, acc, -dec, jerk)
        # the same numbers, zeros of the other sign where drawn (-0.0 == 0.0)
        signs = [*flips, False, False]  # (the limits are never zero)
        other = tuple(-x if x == 0.0 and f else x for x, f in zip(args, signs, strict=True))
        for inputs in (args, other, args):
            got = scurve._phases(*inputs)
            assert bits(got or ()) == bits(jerk_phases.solve_phases(*inputs) or ()), inputs


@settings(max_examples=300, deadline=None)
@given(st.lists(cases, min_size=1, max_size=8))
def test_a_plan_built_alone_in_python_floats_is_the_arrays_row(batch: list[Case]) -> None:
    """``jerk_plan_row`` (the plan of a batch of jogs from rest to one target) gives,
    bit for bit, the row ``jerk_plans`` gives for the same request."""
    built = [(case[0], r) for case in batch if (r := scalar(case)[0]) is not None]
    if not built:
        return
    plans = jerk_plans(
        np.array([dt for dt, _ in built]), np.array([r for _, r in built], dtype=float)
    )
    for k, (dt, request) in enumerate(built):
        *row, (done, end, end_pos) = jerk_plan_row(dt, request)
        for field, values in zip(FIELDS, row, strict=True):
            assert bits(values) == bits(getattr(plans, field)[k]), (k, field)
        assert bits((done, end, end_pos)) == bits(
            (plans.done[k], plans.end[k], plans.end_pos[k])
        ), k
