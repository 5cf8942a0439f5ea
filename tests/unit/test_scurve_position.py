"""Jerk-limited moves to a position in closed form (:mod:`motion_server.kernel.scurve_position`).

- Kinematics from first principles, rest to rest: with the velocity and the
  acceleration limits both reached, a move of d lasts d/v + v/(2a) + v/(2b) + a/(2j) +
  b/(2j) (a the acceleration, b the deceleration: the two ramps and the cruise); with
  neither reached (symmetric limits) it lasts 4·(d/(2j))^(1/3), the peak velocity
  j·(d/(2j))^(2/3); with only the acceleration reached (symmetric) the peak vp solves
  vp²/a + vp·a/j = d and the move lasts 2·(vp/a + a/j).
- ruckig as the reference for random moves from the states the closed form covers (at
  rest or cruising toward the target within the velocity limit, far enough to stop):
  the same duration, the same samples at every cycle within ruckig's documented
  precision, the same end within one cycle, on the target exactly; from accelerating
  states (the peak found by a search), the same duration within 1e-9.
- The other states are planned by ruckig and counted; its plan is sampled within its
  precision, landing on the target exactly (:mod:`motion_server.kernel.ruckig_plan`).
- The S-curve lane steps the moves (eight segments) beside velocity ramps (four, padded)
  bit for bit as the reference path, and a lane saved with four columns runs on.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from ruckig import RuckigError

from motion_server.kernel import Limits, MotionError, MoveProcess, ProcessKind, scurve
from motion_server.kernel.lanes.scurve import PLAN_FIELDS, SCurveLane
from motion_server.kernel.profiles import Profile, SCurveProfile
from motion_server.kernel.scurve import FALLBACKS, JerkPlan, plan_jerk_position
from motion_server.kernel.scurve_position_plan import plans_from_rest
from motion_server.scan import statecodec

from .test_jog_batch import PERIOD, controller
from .test_scurve import P_PRECISION, run, step_beside_ruckig

DT = 0.001


def ruckig_duration(v0: float, d: float, limits: Limits, a0: float = 0.0) -> float:
    """The duration of ruckig's own plan of the move (one trajectory, not stepped)."""
    import ruckig

    otg, inp, traj = ruckig.Ruckig(1, DT), ruckig.InputParameter(1), ruckig.Trajectory(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [a0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [d], [0.0], [0.0]
    inp.max_velocity = [limits.velocity]
    if d >= 0.0:
        inp.max_acceleration, inp.min_acceleration = [limits.acceleration], [-limits.deceleration]
    else:
        inp.max_acceleration, inp.min_acceleration = [limits.deceleration], [-limits.acceleration]
    inp.max_jerk = [limits.jerk]
    otg.calculate(inp, traj)
    return float(traj.duration)


# -- kinematics from first principles ---------------------------------------------------
@pytest.mark.parametrize(
    ("d", "v", "a", "b", "j"),
    [
        (50.0, 100.0, 1000.0, 800.0, 20_000.0),
        (-50.0, 100.0, 1000.0, 800.0, 20_000.0),
        (400.0, 250.0, 2000.0, 2000.0, 1e6),
    ],
)
def test_a_long_move_reaches_both_limits(d: float, v: float, a: float, b: float, j: float) -> None:
    plan = plan_jerk_position(DT, 0.0, 0.0, 0.0, d, Limits(v, a, b, j))
    assert plan is not None
    expected = abs(d) / v + v / (2 * a) + v / (2 * b) + a / (2 * j) + b / (2 * j)
    assert plan.end == pytest.approx(expected, rel=1e-12)
    assert plan.end_position == d
    # the cruise (segment 4) at the velocity limit, the holds at the acceleration limits
    sign = math.copysign(1.0, d)
    assert plan.vel[4] == pytest.approx(sign * v, rel=1e-12)
    assert plan.acc[2] == pytest.approx(sign * a, rel=1e-12)
    assert plan.acc[6] == pytest.approx(-sign * b, rel=1e-12)


@pytest.mark.parametrize(("d", "j"), [(0.5, 20_000.0), (2.0, 5_000.0), (-0.01, 1e5)])
def test_a_short_move_reaches_neither_limit(d: float, j: float) -> None:
    limits = Limits(100.0, 1000.0, 1000.0, j)
    plan = plan_jerk_position(DT, 0.0, 0.0, 0.0, d, limits)
    assert plan is not None
    cube = (abs(d) / (2 * j)) ** (1 / 3)
    assert plan.end == pytest.approx(4 * cube, rel=1e-12)
    assert abs(plan.vel[4]) == pytest.approx(j * cube * cube, rel=1e-12)  # the peak
    assert plan.start[2] == plan.start[3] and plan.start[6] == plan.start[7]  # no hold
    assert plan.start[4] == plan.start[5]  # no cruise


def test_a_medium_move_reaches_the_acceleration_limit_only() -> None:
    """a²/j = 20 mm/s <= vp = 60 mm/s < v: d = 60²/1000 + 60·1000/50,000 = 4.8 mm,
    in 2·(60/1000 + 1000/50,000) = 0.16 s."""
    plan = plan_jerk_position(DT, 0.0, 0.0, 0.0, 4.8, Limits(100.0, 1000.0, 1000.0, 50_000.0))
    assert plan is not None
    assert plan.end == pytest.approx(0.16, rel=1e-12)
    assert plan.vel[4] == pytest.approx(60.0, rel=1e-12)
    assert plan.acc[2] == 1000.0 and plan.start[4] == plan.start[5]  # held, no cruise


def test_a_move_lands_on_its_target_at_rest_and_never_exceeds_its_limits() -> None:
    limits = Limits(100.0, 1000.0, 800.0, 20_000.0)
    prof = SCurveProfile(DT, 0.0, 0.0, 5.0)
    prof.to_position(55.0, limits)
    assert prof.ruckig is None and prof.plan is not None
    trace = run(prof, 700)
    assert trace[-1] == (55.0, 0.0, 0.0, True)
    velocities = [s[1] for s in trace]
    accelerations = [s[2] for s in trace]
    assert max(velocities) <= 100.0 * (1 + 1e-12) and min(velocities) >= 0.0
    assert max(accelerations) <= 1000.0 * (1 + 1e-12)
    assert min(accelerations) >= -800.0 * (1 + 1e-12)
    jerks = np.diff([0.0, *accelerations]) / DT
    assert np.abs(jerks).max() <= 20_000.0 * (1 + 1e-9)
    positions = [s[0] for s in trace]
    assert positions == sorted(positions)  # never passes the target and comes back


def test_a_move_by_nothing_from_rest_ends_at_once() -> None:
    prof = SCurveProfile(DT, 0.0, 0.0, 3.0)
    prof.to_position(3.0, Limits(100.0, 1000.0, 1000.0, 20_000.0))
    assert prof.plan is not None and prof.plan.end == 0.0
    assert run(prof, 1) == [(3.0, 0.0, 0.0, True)]


# -- ruckig as the reference ------------------------------------------------------------
rates = st.floats(10.0, 10_000.0)


@settings(max_examples=300, deadline=None)
@given(
    vmax=st.floats(1.0, 1000.0),
    v_share=st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
    d=st.floats(1e-3, 1000.0),
    backward=st.booleans(),
    acc=rates,
    dec=rates,
    jerk=st.floats(100.0, 1e6),
    dt=st.sampled_from([0.0005, 0.001, 0.002, 0.004]),
)
# a peak 5.6e-9 above the start: solved on the rise, not the peak, it keeps its digits
@example(vmax=100.0, v_share=0.99999, d=100.0, backward=False, acc=10.0, dec=100.0,
         jerk=100.0, dt=0.0005)  # fmt: skip
def test_the_closed_form_samples_what_ruckig_samples(
    vmax: float,
    v_share: float,
    d: float,
    backward: bool,
    acc: float,
    dec: float,
    jerk: float,
    dt: float,
) -> None:
    """From rest or cruising toward the target: the closed form covers the move unless
    it would have to pass the target; where it does, the duration is ruckig's (the same
    time-optimal profile), every cycle agrees within ruckig's precision (and what a
    sample-time difference makes of it: :func:`.test_scurve.time_slack`), both end
    within one cycle, and the last sample is the target at rest."""
    sign = -1.0 if backward else 1.0
    v0, target = sign * v_share * vmax, sign * d
    limits = Limits(vmax, acc, dec, jerk)
    ours, ref = SCurveProfile(dt, v0), Profile(dt, v0)
    fallbacks = FALLBACKS.count
    ours.to_position(target, limits)
    ref.to_position(target, limits)
    stop = v0 * v0 / (2 * dec) + abs(v0) * dec / (2 * jerk)  # at most this far to stop
    if d >= stop:
        assert FALLBACKS.count == fallbacks  # covered
    if FALLBACKS.count == fallbacks + 1:
        # ruckig planned it: its plan, sampled, within its precision (test below)
        assert ours.plan is not None and ours.ruckig is None
        step_beside(ours, ref, dt, limits, v0)
        assert (ours.position, ours.velocity, ours.acceleration) == (target, 0.0, 0.0)
        return
    assert FALLBACKS.count == fallbacks
    plan = ours.plan
    assert plan is not None
    assert plan.end == pytest.approx(ruckig_duration(v0, target, limits), rel=1e-12, abs=1e-12)
    step_beside(ours, ref, dt, limits)
    assert (ours.position, ours.velocity, ours.acceleration) == (target, 0.0, 0.0)


def step_beside(
    ours: SCurveProfile, ref: Profile, dt: float, limits: Limits, v0: float = 0.0, a0: float = 0.0
) -> None:
    """:func:`.test_scurve.step_beside_ruckig` of a move to its end (compared until one
    of the two lands: ruckig's may land a cycle earlier) from (``v0``, ``a0``)."""
    assert ours.plan is not None
    tops = (
        max(limits.velocity, abs(v0)),
        max(limits.acceleration, limits.deceleration, abs(a0)),
        limits.jerk,
    )
    step_beside_ruckig(ours, ref, math.ceil(ours.plan.end / dt) + 3, dt, tops, after_end=False)


@settings(max_examples=300, deadline=None)
@given(
    vmax=st.floats(1.0, 1000.0),
    v_share=st.floats(0.0, 1.0),
    a_share=st.floats(-1.0, 1.0),
    d=st.floats(1e-3, 1000.0),
    backward=st.booleans(),
    acc=rates,
    dec=rates,
    jerk=st.floats(100.0, 1e6),
)
# a state ruckig finds no profile for (its step 1 fails), which the closed form plans
@example(vmax=80.0, v_share=1.0, a_share=-0.8058876932495811, d=2.0, backward=False,
         acc=3491.708138935098, dec=8827.756264456757, jerk=316605.27657133597)  # fmt: skip
def test_from_an_accelerating_state_the_duration_is_ruckigs(
    vmax: float,
    v_share: float,
    a_share: float,
    d: float,
    backward: bool,
    acc: float,
    dec: float,
    jerk: float,
) -> None:
    """A move started while the axis accelerates or decelerates within its limits:
    where the closed form covers it (the peak found by a search), the duration is
    ruckig's within 1e-9 of it (or within a time shift that moves no sample by more than
    ruckig's position precision), and the plan ends on the target at rest."""
    sign = -1.0 if backward else 1.0
    v0, target = sign * v_share * vmax, sign * d
    a0 = sign * a_share * (acc if a_share > 0 else dec)  # within the limits of travel
    limits = Limits(vmax, acc, dec, jerk)
    plan = plan_jerk_position(DT, 0.0, v0, a0, target, limits)
    v_lo = v_share * vmax + a_share * abs(a_share) * (acc if a_share > 0 else dec) ** 2 / (2 * jerk)
    if plan is None or not 0.0 <= v_lo <= vmax:
        assert plan is None or a0 == 0.0
        return
    try:
        duration = ruckig_duration(v0, target, limits, a0)
    except RuckigError:
        # ruckig finds no profile for a few of these states (this test drew v0 = 80 at
        # the limit, a0 = -7,114 of a deceleration limit of 8,828, 2 mm to go, jerk
        # 316,605: ruckig's step 1 fails): the plan is judged on its own
        assert_sound(plan, v0, a0, target, limits)
        return
    # (or a time shift that moves no sample by more than ruckig's position precision:
    # at most the peak speed times the shift)
    peak = max(abs(v) for v in plan.vel)
    assert plan.end == pytest.approx(duration, rel=1e-9, abs=P_PRECISION / max(peak, 1e-300))
    assert plan.end_position == target and plan.end_velocity == 0.0


def assert_sound(plan: JerkPlan, v0: float, a0: float, target: float, limits: Limits) -> None:
    """A plan from (0, ``v0``, ``a0``) toward ``target`` (a covered state: the velocity
    never reverses): every segment's jerk within the limit, every sample's velocity
    within the larger of ``|v0|`` and the limit and of the direction of travel, its
    acceleration within the larger of ``|a0|`` and the limits, the position never
    beyond the target nor going back; the end on the target at rest."""
    sign = 1.0 if target >= 0.0 else -1.0
    assert all(abs(j) <= limits.jerk for j in plan.jerk)
    top_v = max(abs(v0), limits.velocity) * (1 + 1e-12)
    top_a = max(abs(a0), limits.acceleration, limits.deceleration) * (1 + 1e-12)
    last = 0.0
    for k in range(1, math.ceil(plan.done / DT)):
        p, v, a = plan.sample(k * DT)
        assert -P_PRECISION <= sign * v <= top_v, k
        assert abs(a) <= top_a, k
        assert sign * (p - last) >= -P_PRECISION and sign * (target - p) >= -P_PRECISION, k
        last = p
    assert (plan.end_position, plan.end_velocity) == (target, 0.0)


def test_moves_started_while_ramping_are_planned_in_closed_form() -> None:
    """Accelerating toward a far target, and decelerating toward it: both covered, each
    as long as ruckig's plan (within 1e-9), sampled as ruckig samples it, ending on the
    target at rest."""
    limits = Limits(100.0, 1000.0, 800.0, 20_000.0)
    for v0, a0 in ((30.0, 500.0), (80.0, -500.0), (-30.0, -500.0)):
        target = math.copysign(300.0, v0)
        prof, ref = SCurveProfile(DT, v0, a0), Profile(DT, v0, a0)
        before = FALLBACKS.count
        prof.to_position(target, limits)
        ref.to_position(target, limits)
        assert prof.ruckig is None and FALLBACKS.count == before
        assert prof.plan is not None
        duration = ruckig_duration(v0, target, limits, a0)
        assert prof.plan.end == pytest.approx(duration, rel=1e-9)
        step_beside(prof, ref, DT, limits)
        assert (prof.position, prof.velocity, prof.acceleration) == (target, 0.0, 0.0)


@pytest.mark.parametrize(
    ("v0", "a0", "d"),
    [
        (90.0, 900.0, 300.0),  # to be carried beyond the limit: 90 + 900²/40,000 = 110
        (-30.0, 0.0, 50.0),  # moving away from the target
        (100.0, 0.0, 1.0),  # too close to stop before the target
        (150.0, 0.0, 500.0),  # faster than the velocity limit
        (30.0, 1500.0, 300.0),  # an acceleration beyond its limit
        (5.0, -900.0, 300.0),  # its acceleration reverses it: 5 - 900²/40,000 < 0
    ],
)
def test_other_states_are_ruckigs_own_profile_and_counted(v0: float, a0: float, d: float) -> None:
    """Planned by ruckig and counted; its phases (brake first) become the plan's
    segments, so the plan lasts as long as ruckig's trajectory and is sampled within
    ruckig's precision at every cycle, landing on the target exactly."""
    limits = Limits(100.0, 1000.0, 800.0, 20_000.0)
    before = FALLBACKS.count
    ours, ref = SCurveProfile(DT, v0, a0, 2.0), Profile(DT, v0, a0, 2.0)
    ours.to_position(2.0 + d, limits)
    ref.to_position(2.0 + d, limits)
    assert FALLBACKS.count == before + 1
    assert ours.ruckig is None and ours.plan is not None
    assert ours.plan.end == pytest.approx(ruckig_duration(v0, d, limits, a0), rel=1e-12)
    step_beside(ours, ref, DT, limits, v0, a0)
    assert (ours.position, ours.velocity, ours.acceleration) == (2.0 + d, 0.0, 0.0)


def test_a_move_no_plan_can_hold_is_refused_and_the_plan_stays() -> None:
    """1e-6 mm/s over 1e3 mm would take 1e9 s, beyond ruckig's longest trajectory."""
    prof = SCurveProfile(DT)
    prof.to_position(1.0, Limits(100.0, 1000.0, 1000.0, 20_000.0))
    plan = prof.plan
    with pytest.raises(MotionError):
        prof.to_position(1e3, Limits(1e-6, 1000.0, 1000.0, 20_000.0))
    assert prof.plan is plan and prof.target_position == 1.0


# -- many moves from rest planned together ------------------------------------------------
def plan_bits(plan: JerkPlan | None) -> list[bytes] | None:
    """Every float of ``plan`` as bytes (None: no plan)."""
    if plan is None:
        return None
    fields = (plan.start, plan.pos, plan.vel, plan.acc, plan.half, plan.jerk, plan.jhalf,
              plan.jsixth, (plan.end, plan.done, plan.end_position, plan.end_velocity))  # fmt: skip
    return [struct.pack(f"{len(f)}d", *f) for f in fields]


@settings(max_examples=200, deadline=None)
@given(
    distances=st.lists(
        st.one_of(
            st.floats(-500.0, 500.0),
            st.floats(1e-9, 1e4).map(lambda x: -x),
            st.floats(1e-9, 1e4),
            st.sampled_from([0.0, -0.0, 3, 1e9]),
        ),
        min_size=1,
        max_size=12,
    ),
    vmax=st.floats(1.0, 1000.0),
    acc=rates,
    dec=rates,
    jerk=st.floats(100.0, 1e6),
    dt=st.sampled_from([0.0005, 0.001, 0.002]),
)
def test_moves_from_rest_planned_together_are_those_planned_one_by_one(
    distances: list[float], vmax: float, acc: float, dec: float, jerk: float, dt: float
) -> None:
    """:func:`plans_from_rest` gives, bit for bit, what ``plan_jerk_position`` gives each
    distance from rest, and no plan where it gives none or refuses (1e9 mm: too long)."""
    limits = Limits(vmax, acc, dec, jerk).validated()
    together = plans_from_rest(dt, distances, limits)
    for d, plan in zip(distances, together, strict=True):
        try:
            alone = plan_jerk_position(dt, 0.0, 0.0, 0.0, float(d), limits)
        except MotionError:
            alone = None
        assert plan_bits(plan) == plan_bits(alone), d


# -- the S-curve lane -------------------------------------------------------------------
MOVE = Limits(80.0, 2000.0, 1500.0, 40_000.0)
JOG = Limits(60.0, 1000.0, 1000.0, 20_000.0)


def _start(ctl: object, distances: list[float]) -> None:
    """Jerk-limited moves of ``distances`` on the first masters, a jerk-limited jog on
    the next one (its four segments padded in the same lane)."""
    axes = ctl.axes  # type: ignore[attr-defined]
    ctl.start_moves(axes[: len(distances)], distances, MOVE)  # type: ignore[attr-defined]
    ctl.start_jogs([axes[len(distances)]], [-40.0], JOG)  # type: ignore[attr-defined]


def test_moves_step_in_the_scurve_lane_as_the_reference_path() -> None:
    distances = [50.0, -12.5, 0.3, 200.0, 50.0]
    fast, ref = controller(True), controller(False)
    for ctl in (fast, ref):
        _start(ctl, distances)
    fast.step()
    ref.step()
    lane = fast.motion.lanes[1].scurves
    assert len(lane.members) == len(distances) + 1
    for _ in range(1500):
        fast.step()
        ref.step()
        assert np.array_equal(fast.cmd_pos, ref.cmd_pos)
        assert np.array_equal(fast.cmd_vel, ref.cmd_vel)
        assert np.array_equal(fast.cmd_acc, ref.cmd_acc)
    targets = [ax.command_position for ax in fast.axes[: len(distances)]]
    assert targets == distances  # each on its target exactly (they started at 0)
    assert not any(ax.processes for ax in fast.axes[: len(distances)])  # done


@pytest.mark.parametrize("with_ends", [True, False])
def test_a_lane_saved_with_four_columns_runs_on(with_ends: bool) -> None:
    """A snapshot of a lane of velocity ramps from before moves joined it (four columns
    a segment field) is padded when loaded, and steps on as the unpadded copy; also
    one from before the lane kept the plans' ends (``with_ends`` False)."""
    ctl = controller(True)
    ctl.start_jogs(ctl.axes[:3], [40.0, -20.0, 70.0], JOG)
    for _ in range(3):
        ctl.step()
    lane = ctl.motion.lanes[1].scurves
    assert len(lane.members) == 3
    # the lane as it was saved before: four columns a segment field
    saved = statecodec.loads(statecodec.dumps(ctl))
    arrays = saved.motion.lanes[1].scurves.arrays
    for f in PLAN_FIELDS:
        arrays[f] = np.ascontiguousarray(arrays[f][:, :4])
    if not with_ends:
        for f in ("end", "end_pos", "end_vel"):
            del arrays[f]
    old = statecodec.loads(statecodec.dumps(saved))
    assert old.motion.lanes[1].scurves.arrays["start"].shape == (3, 8)
    for _ in range(100):
        ctl.step()
        old.step()
        assert np.array_equal(ctl.cmd_pos, old.cmd_pos)
        assert np.array_equal(ctl.cmd_vel, old.cmd_vel)


def test_a_snapshot_of_moves_in_the_lane_runs_on_bit_for_bit() -> None:
    """Moves and a jog in the S-curve lane, saved through the snapshot codec mid-way:
    the copy steps on as the original does, to the moves' targets."""
    distances = [50.0, -12.5, 0.3, 200.0]
    ctl = controller(True)
    _start(ctl, distances)
    for _ in range(40):
        ctl.step()
    copy = statecodec.loads(statecodec.dumps(ctl))
    # 80 ms in: the 0.3 mm move has landed (4·(0.3/80,000)^(1/3) s = 62 ms), the other
    # three moves and the jog are in the lane
    assert len(copy.motion.lanes[1].scurves.members) == 4
    for _ in range(1500):
        ctl.step()
        copy.step()
        assert ctl.cmd_pos.tobytes() == copy.cmd_pos.tobytes()
    assert [ax.command_position for ax in copy.axes[: len(distances)]] == distances


def test_many_moves_by_one_distance_share_one_plan() -> None:
    ctl = controller(True)
    ctl.start_moves(ctl.axes[:4], [25.0] * 4, MOVE)
    plans = {id(ax.processes[0].profile.plan) for ax in ctl.axes[:4]}
    assert len(plans) == 1
    assert ctl.axes[0].processes[0].profile.dt == PERIOD


def test_what_ruckig_plans_steps_in_the_scurve_lane_as_the_reference_path() -> None:
    """The states the closed form leaves to ruckig, on several axes at once: an MCD that
    lowers running moves' speed below their velocity (ruckig brakes them first), and a
    move commanded the other way while the axis still moves (moving away from its
    target). Each is counted; the moves the MCD re-plans keep their rows in the S-curve
    lane (rewritten in place: their axes are never composed in Python), the new move
    joins it, and the lanes agree with the reference path bit for bit after every cycle
    until every move has landed on its target."""
    distances = [60.0, -45.0, 80.0]
    fast, ref = controller(True), controller(False)
    for ctl in (fast, ref):
        _start(ctl, distances)
        ctl.run(40)  # about 55 mm/s, still speeding up toward 80
    lane = fast.motion.lanes[1].scurves
    before = FALLBACKS.count
    for ctl in (fast, ref):
        for ax in ctl.axes[:2]:
            (move,) = ax.processes
            assert isinstance(move, MoveProcess) and abs(ax.command_velocity) > 25.0
            move.change_dynamics(MOVE, speed=20.0)
            assert move.lane is (lane if ctl is fast else None)
        ctl.start_moves([ctl.axes[2]], [-30.0], MOVE, replace=None)
    assert FALLBACKS.count == before + 6  # three on each controller
    for k in range(1500):
        fast.step()
        ref.step()
        if k == 0:
            assert len(lane.members) == 4  # the three moves and the jog
            assert not any(ax.active() for ax in fast.motion.lanes[1].python_order)
        assert np.array_equal(fast.cmd_pos, ref.cmd_pos), k
        assert np.array_equal(fast.cmd_vel, ref.cmd_vel), k
        assert np.array_equal(fast.cmd_acc, ref.cmd_acc), k
    assert all(not ax.active(ProcessKind.MOVE) for ax in fast.axes[:3])
    landed = [ax.command_position for ax in fast.axes[:3]]
    assert landed == [ax.command_position for ax in ref.axes[:3]]


def test_axes_in_one_state_share_ruckigs_plan_and_each_is_counted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Moves braking from 100 mm/s into a 25 mm/s limit (an MCD on every axis of a
    machine): the first is planned by ruckig, the others in the same state take that
    plan; each is counted. Another state, or a velocity target of the same number, is
    planned again."""
    limits = Limits(25.0, 1000.0, 1000.0, 20_000.0)
    before = FALLBACKS.count
    profs = [SCurveProfile(DT, 100.0, 0.0, 10.0) for _ in range(3)]
    for prof in profs:
        prof.to_position(50.0, limits)
    assert FALLBACKS.count == before + 3
    assert profs[0].plan is not None
    assert profs[1].plan is profs[0].plan and profs[2].plan is profs[0].plan
    # (the velocity closed form covers 100 -> 50 mm/s: refused here, ruckig plans it)
    with monkeypatch.context() as m:
        m.setattr(scurve, "_phases", lambda *args: None)
        jog = SCurveProfile(DT, 100.0, 0.0, 10.0)
        jog.to_velocity(50.0, limits)
    assert jog.plan is not None and jog.plan.end_velocity == 50.0
    other = SCurveProfile(DT, 100.0, 0.0, 10.5)
    other.to_position(50.0, limits)
    assert other.plan is not None and other.plan is not profs[0].plan
    assert FALLBACKS.count == before + 5
    for prof in (profs[1], other):
        run(prof, 3000)
    assert (profs[1].position, profs[1].velocity) == (50.0, 0.0)
    assert (other.position, other.velocity) == (50.0, 0.0)


def test_a_paused_move_resumed_in_the_lane_steps_as_the_reference_path() -> None:
    """MCD speed 0 pauses a jerk-limited move in the S-curve lane (a ramp to rest, four
    segments, its row rewritten in place); a slow jog joins, so the lane is rebuilt
    holding velocity ramps only. Still ramping down, MCD speed 40 resumes the move (eight
    segments again, in place): the lane samples its last segments as the reference
    path does, bit for bit after every cycle until it lands."""
    fast, ref = controller(True), controller(False)
    lane = fast.motion.lanes[1].scurves
    for ctl in (fast, ref):
        _start(ctl, [60.0])
        ctl.run(60)  # the first jog at speed: the move alone in the lane
    for speed, cycles in ((0.0, 10), (40.0, 2000)):
        for ctl in (fast, ref):
            (move,) = ctl.axes[0].processes
            assert isinstance(move, MoveProcess)
            move.change_dynamics(MOVE, speed=speed)
            assert move.lane is (lane if ctl is fast else None)
            if speed == 0.0:
                # (a slow ramp, still in the lane when the resumed move's cruise begins)
                ctl.start_jogs([ctl.axes[2]], [-50.0], Limits(60.0, 200.0, 200.0, 20_000.0))
        for k in range(cycles):
            fast.step()
            ref.step()
            assert np.array_equal(fast.cmd_pos, ref.cmd_pos), (speed, k)
            assert np.array_equal(fast.cmd_vel, ref.cmd_vel), (speed, k)
            assert np.array_equal(fast.cmd_acc, ref.cmd_acc), (speed, k)
    assert not fast.axes[0].active(ProcessKind.MOVE)
    assert fast.axes[0].command_position == ref.axes[0].command_position


@pytest.mark.parametrize("jerk", [0.0, 40_000.0])
def test_a_change_of_profile_kind_leaves_the_lane_as_the_reference_path(jerk: float) -> None:
    """An MCD that turns a running move's profile into the other kind (a jerk-limited
    move made trapezoidal, jerk 0, or a trapezoidal one jerk-limited) cannot keep its
    row: it leaves its lane without its old state written back, is composed in Python,
    joins the other lane, and lands where the reference path lands, bit for bit after
    every cycle."""
    first = Limits(80.0, 2000.0, 1500.0, 40_000.0 - jerk)  # (the kind it starts as)
    fast, ref = controller(True), controller(False)
    lanes = fast.motion.lanes[1]
    for ctl in (fast, ref):
        ctl.start_moves([ctl.axes[0]], [60.0], first)
        ctl.run(30)
    before, after = (lanes.scurves, lanes.profiles) if jerk == 0.0 else (
        lanes.profiles, lanes.scurves)  # fmt: skip
    (move,) = fast.axes[0].processes
    assert move.lane is before
    for ctl in (fast, ref):
        (p,) = ctl.axes[0].processes
        assert isinstance(p, MoveProcess)
        p.change_dynamics(Limits(80.0, 2000.0, 1500.0, jerk))
    assert move.lane is None and id(move) not in before._slot
    for k in range(1500):
        fast.step()
        ref.step()
        assert np.array_equal(fast.cmd_pos, ref.cmd_pos), k
        assert np.array_equal(fast.cmd_vel, ref.cmd_vel), k
        assert np.array_equal(fast.cmd_acc, ref.cmd_acc), k
        if k == 1 and move.active:
            assert move.lane is after
    assert not move.active and fast.axes[0].command_position == ref.axes[0].command_position


def test_a_plan_ruckig_alone_can_step_stays_ruckigs_bit_for_bit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When ruckig's plan cannot be turned into segments (more than eight phases, or an
    end beyond its precision: here every plan is refused so), ruckig steps the profile
    itself: counted, its samples bit for bit a bare Profile's, and the S-curve lane
    leaves it to Python."""
    monkeypatch.setattr(scurve, "ruckig_segments", lambda *args: None)
    monkeypatch.setattr(scurve, "_last_ruckig", (b"", None))
    limits = Limits(100.0, 1000.0, 800.0, 20_000.0)
    before = FALLBACKS.count
    ours, ref = SCurveProfile(DT, 150.0, 0.0, 2.0), Profile(DT, 150.0, 0.0, 2.0)
    ours.to_position(502.0, limits)
    ref.to_position(502.0, limits)
    assert FALLBACKS.count == before + 1
    assert ours.ruckig is not None and ours.plan is None
    assert not SCurveLane.accepts(MoveProcess(DT, 502.0, limits, 150.0, 0.0))
    assert run(ours, 6000) == run(ref, 6000)
    assert (ours.position, ours.velocity, ours.finished) == (502.0, 0.0, True)


def test_a_plan_longer_than_the_closed_forms_take_stays_ruckigs() -> None:
    """ruckig plans this state (0.75 mm/s and -4,483 mm/s² against a 322 mm/s²
    acceleration limit, 0.82 mm back) in a trajectory of about 8,209 s, beyond the
    7,600 s the closed forms refuse: the move is not refused, ruckig steps it itself,
    and it is counted."""
    dt, v0, a0, d = 0.0005, 0.7504460729582255, -4482.887242357632, -0.8218419167060158
    limits = Limits(2.7686956516556287, 322.01830768451214, 3065.0284829058246, 1650.7015224445454)
    before = FALLBACKS.count
    ours, ref = SCurveProfile(dt, v0, a0), Profile(dt, v0, a0)
    ours.to_position(d, limits)
    ref.to_position(d, limits)
    assert FALLBACKS.count == before + 1
    assert ours.ruckig is not None and ref.trajectory is not None
    assert ref.trajectory.duration > 7_600.0
    assert run(ours, 50) == run(ref, 50)
