"""Kinematics from first principles: jogs, moves and stops checked by finite differences
of the sampled command trace, the drive's following error, feedback-only axes.

Finite differences of a trace p_k sampled every dt: v = Δp/dt, a = Δ²p/dt², j = Δ³p/dt³.
For a trapezoidal profile sampled exactly, |a| never exceeds the acceleration limit; for
an S-curve, |j| never exceeds the jerk limit (a difference is an average of the
continuous quantity over the window, and an average cannot exceed a bound of the values).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    ErrorCode,
    FeedbackSignal,
    PLCopenState,
)

from ..support import make_system, sample, trigger

DT = 0.002
REL = 1e-9  # relative tolerance for rounding in finite differences


def servo(number: int = 1, **kw: object) -> AxisConfig:
    params: dict[str, object] = {
        "max_velocity": 100.0,
        "max_acceleration": 1000.0,
        "max_deceleration": 1000.0,
    }
    params.update(kw)
    return AxisConfig(number, f"Axis{number}", AxisType.SERVO, **params)  # type: ignore[arg-type]


def powered(*axes: AxisConfig, period: float = DT) -> MotionSystem:
    """A system with MSO executed on every axis."""
    system = make_system(*axes, period=period)
    mso = system.add("MSO", "MSO_1")
    for a in axes:
        release(system, mso)
        trigger(system, mso, Axis=a.number)
        assert mso.outputs["DN"], mso.outputs
    release(system, mso)
    return system


def release(system: MotionSystem, inst: Instruction) -> None:
    """Rung / Execute low for one cycle."""
    inst.inputs[inst.TRIGGER] = False
    system.cycle()


def trace_from_trigger(
    system: MotionSystem, inst: Instruction, cycles: int, axis: int = 1, **operands: object
) -> np.ndarray:
    """Command positions: the sample before the trigger, then one per cycle from the
    trigger cycle on (``cycles`` + 1 samples)."""
    ax = system.ctl.axis(axis)
    start = ax.command_position_unwound
    trigger(system, inst, **operands)
    first = ax.command_position_unwound
    return np.concatenate([[start, first], sample(system, axis, cycles - 1)])


def diffs(p: np.ndarray, dt: float, order: int) -> np.ndarray:
    return np.diff(p, n=order) / dt**order


def first_cycle(values: np.ndarray, predicate: Callable[[float], bool]) -> int:
    """Index of the first sample meeting ``predicate`` (samples start before the trigger,
    so the index is the number of cycles since the trigger cycle began)."""
    hits = [k for k, v in enumerate(values) if predicate(float(v))]
    assert hits, "never reached"
    return hits[0]


# -- jogs -----------------------------------------------------------------------------------
def test_trapezoidal_jog_reaches_speed_within_its_acceleration_limit() -> None:
    system = powered(servo())
    maj = system.add("MAJ", "MAJ_1")
    speed, accel = 50.0, 500.0
    p = trace_from_trigger(system, maj, 150, Axis=1, Speed=speed, AccelRate=accel, DecelRate=accel)
    v = diffs(p, DT, 1)
    a = diffs(p, DT, 2)
    assert np.abs(a).max() <= accel * (1 + REL)
    # it accelerates at the limit, not slower: the interior of the ramp is at `accel`
    assert a[5:45] == pytest.approx(accel, rel=1e-6)
    assert system.ctl.axis(1).command_velocity == speed
    assert v[-1] == pytest.approx(speed, rel=1e-9)
    # time to speed v/a = 0.1 s, within one cycle
    k = first_cycle(v, lambda x: x >= speed * (1 - 1e-9))
    assert abs(k * DT - speed / accel) <= DT


def test_s_curve_jog_respects_the_jerk_limit() -> None:
    system = powered(servo())
    maj = system.add("MAJ", "MAJ_1")
    speed, accel, jerk = 50.0, 500.0, 10000.0
    p = trace_from_trigger(
        system,
        maj,
        150,
        Axis=1,
        Speed=speed,
        AccelRate=accel,
        DecelRate=accel,
        Profile=1,  # S-curve
        AccelJerk=jerk,
        DecelJerk=jerk,
        JerkUnits=0,  # units/s^3
    )
    j = diffs(p, DT, 3)
    a = diffs(p, DT, 2)
    v = diffs(p, DT, 1)
    assert np.abs(j).max() <= jerk * (1 + REL) + 1e-6
    assert np.abs(a).max() <= accel * (1 + REL)
    # v > a^2/J (25 mm/s): the ramp reaches `accel`; time to speed v/a + a/J = 0.15 s
    k = first_cycle(v, lambda x: x >= speed * (1 - 1e-9))
    assert abs(k * DT - (speed / accel + accel / jerk)) <= DT
    assert system.ctl.axis(1).command_velocity == speed


# -- moves ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("start", "target"),
    # start + (target - start) != target in floating point for all but the first two
    [(0.1 + 0.2, 123.456), (1.0 / 3.0, -7.7), (-52.407, 8.846), (99.129, -5.947), (73.105, -5.45)],
)
def test_absolute_move_ends_exactly_on_target(start: float, target: float) -> None:
    system = powered(servo(max_velocity=2000.0, max_acceleration=1e5, max_deceleration=1e5))
    mam = system.add("MAM", "MAM_1")
    fast = {"Speed": 2000.0, "AccelRate": 1e5, "DecelRate": 1e5}
    trigger(system, mam, Axis=1, Position=start, **fast)
    system.cycle(200)
    assert system.ctl.axis(1).command_position == start
    release(system, mam)
    trigger(system, mam, Axis=1, Position=target, **fast)
    system.cycle(200)
    ax = system.ctl.axis(1)
    assert mam.outputs["PC"]
    assert ax.command_position == target  # exactly, not approximately
    assert ax.command_velocity == 0.0


def test_trapezoidal_move_duration() -> None:
    """d = 100 mm at v = 50 mm/s, a = d = 500 mm/s^2: it reaches v (d > v^2/a), so it
    lasts d/v + v/a = 2.1 s; it ends exactly on target and PC is set in that cycle."""
    system = powered(servo())
    mam = system.add("MAM", "MAM_1")
    p = trace_from_trigger(
        system, mam, 1100, Axis=1, MoveType=1, Position=100.0, Speed=50.0,
        AccelRate=500.0, DecelRate=500.0,
    )  # fmt: skip
    k = first_cycle(p, lambda x: x == 100.0)
    assert abs(k * DT - (100.0 / 50.0 + 50.0 / 500.0)) <= DT
    assert (p[k:] == 100.0).all()
    assert np.abs(diffs(p, DT, 2)).max() <= 500.0 * (1 + REL)
    assert diffs(p, DT, 1).max() <= 50.0 * (1 + REL)


def test_triangular_move_duration() -> None:
    """d = 2 mm with a = 500 mm/s^2 never reaches 50 mm/s (d < v^2/a = 5 mm): it
    lasts 2*sqrt(d/a) = 0.1265 s and peaks at sqrt(a*d) = 31.6 mm/s."""
    system = powered(servo())
    mam = system.add("MAM", "MAM_1")
    p = trace_from_trigger(
        system, mam, 100, Axis=1, MoveType=1, Position=2.0, Speed=50.0,
        AccelRate=500.0, DecelRate=500.0,
    )  # fmt: skip
    k = first_cycle(p, lambda x: x == 2.0)
    assert abs(k * DT - 2.0 * math.sqrt(2.0 / 500.0)) <= DT
    assert diffs(p, DT, 1).max() <= math.sqrt(500.0 * 2.0) * (1 + REL)


# -- MAS ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("change_decel", "decel"),
    [(1, 250.0), (0, 1000.0)],  # ChangeDecel No: the axis maximum deceleration
)
def test_mas_stops_at_the_configured_deceleration(change_decel: int, decel: float) -> None:
    system = powered(servo())
    maj = system.add("MAJ", "MAJ_1")
    mas = system.add("MAS", "MAS_1")
    trigger(system, maj, Axis=1, Speed=50.0, AccelRate=1000.0, DecelRate=1000.0)
    system.cycle(100)
    ax = system.ctl.axis(1)
    assert ax.command_velocity == 50.0
    x0 = ax.command_position
    p = trace_from_trigger(
        system, mas, 150, Axis=1, StopType=1, ChangeDecel=change_decel, DecelRate=250.0
    )
    a = diffs(p, DT, 2)
    assert np.abs(a).max() <= decel * (1 + REL)
    assert a.min() == pytest.approx(-decel, rel=1e-6)  # and not more gently
    v = diffs(p, DT, 1)
    k = first_cycle(v, lambda x: x == 0.0)
    assert abs(k * DT - 50.0 / decel) <= DT
    # stopping distance v^2 / 2d
    assert ax.command_position - x0 == pytest.approx(50.0**2 / (2 * decel), abs=1e-9)
    assert mas.outputs["PC"] and not mas.outputs["IP"]


# -- rotary moves ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("move_type", "target", "displacement"),
    [
        (2, 10.0, 20.0),  # shortest path from 350 to 10: +20
        (2, 300.0, -50.0),  # shortest path from 350 to 300: -50
        (3, 340.0, 350.0),  # positive from 350 to 340: the long way, +350
        (4, 10.0, -340.0),  # negative from 350 to 10: -340
        (0, 10.0, -340.0),  # absolute: within the unwind, 350 -> 10 is -340
    ],
)
def test_rotary_move_types(move_type: int, target: float, displacement: float) -> None:
    system = powered(
        servo(units="deg", rollover=360.0, max_velocity=3600.0, max_acceleration=36000.0,
              max_deceleration=36000.0)
    )  # fmt: skip
    mam = system.add("MAM", "MAM_1")
    dyn = {"Speed": 1800.0, "AccelRate": 36000.0, "DecelRate": 36000.0}
    trigger(system, mam, Axis=1, MoveType=0, Position=350.0, **dyn)
    system.cycle(300)
    ax = system.ctl.axis(1)
    assert ax.command_position == 350.0
    release(system, mam)
    p = trace_from_trigger(system, mam, 400, Axis=1, MoveType=move_type, Position=target, **dyn)
    v = diffs(p, DT, 1)
    assert (v * math.copysign(1.0, displacement) >= 0.0).all()  # one direction only
    assert p[-1] - p[0] == displacement
    assert ax.command_position == target
    assert 0.0 <= ax.actual_position < 360.0


def test_rotary_target_outside_the_unwind_is_refused() -> None:
    system = powered(servo(units="deg", rollover=360.0))
    mam = system.add("MAM", "MAM_1")
    trigger(system, mam, Axis=1, MoveType=2, Position=360.0)
    assert mam.outputs["ER"] and mam.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert mam.outputs["EXERR"] == 3  # MAM(Axis, MotionControl, MoveType, Position, ...)
    system.cycle(10)
    assert system.ctl.axis(1).command_position == 0.0


# -- following error ------------------------------------------------------------------------
def steady_following_error(v: float, bandwidth: float) -> float:
    """x'' + 2w x' + w^2 x = w^2 c with c = v t: try x = v t - L; then 2w v = w^2 L, so
    the loop lags the command by L = 2v/w (w = 2 pi bandwidth) once the transient
    (A + B t) e^(-wt) has died away."""
    return 2.0 * v / (2.0 * math.pi * bandwidth)


@pytest.mark.parametrize(
    ("speed", "bandwidth", "period"),
    [(100.0, 40.0, 0.002), (250.0, 25.0, 0.001), (60.0, 10.0, 0.004)],
)
def test_steady_following_error_is_2v_over_omega(
    speed: float, bandwidth: float, period: float
) -> None:
    system = powered(
        servo(max_velocity=1000.0, max_acceleration=1e4, drive_bandwidth=bandwidth),
        period=period,
    )
    maj = system.add("MAJ", "MAJ_1")
    trigger(system, maj, Axis=1, Speed=speed, AccelRate=5000.0, DecelRate=5000.0)
    # at speed after v/a; then wait until (1 + wt) e^(-wt) < 1e-10 (wt = 27)
    w = 2.0 * math.pi * bandwidth
    system.cycle(math.ceil((speed / 5000.0 + 27.0 / w) / period))
    ax = system.ctl.axis(1)
    expected = steady_following_error(speed, bandwidth)
    half_count = 0.5 / ax.config.counts_per_unit
    for _ in range(20):
        system.cycle()
        assert ax.command_velocity == speed
        assert abs(ax.position_error - expected) <= half_count + 1e-9
        assert ax.actual_velocity == pytest.approx(speed, rel=1e-9)


def test_following_error_beyond_its_limit_faults_the_axis() -> None:
    """FE limit 0.5 mm at 40 Hz: while accelerating at a the lag is 2v/w - 3a/w^2, so it
    crosses 0.5 mm near v = 68.8 mm/s, before the jog reaches 100 mm/s."""
    system = powered(servo(following_error_limit=0.5, coast_deceleration=400.0))
    maj = system.add("MAJ", "MAJ_1")
    ax = system.ctl.axis(1)
    t0 = system.ctl.time
    trigger(system, maj, Axis=1, Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
    w = 2.0 * math.pi * 40.0
    errors = [ax.position_error]
    for _ in range(60):
        if ax.state == AxisState.AXIS_FAULTED:
            break
        system.cycle()
        errors.append(ax.position_error)
    assert ax.state == AxisState.AXIS_FAULTED
    assert ax.fault & AxisFault.POSITION_ERROR
    assert ax.plcopen_state == PLCopenState.ERRORSTOP
    # it faulted in the first cycle whose error exceeded the limit
    assert errors[-1] > 0.5 and max(errors[:-1]) <= 0.5
    v_fault = (0.5 + 3 * 1000.0 / w**2) * w / 2
    assert abs((system.ctl.time - t0) - v_fault / 1000.0) <= DT
    assert not maj.outputs["IP"]
    # the drive is off: the axis coasts at 400 mm/s^2, the command follows the actual
    v = []
    for _ in range(10):
        system.cycle()
        v.append(ax.actual_velocity)
        assert ax.command_position == ax.actual_position
    assert np.diff(v) == pytest.approx(-400.0 * DT, rel=1e-9)
    # motion refused while faulted, the axis does not move by it
    release(system, maj)
    trigger(system, maj, Axis=1)
    assert maj.outputs["ER"] and maj.outputs["ERR"] == ErrorCode.AXIS_FAULTED
    msoi = system["MSO_1"]
    trigger(system, msoi, Axis=1)
    assert msoi.outputs["ERR"] == ErrorCode.AXIS_FAULTED
    # MAFR clears it: Axis Ready, then MSO closes the loop where the axis is
    mafr = system.add("MAFR", "MAFR_1")
    trigger(system, mafr, Axis=1)
    assert mafr.outputs["DN"]
    assert ax.state == AxisState.AXIS_READY and ax.fault == 0
    system.cycle(100)  # coasts to rest
    release(system, msoi)
    trigger(system, msoi, Axis=1)
    assert ax.state == AxisState.SERVO_CONTROL
    release(system, maj)
    trigger(system, maj, Axis=1, Speed=10.0)
    assert maj.outputs["IP"] and not maj.outputs["ER"]


# -- feedback-only axes -----------------------------------------------------------------------
def feedback(**kw: object) -> AxisConfig:
    return AxisConfig(4, "Axis4", AxisType.FEEDBACK_ONLY, **kw)  # type: ignore[arg-type]


def test_hand_wheel_input_quantised_to_counts() -> None:
    system = make_system(feedback(conversion_constant=100.0))
    ax = system.ctl.axis(4)
    system.ctl.set_feedback_input(ax, 12.3456)
    system.cycle()
    assert ax.actual_position == 12.35  # 1234.56 counts -> 1235
    system.ctl.set_feedback_input(ax, 12.3556)
    system.cycle()
    assert ax.actual_position == 12.36
    assert ax.actual_velocity == pytest.approx(0.01 / DT, rel=1e-9)
    with pytest.raises(Exception) as info:
        system.ctl.set_feedback_input(ax, math.nan)
    assert getattr(info.value, "code", None) == ErrorCode.PARAMETER_OUT_OF_RANGE
    system.cycle()
    assert ax.actual_position == 12.36


def test_rotary_hand_wheel_unwinds() -> None:
    """The input is a wrapped reading: each new reading is taken the short way round
    from the last one (a hand wheel cannot turn half a revolution in one cycle)."""
    system = make_system(feedback(conversion_constant=10.0, rollover=360.0))
    ax = system.ctl.axis(4)
    system.ctl.set_feedback_input(ax, 350.0)  # 10 degrees back from 0
    system.cycle()
    assert ax.actual_position == 350.0
    assert ax.actual_position_unwound == -10.0
    system.ctl.set_feedback_input(ax, 10.0)  # 20 degrees forward, across the unwind
    system.cycle()
    assert ax.actual_position == 10.0
    assert ax.actual_position_unwound == 10.0
    assert ax.actual_velocity == pytest.approx(20.0 / DT)


def test_constant_velocity_signal() -> None:
    """33 mm/s read with 10 counts/mm: 0.33 mm after 5 cycles is 3.3 counts -> 0.3 mm;
    after 100 cycles (0.2 s), 6.6 mm exactly."""
    system = make_system(
        feedback(
            conversion_constant=10.0,
            feedback_signal=FeedbackSignal.CONSTANT_VELOCITY,
            signal_velocity=33.0,
        )
    )
    ax = system.ctl.axis(4)
    system.cycle(5)
    assert ax.actual_position == 0.3
    system.cycle(95)
    assert ax.actual_position == 6.6


def test_sine_signal() -> None:
    """10 mm amplitude at f = 1/(12 * 0.02 s): at 10 cycles (0.02 s) the phase is 30°,
    5 mm; a quarter period (30 cycles) 10 mm; half (60) 0; three quarters -10 mm."""
    system = make_system(
        feedback(
            conversion_constant=100.0,
            feedback_signal=FeedbackSignal.SINE,
            signal_amplitude=10.0,
            signal_frequency=1.0 / 0.24,
        )
    )
    ax = system.ctl.axis(4)
    expected = {10: 5.0, 30: 10.0, 60: 0.0, 90: -10.0, 120: 0.0}
    done = 0
    for k, value in expected.items():
        system.cycle(k - done)
        done = k
        assert ax.actual_position == value, k


@pytest.mark.parametrize("type_name", ["MSO", "MSF", "MAJ", "MAM", "MAS", "MCD"])
def test_feedback_only_axis_refuses_motion_instructions(type_name: str) -> None:
    system = make_system(feedback(conversion_constant=100.0))
    inst = system.add(type_name, f"{type_name}_1")
    ax = system.ctl.axis(4)
    system.ctl.set_feedback_input(ax, 1.0)
    system.cycle()
    trigger(system, inst, Axis=4)
    assert inst.outputs["ER"]
    assert inst.outputs["ERR"] == ErrorCode.WRONG_AXIS_TYPE
    system.cycle(10)
    assert ax.actual_position == 1.0
    assert ax.processes == []
