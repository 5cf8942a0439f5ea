"""MC_GearIn, MC_GearOut and MC_CombineAxes, with the seed's test scenarios.

Kinematics used: a master at 100 units/s geared 1/2 gives 50 units/s; a catch-up at
1000 units/s^2 reaches it in 0.05 s = 25 cycles of 2 ms; MC_Stop at 500 units/s^2 brings
50 units/s to rest in 0.1 s = 50 cycles.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import AxisConfig, AxisType, PLCopenState, ProcessKind

from ..support import make_system, trigger

DT = 0.002


def system() -> MotionSystem:
    """1 and 3 virtual masters (powered), 2 and 5 servo slaves, 4 a hand wheel (100 counts/unit)."""
    servo = dict(max_velocity=1000.0, max_acceleration=5000.0, max_deceleration=5000.0)
    s = make_system(
        AxisConfig(1, "Master1", AxisType.VIRTUAL, max_acceleration=1e5, max_deceleration=1e5),
        AxisConfig(2, "Slave", AxisType.SERVO, **servo),
        AxisConfig(3, "Master2", AxisType.VIRTUAL, max_acceleration=1e5, max_deceleration=1e5),
        AxisConfig(4, "Wheel", AxisType.FEEDBACK_ONLY, conversion_constant=100.0),
        AxisConfig(5, "Slave2", AxisType.SERVO, **servo),
    )
    for n in (1, 3):  # the masters; slaves are powered by MC_Power in the tests
        s.ctl.servo_on(s.ctl.axis(n))
    return s


def power(s: MotionSystem, *axes: int) -> None:
    for n in axes:
        p = s.add("MC_Power", f"Power{n}", {"Axis": n})
        p.inputs["Enable"] = True
    s.cycle()


def run(s: MotionSystem, axis: int, velocity: float) -> Instruction:
    """Bring ``axis`` to ``velocity`` with a jog (accel 1e5) and keep it there."""
    j = s.add("MAJ", f"Jog{axis}_{len(s.instances)}", {"Axis": axis})
    trigger(
        s,
        j,
        Speed=abs(velocity),
        Direction=1 if velocity < 0 else 0,
        AccelRate=1e5,
        DecelRate=1e5,
    )
    j.inputs["Execute"] = False
    s.cycle(20)
    assert s.ctl.axis(axis).command_velocity == pytest.approx(velocity)
    return j


def gear_in(s: MotionSystem, name: str = "GearIn", **operands: object) -> Instruction:
    ops: dict[str, object] = {"Master": 1, "Slave": 2, "Acceleration": 1000.0}
    ops["Deceleration"] = 1000.0
    ops.update(operands)
    g = s.add("MC_GearIn", name, {})
    trigger(s, g, **ops)
    return g


def cmd(s: MotionSystem, axis: int) -> float:
    return s.ctl.axis(axis).command_position_unwound


def vel(s: MotionSystem, axis: int) -> float:
    return s.ctl.axis(axis).command_velocity


# -- MC_GearIn ----------------------------------------------------------------------------


def test_gear_in_follows_a_hand_wheel_one_to_one_on_actual_position() -> None:
    """The seed's FB test: RatioNumerator 1, RatioDenominator 1, MasterValueSource 1;
    turn the hand wheel and the servo follows at 1:1."""
    s = system()
    power(s, 2)
    wheel = s.ctl.axis(4)
    s.ctl.set_feedback_input(wheel, 3.0)
    s.cycle()
    g = gear_in(s, Master=4, RatioNumerator=1.0, RatioDenominator=1.0, MasterValueSource=1)
    assert g.outputs["Busy"] and g.outputs["Active"] and g.outputs["InGear"]
    slave = s.ctl.axis(2)
    assert slave.plcopen_state == PLCopenState.SYNCHRONIZED_MOTION
    w0, s0 = wheel.actual_position_unwound, cmd(s, 2)
    # a hand turning the wheel: uneven increments, forward then back
    rng = np.random.default_rng(7)
    readings = np.concatenate(
        [3.0 + np.cumsum(rng.uniform(0.0, 0.08, 300)), 3.0 + np.linspace(24.0, 9.5, 200)]
    )
    for r in readings:
        s.ctl.set_feedback_input(wheel, float(r))
        s.cycle()
        assert cmd(s, 2) - s0 == wheel.actual_position_unwound - w0
        assert g.outputs["InGear"]
    # the wheel's reading is quantised to its 100 counts per unit
    assert wheel.actual_position_unwound == round(readings[-1] * 100) / 100
    s.cycle(250)  # the wheel rests: the servo's actual settles on its command
    assert abs(slave.actual_position_unwound - cmd(s, 2)) <= 1 / 1000


def test_set_value_reference_to_a_feedback_only_master_is_refused() -> None:
    s = system()
    power(s, 2)
    g = gear_in(s, Master=4, MasterValueSource=0)
    assert g.outputs["Error"] and g.outputs["ErrorID"] == 8 and not g.outputs["Busy"]
    assert s.ctl.axis(2).active() == []


def test_catch_up_respects_acceleration_and_in_gear_rises_at_the_gear_velocity() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 100.0)
    before = [cmd(s, 2)] * 2
    g = gear_in(s, RatioNumerator=1.0, RatioDenominator=2.0)
    positions, in_gear, velocities = list(before), [], []
    for _ in range(40):
        positions.append(cmd(s, 2))
        in_gear.append(g.outputs["InGear"])
        velocities.append(vel(s, 2))
        s.cycle()
    first = in_gear.index(True) + 1  # cycles since the rising edge, counting it
    assert first in (25, 26)
    assert velocities[first - 1] == pytest.approx(50.0)
    assert all(v < 50.0 for v in velocities[: first - 1])
    assert all(in_gear[first - 1 :])
    a = np.diff(np.array(positions), 2) / DT**2
    assert np.max(np.abs(a)) <= 1000.0 * (1 + 1e-6)
    assert not g.outputs["CommandAborted"] and g.outputs["Busy"]


def test_jerk_limited_catch_up() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 100.0)
    g = gear_in(s, RatioNumerator=1.0, RatioDenominator=2.0, Jerk=50_000.0)
    acc = [s.ctl.axis(2).command_acceleration]
    for _ in range(100):
        s.cycle()
        acc.append(s.ctl.axis(2).command_acceleration)
    assert g.outputs["InGear"] and vel(s, 2) == pytest.approx(50.0)
    a = np.array(acc)
    assert np.max(np.abs(a)) <= 1000.0 * (1 + 1e-9)
    assert np.max(np.abs(np.diff(a))) / DT <= 50_000.0 * (1 + 1e-6)


def test_a_new_rising_edge_changes_the_ratio() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 100.0)
    g = gear_in(s, RatioNumerator=1.0, RatioDenominator=2.0)
    g.inputs["Execute"] = False
    s.cycle(40)
    assert g.outputs["InGear"] and vel(s, 2) == pytest.approx(50.0)
    trigger(s, g, RatioNumerator=3.0)  # 3/2: 150 units/s, 100 more at 1000 units/s^2
    assert not g.outputs["InGear"] and g.outputs["Busy"] and not g.outputs["CommandAborted"]
    s.cycle(48)
    assert not g.outputs["InGear"]
    s.cycle(2)
    assert g.outputs["InGear"] and vel(s, 2) == pytest.approx(150.0)
    m0, s0 = cmd(s, 1), cmd(s, 2)
    s.cycle(10)
    assert cmd(s, 2) - s0 == pytest.approx(1.5 * (cmd(s, 1) - m0), abs=1e-9)


def test_gear_in_buffered_starts_when_the_move_is_done() -> None:
    s = system()
    power(s, 2)
    move = s.add("MC_MoveAbsolute", "Move", {})
    trigger(s, move, Axis=2, Position=2.0, Velocity=20.0, Acceleration=1000.0, Deceleration=1000.0)
    g = gear_in(s, BufferMode=1)
    assert g.outputs["Busy"] and not g.outputs["Active"]
    assert s.ctl.axis(2).active(ProcessKind.GEAR) == []
    for _ in range(200):
        s.cycle()
        if move.outputs["Done"]:
            break
    s.cycle()
    assert g.outputs["Active"] and g.outputs["InGear"]  # master at rest: in gear at once
    assert cmd(s, 2) == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("operands", "code"),
    [
        ({"RatioDenominator": 0.0}, 13),
        ({"RatioDenominator": -2.0}, 13),
        ({"RatioNumerator": 0.0}, 13),
        ({"RatioNumerator": float("nan")}, 13),
        ({"Acceleration": 0.0}, 13),
        ({"Jerk": -1.0}, 13),
        ({"MasterValueSource": 2}, 13),
        ({"Master": 2}, 10),
        ({"Slave": 5}, 5),
        ({"Master": 42}, 11),
    ],
)
def test_gear_in_errors_move_nothing(operands: dict[str, object], code: int) -> None:
    s = system()
    power(s, 2)
    run(s, 1, 100.0)
    g = gear_in(s, **operands)
    assert g.outputs["Error"] and g.outputs["ErrorID"] == code
    assert not g.outputs["Busy"] and not g.outputs["InGear"]
    p = cmd(s, 2)
    s.cycle(10)
    assert cmd(s, 2) == p and s.ctl.axis(2).active() == []


def test_a_loop_through_another_slave_is_refused() -> None:
    s = system()
    power(s, 2, 5)
    assert gear_in(s, "a", Master=2, Slave=5).outputs["Busy"]
    g = gear_in(s, "b", Master=5, Slave=2)
    assert g.outputs["Error"] and g.outputs["ErrorID"] == 10


# -- MC_GearOut ---------------------------------------------------------------------------


def test_gear_out_keeps_the_velocity_until_mc_stop() -> None:
    """The seed's FB test: master at constant speed, GearIn, GearOut: the slave keeps its
    speed in continuous motion; MC_Stop stops it."""
    s = system()
    power(s, 2)
    jog = run(s, 1, 100.0)
    g = gear_in(s, RatioNumerator=1.0, RatioDenominator=2.0)
    s.cycle(40)
    assert g.outputs["InGear"]
    out = s.add("MC_GearOut", "GearOut", {})
    trigger(s, out, Slave=2)
    assert out.outputs["Done"] and not out.outputs["Busy"] and not out.outputs["Error"]
    assert g.outputs["CommandAborted"] and not g.outputs["InGear"]
    slave = s.ctl.axis(2)
    assert slave.plcopen_state == PLCopenState.CONTINUOUS_MOTION
    stop_master = s.add("MAS", "StopMaster", {})
    trigger(s, stop_master, Axis=1)  # the master stops; the slave does not care
    x0 = cmd(s, 2)
    for k in range(1, 201):
        s.cycle()
        assert vel(s, 2) == 50.0
        assert cmd(s, 2) - x0 == pytest.approx(50.0 * k * DT, abs=1e-9)
    assert vel(s, 1) == 0.0 and jog.outputs["DN"]
    stop = s.add("MC_Stop", "Stop", {})
    trigger(s, stop, Axis=2, Deceleration=500.0)
    v = [vel(s, 2)]
    for _ in range(60):
        s.cycle()
        v.append(vel(s, 2))
    # 50 / 500 = 0.1 s = 50 cycles, the first of them the scan that starts the stop
    assert v[48] > 0.0 and v[49] == 0.0
    assert np.max(np.abs(np.diff(v))) / DT <= 500.0 * (1 + 1e-9)
    assert stop.outputs["Done"]


def test_mc_stop_disengages_the_gear_directly() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 100.0)
    g = gear_in(s, RatioNumerator=1.0, RatioDenominator=2.0)
    s.cycle(40)
    stop = s.add("MC_Stop", "Stop", {})
    trigger(s, stop, Axis=2, Deceleration=500.0)
    assert g.outputs["CommandAborted"] and not g.outputs["Busy"]
    assert s.ctl.axis(2).active(ProcessKind.GEAR) == []
    s.cycle(60)
    assert vel(s, 2) == 0.0 and stop.outputs["Done"]


def test_gear_out_of_an_axis_that_is_not_geared_is_an_error() -> None:
    s = system()
    power(s, 2)
    out = s.add("MC_GearOut", "GearOut", {})
    trigger(s, out, Slave=2)
    assert out.outputs["Error"] and out.outputs["ErrorID"] == 1003 and not out.outputs["Done"]


def test_gear_out_disengages_a_mag_too() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 100.0)
    mag = s.add("MAG", "MAG", {})
    trigger(s, mag, SlaveAxis=2, MasterAxis=1, Ratio=0.25, Clutch=1)
    out = s.add("MC_GearOut", "GearOut", {})
    trigger(s, out, Slave=2)
    assert out.outputs["Done"] and not mag.outputs["IP"]
    s.cycle(10)
    assert vel(s, 2) == 25.0


# -- MC_CombineAxes -----------------------------------------------------------------------


@pytest.mark.parametrize(("mode", "sign"), [(0, 1.0), (1, -1.0)], ids=["add", "subtract"])
def test_combine_axes_sum_and_difference_of_two_masters(mode: int, sign: float) -> None:
    """The seed's FB test: all ratios 1/1 on command positions, the combine engaged, then
    both masters at constant velocity: slave velocity = v1 + v2 (add) or v1 - v2."""
    s = system()
    power(s, 2)
    c = s.add("MC_CombineAxes", "Combine", {})
    trigger(s, c, Master1=1, Master2=3, Slave=2, CombineMode=mode)
    assert c.outputs["Busy"] and c.outputs["InSync"]  # masters at rest: in sync at once
    m1, m2, s0 = cmd(s, 1), cmd(s, 3), cmd(s, 2)
    run(s, 1, 30.0)
    run(s, 3, 10.0)
    for _ in range(100):
        s.cycle()
        expected = (cmd(s, 1) - m1) + sign * (cmd(s, 3) - m2)
        assert cmd(s, 2) - s0 == pytest.approx(expected, abs=1e-9)
    assert vel(s, 2) == pytest.approx(30.0 + sign * 10.0)
    assert c.outputs["InSync"]


def test_combine_axes_applies_each_masters_own_ratio() -> None:
    s = system()
    power(s, 2)
    c = s.add("MC_CombineAxes", "Combine", {})
    trigger(
        s,
        c,
        Master1=1,
        Master2=3,
        Slave=2,
        CombineMode=1,
        GearRatioNumeratorM1=2.0,
        GearRatioDenominatorM1=1.0,
        GearRatioNumeratorM2=-1.0,
        GearRatioDenominatorM2=4.0,
    )
    run(s, 1, 30.0)
    run(s, 3, 20.0)
    s.cycle(5)
    assert vel(s, 2) == pytest.approx(2.0 * 30.0 - (-0.25) * 20.0)


def test_combine_catches_up_with_moving_masters() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 30.0)
    run(s, 3, 10.0)
    c = s.add("MC_CombineAxes", "Combine", {})
    trigger(s, c, Master1=1, Master2=3, Slave=2, Acceleration=1000.0, Deceleration=1000.0)
    assert not c.outputs["InSync"]
    s.cycle(18)  # 40 units/s at 1000 units/s^2: 0.04 s = 20 cycles
    assert not c.outputs["InSync"]
    s.cycle(2)
    assert c.outputs["InSync"] and vel(s, 2) == pytest.approx(40.0)


def test_gear_out_on_a_combined_slave_is_refused_and_mc_stop_ends_it() -> None:
    s = system()
    power(s, 2)
    run(s, 1, 30.0)
    run(s, 3, 10.0)
    c = s.add("MC_CombineAxes", "Combine", {})
    trigger(s, c, Master1=1, Master2=3, Slave=2, Acceleration=1000.0, Deceleration=1000.0)
    s.cycle(30)
    out = s.add("MC_GearOut", "GearOut", {})
    trigger(s, out, Slave=2)
    assert out.outputs["Error"] and out.outputs["ErrorID"] == 1002
    assert c.outputs["InSync"] and not c.outputs["CommandAborted"]
    s.cycle()
    assert vel(s, 2) == pytest.approx(40.0)
    stop = s.add("MC_Stop", "Stop", {})
    trigger(s, stop, Axis=2, Deceleration=1000.0)
    assert c.outputs["CommandAborted"] and not c.outputs["InSync"]
    s.cycle(50)
    assert vel(s, 2) == 0.0


@pytest.mark.parametrize(
    ("operands", "code"),
    [
        ({"GearRatioDenominatorM1": 0.0}, 13),
        ({"GearRatioNumeratorM2": 0.0}, 13),
        ({"CombineMode": 2}, 13),
        ({"MasterValueSourceM2": 0, "Master2": 4}, 8),
        ({"Master1": 2}, 10),
    ],
)
def test_combine_errors_move_nothing(operands: dict[str, object], code: int) -> None:
    s = system()
    power(s, 2)
    run(s, 1, 30.0)
    c = s.add("MC_CombineAxes", "Combine", {})
    ops: dict[str, object] = {"Master1": 1, "Master2": 3, "Slave": 2}
    ops.update(operands)
    trigger(s, c, **ops)
    assert c.outputs["Error"] and c.outputs["ErrorID"] == code
    assert s.ctl.axis(2).active() == []
