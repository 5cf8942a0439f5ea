"""MAG, Motion Axis Gear: status bits, ratio and direction, clutch, superposition, errors.

Numbers are from the MAG seed and from kinematics: a 0.5 ratio on a master at 100 units/s
means a slave gear velocity of 50 units/s; a clutch at 1000 units/s^2 reaches it after
50 / 1000 = 0.05 s = 25 cycles of 2 ms, travelling 50^2 / (2 x 1000) = 1.25 units.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    MotionStatusBit,
    PLCopenState,
    ProcessKind,
)

from ..support import make_system, trigger

DT = 0.002
GEARING = 1 << MotionStatusBit.GEARING
LOCK = 1 << MotionStatusBit.GEARING_LOCK


def system() -> MotionSystem:
    """1 virtual master, 2 and 3 servo slaves (max accel 2000), 4 a hand wheel,
    5 a rotary servo (360), 6 another servo."""
    servo = dict(max_velocity=1000.0, max_acceleration=2000.0, max_deceleration=2000.0)
    s = make_system(
        AxisConfig(1, "Master", AxisType.VIRTUAL, max_acceleration=1e5, max_deceleration=1e5),
        AxisConfig(2, "Slave", AxisType.SERVO, **servo),
        AxisConfig(3, "Other", AxisType.SERVO, **servo),
        AxisConfig(4, "Wheel", AxisType.FEEDBACK_ONLY, conversion_constant=100.0),
        AxisConfig(5, "Rotary", AxisType.SERVO, rollover=360.0, **servo),
        AxisConfig(6, "Third", AxisType.SERVO, **servo),
    )
    for n in (1, 2, 3, 5, 6):
        s.ctl.servo_on(s.ctl.axis(n))
    return s


def fire(s: MotionSystem, inst: Instruction, **operands: object) -> None:
    """One scan with the rung true (the rising edge), then the rung false again."""
    trigger(s, inst, **operands)
    inst.inputs[inst.TRIGGER] = False


def jog(s: MotionSystem, axis: int, speed: float, name: str = "") -> Instruction:
    """Run ``axis`` up to ``speed`` (accel 1e5: 0.05 s at most) and hold it there."""
    j = s.add("MAJ", name or f"Jog{axis}_{len(s.instances)}", {"Axis": axis})
    direction = 1 if speed < 0 else 0
    fire(s, j, Speed=abs(speed), Direction=direction, AccelRate=1e5, DecelRate=1e5)
    s.cycle(30)
    assert s.ctl.axis(axis).command_velocity == pytest.approx(speed, abs=1e-9)
    return j


def mag(s: MotionSystem, name: str = "MAG", **operands: object) -> Instruction:
    defaults: dict[str, object] = {"SlaveAxis": 2, "MasterAxis": 1, "Clutch": 1}
    defaults.update(operands)
    inst = s.add("MAG", name, {})
    fire(s, inst, **defaults)
    return inst


def cmd(s: MotionSystem, axis: int) -> float:
    return s.ctl.axis(axis).command_position_unwound


def trace(s: MotionSystem, axis: int, cycles: int) -> np.ndarray:
    out = np.empty(cycles)
    for k in range(cycles):
        s.cycle()
        out[k] = cmd(s, axis)
    return out


# -- status bits --------------------------------------------------------------------------


def test_dn_and_ip_are_set_in_the_same_scan_and_ip_stays() -> None:
    s = system()
    g = mag(s, Ratio=0.5)
    out = g.outputs
    assert (out["EN"], out["DN"], out["IP"], out["ER"], out["PC"]) == (
        True,
        True,
        True,
        False,
        False,
    )
    assert out["FLAGS"] == (1 << 31) | (1 << 29) | (1 << 26)
    slave = s.ctl.axis(2)
    assert slave.motion_status & GEARING and slave.motion_status & LOCK
    assert slave.plcopen_state == PLCopenState.SYNCHRONIZED_MOTION
    s.cycle()  # rung false: EN clears (DN is set), DN and IP stay
    assert (out["EN"], out["DN"], out["IP"]) == (False, True, True)
    s.cycle(500)
    assert out["IP"] and out["DN"] and not out["ER"]


def test_without_clutch_the_slave_locks_at_once_with_a_velocity_step() -> None:
    s = system()
    jog(s, 1, 100.0)
    m0 = cmd(s, 1)
    g = mag(s, Ratio=0.5)
    slave = s.ctl.axis(2)
    # one scan: the slave's velocity stepped from 0 to 0.5 x 100, as the seed warns
    assert slave.command_velocity == pytest.approx(50.0)
    assert g.outputs["IP"] and slave.motion_status & LOCK
    for _ in range(200):
        s.cycle()
        assert cmd(s, 2) == pytest.approx(0.5 * (cmd(s, 1) - m0), abs=1e-12)


# -- clutch -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("rate", "units"),
    [(1000.0, 0), (50.0, 1)],  # 1000 units/s^2, or 50 % of the slave's 2000
    ids=["units_per_s2", "percent_of_maximum"],
)
def test_clutch_ramps_at_accel_rate_then_locks_when_speeds_match(rate: float, units: int) -> None:
    s = system()
    jog(s, 1, 100.0)
    slave = s.ctl.axis(2)
    before = [cmd(s, 2), cmd(s, 2)]
    g = s.add("MAG", "MAG", {})
    velocities, locked = [], []
    positions = list(before)
    fire(s, g, SlaveAxis=2, MasterAxis=1, Ratio=0.5, Clutch=0, AccelRate=rate, AccelUnits=units)
    for _ in range(60):
        velocities.append(slave.command_velocity)
        locked.append(bool(slave.motion_status & LOCK))
        positions.append(cmd(s, 2))
        s.cycle()
    accel = 1000.0
    # trapezoidal: v_k = accel x k x dt until the gear speed 50 is reached at cycle 25
    lock_cycle = math.ceil(50.0 / (accel * DT))
    first_lock = locked.index(True) + 1
    assert first_lock in (lock_cycle, lock_cycle + 1)
    assert not any(locked[: first_lock - 1]) and all(locked[first_lock - 1 :])
    for k in range(1, first_lock):
        assert velocities[k - 1] == pytest.approx(accel * k * DT, abs=1e-9)
    assert velocities[first_lock - 1] == pytest.approx(50.0)
    # finite differences of the sampled command position: |a| <= AccelRate
    p = np.array(positions)
    a = np.diff(p, 2) / DT**2
    assert np.max(np.abs(a)) <= accel * (1 + 1e-6)
    # distance covered while clutching: v^2 / (2 a) = 1.25
    assert g.outputs["IP"]


def test_the_status_arrays_show_the_clutch_locking_in_the_cycle_it_locks() -> None:
    """What a front-end publishes (``Controller.status_arrays``) shows GearingLockStatus
    from the cycle the clutch reaches the gear speed: 50 / (1000 x 0.002) = 25 cycles, the
    same cycle as the axis property (the slave is composed in Python, a group of 6)."""
    s = system()
    jog(s, 1, 100.0)
    ctl = s.ctl
    g = s.add("MAG", "MAG", {})
    fire(s, g, SlaveAxis=2, MasterAxis=1, Ratio=0.5, Clutch=0, AccelRate=1000.0, AccelUnits=0)
    locked = []  # after 1, 2, ... steps of the gear (the first ran in the scan of the edge)
    for _ in range(40):
        word = int(ctl.status_arrays().motion_status[1])
        assert word == ctl.axis(2).motion_status
        locked.append(bool(word & LOCK))
        s.cycle()
    first_lock = locked.index(True) + 1
    assert first_lock in (25, 26) and all(locked[first_lock - 1 :])


def test_clutch_merges_a_ratio_change_on_the_fly() -> None:
    s = system()
    jog(s, 1, 100.0)
    old = mag(s, "Old", Ratio=0.5)
    s.cycle(5)
    slave = s.ctl.axis(2)
    # locked at 50 units/s before: 0.1 units per cycle
    positions = [cmd(s, 2) - 0.2, cmd(s, 2) - 0.1, cmd(s, 2)]
    new = mag(s, "New", Ratio=1.5, Clutch=0, AccelRate=1000.0, AccelUnits=0)
    assert not old.outputs["IP"] and new.outputs["IP"]
    positions.append(cmd(s, 2))
    positions += list(trace(s, 2, 80))
    a = np.diff(np.array(positions), 2) / DT**2
    assert np.max(np.abs(a)) <= 1000.0 * (1 + 1e-6)
    assert slave.command_velocity == pytest.approx(150.0)
    assert slave.motion_status & LOCK


# -- ratio and direction ------------------------------------------------------------------


def gear_velocity(s: MotionSystem, **operands: object) -> float:
    mag(s, f"MAG{len(s.instances)}", **operands)
    s.cycle()
    return s.ctl.axis(2).command_velocity


def test_direction_same_opposite_reverse_unchanged_and_ratio_sign() -> None:
    s = system()
    jog(s, 1, 100.0)
    # never geared: Reverse reverses "Same"
    assert gear_velocity(s, Ratio=0.25, Direction=2) == pytest.approx(-25.0)
    assert gear_velocity(s, Ratio=0.25, Direction=0) == pytest.approx(25.0)
    assert gear_velocity(s, Ratio=0.5, Direction=3) == pytest.approx(50.0)  # unchanged
    assert gear_velocity(s, Ratio=0.5, Direction=2) == pytest.approx(-50.0)  # reverse
    assert gear_velocity(s, Ratio=2.0, Direction=3) == pytest.approx(-200.0)  # keeps opposite
    assert gear_velocity(s, Ratio=1.0, Direction=1) == pytest.approx(-100.0)  # opposite
    # a negative Ratio inverts whatever Direction selects ...
    assert gear_velocity(s, Ratio=-1.0, Direction=0) == pytest.approx(-100.0)
    assert gear_velocity(s, Ratio=-1.0, Direction=1) == pytest.approx(100.0)
    # ... and is not remembered as the direction: Unchanged keeps the last Direction
    assert gear_velocity(s, Ratio=1.0, Direction=3) == pytest.approx(-100.0)


def test_reverse_is_relative_to_the_previous_gearing_after_a_stop() -> None:
    s = system()
    jog(s, 1, 100.0)
    assert gear_velocity(s, Ratio=1.0, Direction=1) == pytest.approx(-100.0)
    stop = s.add("MAS", "Stop", {})
    fire(s, stop, Axis=2, StopType=3)
    s.cycle(100)
    assert s.ctl.axis(2).active(ProcessKind.GEAR) == []
    assert gear_velocity(s, Ratio=1.0, Direction=2) == pytest.approx(100.0)


def test_real_ratio_limits_from_the_seed() -> None:
    s = system()
    for name, ratio in [("lo", 0.00001), ("lo32", float(np.float32(0.00001))), ("hi", 9.99999)]:
        g = mag(s, name, Ratio=ratio)
        assert g.outputs["DN"] and not g.outputs["ER"], name
    g = mag(s, "neg", Ratio=-9.99999)
    assert g.outputs["DN"]
    for k, ratio in enumerate([0.0, 10.0, -10.0, 0.000004, math.nan, math.inf]):
        g = mag(s, f"bad{k}", Ratio=ratio)
        assert g.outputs["ER"] and g.outputs["ERR"] == 13 and g.outputs["EXERR"] == 4, ratio
        assert not g.outputs["DN"] and not g.outputs["IP"]


def test_fraction_ratio_uses_counts_not_units() -> None:
    s = system()
    # the hand wheel has 100 counts per unit, the slave 1000: 3 slave counts per master
    # count, and 2.5 wheel units = 250 counts, make 750 slave counts (0.75 units)
    wheel = s.ctl.axis(4)
    s.ctl.set_feedback_input(wheel, 1.0)
    s.cycle()
    mag(s, MasterAxis=4, RatioFormat=1, SlaveCounts=3, MasterCounts=1, MasterReference=0)
    s.ctl.set_feedback_input(wheel, 3.5)  # +250 master counts
    s.cycle()
    assert round(cmd(s, 2) * 1000) == 750


# -- superposition ------------------------------------------------------------------------


def test_incremental_move_on_a_geared_slave_shifts_the_phase_exactly() -> None:
    s = system()
    jog(s, 1, 100.0)
    g = mag(s, Ratio=1.0)
    s.cycle(3)
    phase0 = cmd(s, 2) - cmd(s, 1)
    mam = s.add("MAM", "Phase", {})
    fire(s, mam, Axis=2, MoveType=1, Position=5.0, Speed=50.0, AccelRate=1000.0, DecelRate=1000.0)
    slave = s.ctl.axis(2)
    assert slave.motion_status & (1 << MotionStatusBit.MOVE) and slave.motion_status & GEARING
    s.cycle(200)  # 5 units at 50 units/s with 0.05 s ramps: 0.15 s = 75 cycles
    assert mam.outputs["PC"] and g.outputs["IP"]
    assert cmd(s, 2) - cmd(s, 1) == pytest.approx(phase0 + 5.0, abs=1e-9)
    assert slave.command_velocity == pytest.approx(100.0)


def test_jog_adds_its_velocity_and_the_clutch_leaves_it_alone() -> None:
    s = system()
    jog(s, 1, 100.0)
    jog(s, 2, 20.0, "SlaveJog")
    g = mag(s, Ratio=0.5, Clutch=0, AccelRate=1000.0, AccelUnits=0)
    s.cycle(40)
    slave = s.ctl.axis(2)
    assert slave.command_velocity == pytest.approx(20.0 + 50.0)
    assert slave.motion_status & (1 << MotionStatusBit.JOG) and slave.motion_status & LOCK
    assert g.outputs["IP"]


# -- ending the gear ----------------------------------------------------------------------


@pytest.mark.parametrize("stop_type", [0, 3], ids=["all", "gear"])
def test_mas_all_or_gear_stops_gearing_and_clears_ip(stop_type: int) -> None:
    s = system()
    jog(s, 1, 100.0)
    g = mag(s, Ratio=0.5)
    s.cycle(5)
    stop = s.add("MAS", "Stop", {})
    fire(s, stop, Axis=2, StopType=stop_type)
    assert not g.outputs["IP"] and g.outputs["DN"]
    slave = s.ctl.axis(2)
    assert not slave.motion_status & GEARING
    # max deceleration 2000: 50 units/s to rest in 25 cycles
    s.cycle(24)
    assert slave.command_velocity == pytest.approx(0.0, abs=1e-9)
    s.cycle(2)
    assert stop.outputs["PC"]


def test_mas_jog_leaves_the_gear_running() -> None:
    s = system()
    jog(s, 1, 100.0)
    jog(s, 2, 10.0, "SlaveJog")
    g = mag(s, Ratio=0.5)
    stop = s.add("MAS", "Stop", {})
    fire(s, stop, Axis=2, StopType=1)
    s.cycle(50)
    assert g.outputs["IP"]
    assert s.ctl.axis(2).command_velocity == pytest.approx(50.0)


def test_a_new_mag_supersedes_and_may_change_the_master() -> None:
    s = system()
    jog(s, 1, 100.0)
    jog(s, 3, -40.0)
    first = mag(s, "First", Ratio=0.5)
    second = mag(s, "Second", MasterAxis=3, Ratio=0.5)
    assert not first.outputs["IP"] and first.outputs["DN"]
    assert second.outputs["IP"]
    s.cycle(3)
    assert s.ctl.axis(2).command_velocity == pytest.approx(-20.0)
    gears = s.ctl.axis(2).active(ProcessKind.GEAR)
    assert len(gears) == 1 and gears[0].masters == (3,)


def test_merge_shutdown_and_fault_clear_ip() -> None:
    s = system()
    jog(s, 1, 100.0)
    g = mag(s, "A", Ratio=0.5)
    merge = s.add("MAJ", "Merge", {})
    fire(s, merge, Axis=2, Speed=5.0, Merge=1, AccelRate=1000.0, DecelRate=1000.0)
    assert not g.outputs["IP"]
    g = mag(s, "B", Ratio=0.5)
    s.ctl.shutdown(s.ctl.axis(2))
    s.cycle()
    assert not g.outputs["IP"]
    s.ctl.shutdown_reset(s.ctl.axis(2))
    s.ctl.servo_on(s.ctl.axis(2))
    g = mag(s, "C", Ratio=0.5)
    assert g.outputs["IP"]
    s.ctl.fault(s.ctl.axis(2), 1)
    s.cycle()
    assert not g.outputs["IP"]


# -- rotary slaves and master references --------------------------------------------------


def test_rotary_slave_gears_on_unwound_positions() -> None:
    s = system()
    jog(s, 1, 500.0)
    m0, s0 = cmd(s, 1), cmd(s, 5)
    mag(s, SlaveAxis=5, Ratio=1.0)
    s.cycle(2000)  # 4 s at 500 units/s: 2000 degrees, several turns
    travel = cmd(s, 1) - m0
    assert travel > 1800.0
    rotary = s.ctl.axis(5)
    assert rotary.command_position_unwound - s0 == pytest.approx(travel, abs=1e-9)
    assert rotary.command_position == pytest.approx((s0 + travel) % 360.0, abs=1e-9)


def test_master_reference_command_reads_this_cycle_actual_the_previous_drive_output() -> None:
    s = system()
    jog(s, 3, 80.0)  # a servo master: its actual lags its command
    master = s.ctl.axis(3)
    c_lock, s2_before = master.command_position_unwound, cmd(s, 2)
    by_cmd = mag(s, "ByCommand", SlaveAxis=2, MasterAxis=3, Ratio=0.5, MasterReference=1)
    a_lock, s6_before = master.actual_position_unwound, cmd(s, 6)
    a_prev = a_lock
    by_act = mag(s, "ByActual", SlaveAxis=6, MasterAxis=3, Ratio=0.5, MasterReference=0)
    assert by_cmd.outputs["IP"] and by_act.outputs["IP"]
    for _ in range(50):
        # command: this cycle's master command (the master composes first)
        assert cmd(s, 2) - s2_before == pytest.approx(
            0.5 * (master.command_position_unwound - c_lock), abs=1e-12
        )
        # actual: the feedback at the start of the cycle = last cycle's drive output
        assert cmd(s, 6) - s6_before == pytest.approx(0.5 * (a_prev - a_lock), abs=1e-12)
        a_prev = master.actual_position_unwound
        s.cycle()
    # the two references really differ: the servo master lags its command
    assert abs(master.command_position_unwound - master.actual_position_unwound) > 0.1


# -- errors -------------------------------------------------------------------------------


def assert_no_motion(s: MotionSystem, axis: int) -> None:
    ax = s.ctl.axis(axis)
    p = cmd(s, axis)
    s.cycle(20)
    assert cmd(s, axis) == p and ax.active(ProcessKind.GEAR) == []


def test_errors_state_and_axis_type() -> None:
    s = system()
    jog(s, 1, 100.0)
    s.ctl.servo_off(s.ctl.axis(2))
    s.cycle(200)  # let it coast to rest
    g = mag(s, "off")
    assert g.outputs["ER"] and g.outputs["ERR"] == 5 and not g.outputs["IP"]
    assert_no_motion(s, 2)
    g = mag(s, "fb", SlaveAxis=4)
    assert g.outputs["ERR"] == 8
    g = mag(s, "fbcmd", SlaveAxis=3, MasterAxis=4, MasterReference=1)
    assert g.outputs["ERR"] == 8
    assert_no_motion(s, 3)
    g = mag(s, "fbact", SlaveAxis=3, MasterAxis=4, MasterReference=0)
    assert g.outputs["DN"] and not g.outputs["ER"]
    s.ctl.shutdown(s.ctl.axis(6))
    g = mag(s, "sd", SlaveAxis=6)
    assert g.outputs["ERR"] == 7
    g = mag(s, "nax", SlaveAxis=99)
    assert g.outputs["ERR"] == 11


def test_cross_coupling_is_refused_with_err_10() -> None:
    s = system()
    assert mag(s, "a", SlaveAxis=2, MasterAxis=3).outputs["IP"]
    g = mag(s, "b", SlaveAxis=3, MasterAxis=2)  # A follows B, B would follow A
    assert g.outputs["ER"] and g.outputs["ERR"] == 10
    assert mag(s, "c", SlaveAxis=3, MasterAxis=6).outputs["IP"]
    g = mag(s, "d", SlaveAxis=6, MasterAxis=2)  # 2 <- 3 <- 6 <- 2: a longer loop
    assert g.outputs["ERR"] == 10
    g = mag(s, "e", SlaveAxis=2, MasterAxis=2)  # its own master
    assert g.outputs["ERR"] == 10
    assert s.ctl.axis(6).active(ProcessKind.GEAR) == []


@pytest.mark.parametrize(
    ("operands", "exerr"),
    [
        ({"Direction": 4}, 3),
        ({"Ratio": 12.0}, 4),
        ({"RatioFormat": 1, "SlaveCounts": 0}, 5),
        ({"RatioFormat": 1, "MasterCounts": 0}, 6),
        ({"MasterReference": 2}, 7),
        ({"RatioFormat": 2}, 8),
        ({"Clutch": 2}, 9),
        ({"Clutch": 0, "AccelRate": 0.0}, 10),
        ({"Clutch": 0, "AccelRate": -5.0, "AccelUnits": 1}, 10),
        # AccelUnits counts with the clutch only (issue 16: operands a mode does not use
        # are not judged); without it the same value is accepted (test below)
        ({"Clutch": 0, "AccelUnits": 3}, 11),
    ],
)
def test_operands_out_of_range_give_err_13_with_exerr(
    operands: dict[str, object], exerr: int
) -> None:
    s = system()
    jog(s, 1, 100.0)
    g = mag(s, **operands)
    assert g.outputs["ER"] and g.outputs["ERR"] == 13 and g.outputs["EXERR"] == exerr
    assert not g.outputs["DN"] and not g.outputs["IP"]
    assert_no_motion(s, 2)


def test_clutch_operands_are_not_judged_without_the_clutch() -> None:
    """Issue 16: an operand the mode does not use is not judged. Without the clutch the
    gear locks at once and neither AccelRate nor AccelUnits is looked at."""
    s = system()
    jog(s, 1, 100.0)
    g = mag(s, Clutch=1, AccelRate=-5.0, AccelUnits=3)
    assert g.outputs["DN"] and g.outputs["IP"] and not g.outputs["ER"]
    s.cycle()
    assert s.ctl.axis(2).command_velocity == pytest.approx(100.0, abs=1e-9)


def test_an_error_leaves_the_running_gear_alone() -> None:
    s = system()
    jog(s, 1, 100.0)
    good = mag(s, "good", Ratio=0.5)
    bad = mag(s, "bad", Ratio=20.0)
    assert bad.outputs["ER"] and good.outputs["IP"]
    s.cycle()
    assert s.ctl.axis(2).command_velocity == pytest.approx(50.0)


def test_clutch_disabled_ignores_accel_rate() -> None:
    s = system()
    g = mag(s, Clutch=1, AccelRate=0.0)
    assert g.outputs["DN"] and g.outputs["IP"]
