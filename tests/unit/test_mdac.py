"""MDAC and master-driven MAJ/MAM: speed per master unit, changing the master, the 5 %
rule, and the runtime errors.

Virtual axes (command = actual), dt = 2 ms. Master A (axis 1) jogs at 100 mm/s, master
B (axis 2) at 80 mm/s; the slave (axis 3) runs master-driven with acceleration and
deceleration 0.05 mm per master mm² (AccelUnits = DecelUnits = 4). First principles:

- a jog at 0.5 mm per master mm from rest reaches its ratio after 0.5 / 0.05 = 10 mm of
  master travel (50 cycles of master A), having moved 0.5² / (2 * 0.05) = 2.5 mm; then the
  slave moves 0.5 mm per master mm: 50 mm/s behind A's 100 mm/s;
- switched to B at 1.0 mm per master mm, it inherits 50 mm/s = 0.625 mm per B mm and
  needs (1 - 0.625) / 0.05 = 7.5 mm of B's travel (46.875 cycles at 0.16 mm per cycle)
  to track B at 80 mm/s;
- the 5 % rule on a slave at 50 mm/s: the new speed must be at least 2.5 mm/s, so with B
  at 80 mm/s at least 2.5 / 80 = 0.03125 mm per master mm.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_server.instructions import Instruction, LogixInstruction, MotionSystem
from motion_server.kernel import AxisConfig, AxisType, ErrorCode

from ..support import make_system, trigger

DT = 0.002
VA = 100.0
VB = 80.0
MD_ACCEL = 0.05
MASTER_UNITS = 4


def logix(inst: Instruction) -> LogixInstruction:
    assert isinstance(inst, LogixInstruction)
    return inst


def virtual(number: int) -> AxisConfig:
    return AxisConfig(
        number,
        f"Axis{number}",
        AxisType.VIRTUAL,
        max_velocity=1000.0,
        max_acceleration=10000.0,
        max_deceleration=1000.0,
    )


def md_dynamics(speed: float) -> dict[str, float]:
    return {
        "Speed": speed,
        "SpeedUnits": MASTER_UNITS,
        "AccelRate": MD_ACCEL,
        "AccelUnits": MASTER_UNITS,
        "DecelRate": MD_ACCEL,
        "DecelUnits": MASTER_UNITS,
    }


def setup(b_speed: float = VB) -> MotionSystem:
    """Masters A (1) and B (2) jogging at VA and ``b_speed``; the slave (3) at rest."""
    system = make_system(virtual(1), virtual(2), virtual(3), period=DT)
    for n in (1, 2, 3):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
    for n, speed in ((1, VA), (2, b_speed)):
        if speed:
            jog = system.add("MAJ", f"JOG_{n}", {"Axis": n, "Speed": speed, "AccelRate": 1e4})
            trigger(system, jog)
    system.cycle(10)
    return system


def mdac(system: MotionSystem, name: str, master: int, motion_type: int = 0) -> LogixInstruction:
    inst = logix(
        system.add(
            "MDAC",
            name,
            {"SlaveAxis": 3, "MasterAxis": master, "MotionType": motion_type, "MasterReference": 1},
        )
    )
    trigger(system, inst)
    return inst


def md_jog(system: MotionSystem, name: str, speed: float, **extra: float) -> LogixInstruction:
    inst = logix(system.add("MAJ", name, {"Axis": 3, **md_dynamics(speed), **extra}))
    trigger(system, inst)
    return inst


def positions(system: MotionSystem, cycles: int) -> np.ndarray:
    """Command positions of axes 1..3 before and after each of ``cycles`` cycles."""
    out = np.empty((cycles + 1, 3))
    for k in range(cycles + 1):
        if k:
            system.cycle()
        out[k] = [system.ctl.axis(n).command_position_unwound for n in (1, 2, 3)]
    return out


def following_a(system: MotionSystem) -> tuple[LogixInstruction, LogixInstruction]:
    """The slave tracking master A at 0.5 mm per mm (50 mm/s)."""
    m1 = mdac(system, "MDAC_1", master=1)
    j1 = md_jog(system, "MAJ_1", 0.5)
    system.cycle(60)
    assert j1.outputs["TrackingMaster"]
    assert system.ctl.axis(3).command_velocity == pytest.approx(50.0, abs=1e-9)
    return m1, j1


def test_master_driven_jog_speed_is_programmed_speed_times_master_speed() -> None:
    system = setup()
    m1 = mdac(system, "MDAC_1", master=1)
    assert m1.bit("DN") and m1.bit("IP") and not m1.bit("AC")
    slave = system.ctl.axis(3)
    start = slave.command_position_unwound
    j1 = md_jog(system, "MAJ_1", 0.5)
    assert j1.bit("IP") and m1.bit("AC") and not j1.outputs["TrackingMaster"]
    system.cycle(48)
    assert not j1.outputs["TrackingMaster"]  # 49 cycles: 9.8 mm of master travel
    system.cycle()
    assert j1.outputs["TrackingMaster"]  # 50 cycles: 10 mm, the ratio is reached
    assert slave.command_position_unwound - start == pytest.approx(2.5, abs=1e-9)
    trace = positions(system, 20)
    np.testing.assert_allclose(np.diff(trace[:, 2]), 0.5 * np.diff(trace[:, 0]), atol=1e-9)
    assert slave.command_velocity == pytest.approx(0.5 * VA, abs=1e-9)
    # the master speeds up to 200 mm/s: the slave follows at half its speed, every cycle
    faster = system.add("MAJ", "JOG_1b", {"Axis": 1, "Speed": 200.0, "AccelRate": 1e4})
    trigger(system, faster)
    trace = positions(system, 20)
    np.testing.assert_allclose(np.diff(trace[:, 2]), 0.5 * np.diff(trace[:, 0]), atol=1e-9)
    assert system.ctl.axis(1).command_velocity == pytest.approx(200.0)
    assert slave.command_velocity == pytest.approx(100.0, abs=1e-9)
    assert j1.outputs["TrackingMaster"] and j1.bit("IP")


def test_a_master_moving_in_reverse_holds_the_slave() -> None:
    """Lock direction: immediate, forward only."""
    system = setup()
    mdac(system, "MDAC_1", master=1)
    md_jog(system, "MAJ_1", 0.5)
    system.cycle(60)
    back = system.add(
        "MAJ", "JOG_1r", {"Axis": 1, "Direction": 1, "Speed": 100.0, "AccelRate": 1e4}
    )
    trigger(system, back)
    system.cycle(20)  # the master has reversed (100 mm/s to -100 mm/s in 20 ms)
    assert system.ctl.axis(1).command_velocity == pytest.approx(-100.0)
    trace = positions(system, 10)
    assert np.all(np.diff(trace[:, 0]) < 0.0)
    np.testing.assert_array_equal(np.diff(trace[:, 2]), 0.0)
    assert system.ctl.axis(3).command_velocity == 0.0


def test_master_driven_move_covers_its_distance_over_master_travel() -> None:
    """10 mm at 0.5 mm per master mm, 0.05 mm/mm² both ways: 10 + 10 + 10 mm of master
    travel (ramp, cruise 5 mm of slave at 0.5, ramp) = 30 mm = 150 cycles of A; while
    the master stands still the move waits."""
    system = setup()
    mdac(system, "MDAC_1", master=1)
    slave = system.ctl.axis(3)
    master = system.ctl.axis(1)
    start = slave.command_position_unwound
    m_start = master.command_position_unwound
    mam = logix(
        system.add("MAM", "MAM_1", {"Axis": 3, "MoveType": 1, "Position": 10.0, **md_dynamics(0.5)})
    )
    trigger(system, mam)
    system.cycle(73)  # 74 cycles: 14.8 mm of master travel, cruising
    assert mam.outputs["TrackingMaster"]
    assert slave.command_position_unwound - start == pytest.approx(2.5 + 0.5 * 4.8, abs=1e-9)
    # stop the master in 5 cycles (1e4 mm/s^2): the move pauses with it
    stop = system.add(
        "MAS", "MAS_1", {"Axis": 1, "StopType": 0, "ChangeDecel": 1, "DecelRate": 1e4}
    )
    trigger(system, stop)
    system.cycle(10)
    assert master.command_velocity == 0.0
    paused = slave.command_position_unwound
    system.cycle(50)
    assert slave.command_position_unwound == paused and mam.bit("IP")
    # the master resumes; the move ends once the master has travelled 30 mm in all
    jog = system.add("MAJ", "JOG_1c", {"Axis": 1, "Speed": VA, "AccelRate": 1e4})
    trigger(system, jog)
    while mam.bit("IP"):
        system.cycle()
    assert mam.bit("PC") and not mam.bit("ER")
    assert slave.command_position_unwound - start == pytest.approx(10.0, abs=1e-9)
    travel = master.command_position_unwound - m_start
    assert 30.0 - 1e-9 <= travel < 30.0 + VA * DT


def test_changing_the_master_is_pending_until_the_next_motion_instruction() -> None:
    system = setup()
    m1, j1 = following_a(system)
    slave = system.ctl.axis(3)
    m2 = mdac(system, "MDAC_2", master=2)
    # pending: both MDACs in process, only the first one active; still following A
    assert m2.bit("DN") and m2.bit("IP") and not m2.bit("AC")
    assert m1.bit("IP") and m1.bit("AC") and j1.bit("IP")
    trace = positions(system, 10)
    np.testing.assert_allclose(np.diff(trace[:, 2]), 0.5 * np.diff(trace[:, 0]), atol=1e-9)
    assert m2.bit("IP") and not m2.bit("AC") and m1.bit("AC")
    # the next master-driven MAJ goes IP: the slave switches to B in that cycle
    j2 = md_jog(system, "MAJ_2", 1.0)
    assert j2.bit("IP") and not j2.bit("ER")
    assert not j1.bit("IP")
    assert not m1.bit("IP") and not m1.bit("AC")
    assert m2.bit("IP") and m2.bit("AC")
    assert not j2.outputs["TrackingMaster"]
    # no jump: 0.625 mm per B mm inherited, plus one cycle of 0.05 * 0.16 mm
    assert slave.command_velocity == pytest.approx((0.625 + 0.05 * 0.16) * VB, abs=1e-9)
    system.cycle(45)
    assert not j2.outputs["TrackingMaster"]  # 46 cycles: 7.36 mm of B's travel
    system.cycle()
    assert j2.outputs["TrackingMaster"]  # 47 cycles: 7.52 mm >= 7.5 mm
    trace = positions(system, 10)
    np.testing.assert_allclose(np.diff(trace[:, 2]), 1.0 * np.diff(trace[:, 1]), atol=1e-9)
    assert slave.command_velocity == pytest.approx(VB, abs=1e-9)


def test_a_time_driven_instruction_also_switches_a_pending_master() -> None:
    system = setup()
    m1, _ = following_a(system)
    m2 = mdac(system, "MDAC_2", master=2)
    mam = logix(system.add("MAM", "MAM_t", {"Axis": 3, "MoveType": 1, "Position": 1.0}))
    trigger(system, mam)
    assert mam.bit("IP")
    assert not m1.bit("IP") and m2.bit("IP") and m2.bit("AC")
    # the master-driven jog follows B from this scan on (logix-MDAC: the axis is
    # reassigned when the new instruction goes IP): it keeps its 50 mm/s, i.e. 0.625 mm
    # per B mm, and ramps back to its 0.5 mm per mm over (0.625 - 0.5) / 0.05 = 2.5 mm of
    # B's travel; A stopping changes nothing any more
    stop_a = logix(system.add("MAS", "MAS_A", {"Axis": 1}))
    trigger(system, stop_a)
    system.cycle(200)  # A at rest, the 1 mm move long done (0.2 s at 100 mm/s^2)
    assert system.ctl.axis(1).command_velocity == 0.0 and mam.bit("PC")
    trace = positions(system, 10)
    np.testing.assert_allclose(np.diff(trace[:, 2]), 0.5 * np.diff(trace[:, 1]), atol=1e-9)


def test_all_master_driven_motion_follows_the_new_master() -> None:
    """A master-driven jog (0.5 mm per mm) and move (0.25 mm per mm) superimposed: 75 mm/s
    on A. The change to B by a new jog moves the running move to B too. Each keeps its
    velocity and ramps (0.05 mm per mm²) to its programmed speed in B's travel: the jog
    from 50 / 80 = 0.625, the move from 25 / 80 = 0.3125; then (0.5 + 0.25) · 80 = 60 mm/s
    (it would be 0.5 · 80 + 0.25 · 100 = 65 on the old master)."""
    system = setup()
    m1, _ = following_a(system)
    mam = logix(
        system.add(
            "MAM", "MAM_md", {"Axis": 3, "MoveType": 1, "Position": 1e6, **md_dynamics(0.25)}
        )
    )
    trigger(system, mam)
    system.cycle(60)
    slave = system.ctl.axis(3)
    assert slave.command_velocity == pytest.approx(75.0, abs=1e-9)
    m2 = mdac(system, "MDAC_2", master=2)
    j2 = md_jog(system, "MAJ_2", 0.5)
    assert j2.bit("IP") and mam.bit("IP") and m2.bit("AC") and not m1.bit("IP")
    # in that scan: 0.625 and 0.3125 mm per B mm, each plus one cycle's ramp of
    # 0.05 · 0.16 mm the other way (both slow down toward their speed)
    assert slave.command_velocity == pytest.approx(
        (0.625 - 0.05 * 0.16 + 0.3125 - 0.05 * 0.16) * VB, abs=1e-9
    )
    stop_a = logix(system.add("MAS", "MAS_A", {"Axis": 1}))
    trigger(system, stop_a)
    system.cycle(100)
    assert system.ctl.axis(1).command_velocity == 0.0
    trace = positions(system, 10)
    np.testing.assert_allclose(np.diff(trace[:, 2]), 0.75 * np.diff(trace[:, 1]), atol=1e-9)
    assert slave.command_velocity == pytest.approx(0.75 * VB, abs=1e-9)


def test_a_time_driven_switch_to_an_idle_master_is_refused_while_the_slave_moves() -> None:
    """The master-driven jog that would follow B is moving and B is idle: ERR 97 for the
    instruction making the request (logix-MDAC), nothing changes."""
    system = setup(b_speed=0.0)
    m1, j1 = following_a(system)
    m2 = mdac(system, "MDAC_2", master=2)
    mam = logix(system.add("MAM", "MAM_t", {"Axis": 3, "MoveType": 1, "Position": 1.0}))
    trigger(system, mam)
    assert mam.bit("ER") and mam.outputs["ERR"] == ErrorCode.MDSC_IDLE_MASTER_AND_SLAVE_MOVING
    assert j1.bit("IP") and m1.bit("AC") and m2.bit("IP") and not m2.bit("AC")
    system.cycle(5)
    assert system.ctl.axis(3).command_velocity == pytest.approx(50.0, abs=1e-9)


@pytest.mark.parametrize(
    ("speed", "error"),
    [
        (0.03, ErrorCode.MDSC_INVALID_SLAVE_SPEED_REDUCTION),  # 2.4 mm/s < 2.5 mm/s
        (0.032, ErrorCode.NONE),  # 2.56 mm/s >= 2.5 mm/s
        (0.03125, ErrorCode.NONE),  # exactly 5 %
    ],
)
def test_five_percent_rule(speed: float, error: ErrorCode) -> None:
    system = setup()
    m1, j1 = following_a(system)
    m2 = mdac(system, "MDAC_2", master=2)
    slave = system.ctl.axis(3)
    j2 = md_jog(system, "MAJ_2", speed)
    if error:
        assert j2.bit("ER") and j2.outputs["ERR"] == error and not j2.bit("IP")
        # refused: still following A at 50 mm/s, the reassignment still pending
        assert j1.bit("IP") and m1.bit("IP") and m1.bit("AC")
        assert m2.bit("IP") and not m2.bit("AC")
        assert slave.command_velocity == pytest.approx(50.0, abs=1e-9)
    else:
        assert j2.bit("IP") and not j2.bit("ER")
        assert not m1.bit("IP") and m2.bit("AC")


def test_an_idle_second_master_while_the_slave_moves_is_refused() -> None:
    system = setup(b_speed=0.0)
    m1, j1 = following_a(system)
    m2 = mdac(system, "MDAC_2", master=2)
    j2 = md_jog(system, "MAJ_2", 1.0)
    assert j2.bit("ER") and j2.outputs["ERR"] == ErrorCode.MDSC_IDLE_MASTER_AND_SLAVE_MOVING
    assert j1.bit("IP") and m1.bit("AC") and m2.bit("IP")
    assert system.ctl.axis(3).command_velocity == pytest.approx(50.0, abs=1e-9)
    # once B moves the same request goes through
    jog_b = system.add("MAJ", "JOG_2", {"Axis": 2, "Speed": VB, "AccelRate": 1e4})
    trigger(system, jog_b)
    system.cycle(10)
    j2.inputs["Execute"] = False
    system.cycle()
    trigger(system, j2)
    assert j2.bit("IP") and not j2.bit("ER") and m2.bit("AC") and not m1.bit("IP")


def test_an_idle_second_master_is_fine_while_the_slave_stands_still() -> None:
    system = setup(b_speed=0.0)
    mdac(system, "MDAC_1", master=1)
    m2 = mdac(system, "MDAC_2", master=2)
    j2 = md_jog(system, "MAJ_2", 1.0)
    assert j2.bit("IP") and m2.bit("AC")
    system.cycle(20)
    assert system.ctl.axis(3).command_velocity == 0.0  # B idle: the slave waits


def test_the_same_axis_as_master_and_slave_is_refused() -> None:
    system = setup()
    inst = logix(system.add("MDAC", "MDAC_1", {"SlaveAxis": 3, "MasterAxis": 3}))
    trigger(system, inst)
    # MasterAxis is the second operand of MDAC(SlaveAxis, MasterAxis, MotionControl, ...)
    assert inst.bit("ER") and inst.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert inst.outputs["EXERR"] == 1
    assert not inst.bit("IP") and system.ctl.mdsc.links(3) == []


def test_another_motion_type_while_an_mdac_all_is_active_is_a_runtime_error() -> None:
    system = setup()
    m1, j1 = following_a(system)
    for motion_type in (1, 2):
        bad = mdac(system, f"MDAC_type{motion_type}", master=2, motion_type=motion_type)
        assert bad.bit("ER") and bad.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
        assert not bad.bit("IP")
    assert m1.bit("IP") and m1.bit("AC") and j1.bit("IP")


def test_a_jog_assignment_changes_master_only_after_a_stop_breaks_it() -> None:
    system = setup()
    m1 = mdac(system, "MDAC_1", master=1, motion_type=1)
    md_jog(system, "MAJ_1", 0.5)
    system.cycle(5)
    again = mdac(system, "MDAC_2", master=2, motion_type=1)
    assert again.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
    # a Move assignment to another master is independent of the Jog one
    move = mdac(system, "MDAC_3", master=2, motion_type=2)
    assert move.bit("IP") and not move.bit("ER") and m1.bit("IP")
    mas = system.add("MAS", "MAS_3", {"Axis": 3, "StopType": 0})
    trigger(system, mas)
    assert not m1.bit("IP") and not move.bit("IP")
    retry = mdac(system, "MDAC_4", master=2, motion_type=1)
    assert retry.bit("IP") and not retry.bit("ER")


def test_dynamics_must_all_be_master_driven_or_all_time_driven() -> None:
    system = setup()
    mdac(system, "MDAC_1", master=1)
    slave = system.ctl.axis(3)
    for units in ({"AccelUnits": 0}, {"DecelUnits": 1}, {"SpeedUnits": 0}):
        inst = logix(system.add("MAJ", f"MAJ_{len(units)}{next(iter(units))}", {"Axis": 3}))
        trigger(system, inst, **{**md_dynamics(0.5), **units})
        assert (
            inst.bit("ER") and inst.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
        )
    # an S-curve also needs its jerk in master units (or % of time)
    jerk = logix(system.add("MAM", "MAM_j", {"Axis": 3, "MoveType": 1, "Position": 5.0}))
    trigger(system, jerk, **md_dynamics(0.5), Profile=1, JerkUnits=0, AccelJerk=1.0)
    assert jerk.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
    system.cycle(5)
    assert slave.command_velocity == 0.0 and slave.processes == []
    ok = logix(system.add("MAM", "MAM_ok", {"Axis": 3, "MoveType": 1, "Position": 5.0}))
    trigger(system, ok, **md_dynamics(0.5), Profile=1, JerkUnits=MASTER_UNITS, AccelJerk=0.1)
    assert ok.bit("IP") and not ok.bit("ER")


def test_master_units_need_an_mdac_first() -> None:
    system = setup()
    inst = md_jog(system, "MAJ_1", 0.5)
    assert inst.bit("ER") and inst.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
    assert system.ctl.axis(3).processes == []


def test_mdac_refuses_feedback_only_slaves_and_cross_coupling() -> None:
    system = make_system(
        virtual(1), virtual(2), AxisConfig(3, "Wheel", AxisType.FEEDBACK_ONLY), period=DT
    )
    wheel = logix(system.add("MDAC", "MDAC_w", {"SlaveAxis": 3, "MasterAxis": 1}))
    trigger(system, wheel)
    assert wheel.outputs["ERR"] == ErrorCode.WRONG_AXIS_TYPE
    first = logix(system.add("MDAC", "MDAC_1", {"SlaveAxis": 2, "MasterAxis": 1}))
    trigger(system, first)
    assert first.bit("IP")
    loop = logix(system.add("MDAC", "MDAC_2", {"SlaveAxis": 1, "MasterAxis": 2}))
    trigger(system, loop)
    assert loop.outputs["ERR"] == ErrorCode.MASTER_AXIS_CONFLICT
    # a feedback-only axis (a hand wheel) can be the master
    hand = logix(system.add("MDAC", "MDAC_3", {"SlaveAxis": 1, "MasterAxis": 3}))
    trigger(system, hand)
    assert hand.bit("IP") and not hand.bit("ER")


def test_a_new_master_reference_is_refused_while_the_slave_moves() -> None:
    system = setup()
    m1, j1 = following_a(system)
    actual = logix(
        system.add("MDAC", "MDAC_act", {"SlaveAxis": 3, "MasterAxis": 1, "MasterReference": 0})
    )
    trigger(system, actual)
    assert actual.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE
    assert m1.bit("IP") and m1.bit("AC") and j1.bit("IP")
    # at rest the reference may change: the new MDAC takes over the assignment at once
    mas = system.add("MAS", "MAS_j", {"Axis": 3, "StopType": 1, "ChangeDecel": 1, "DecelRate": 1e4})
    trigger(system, mas)
    system.cycle(20)
    assert system.ctl.axis(3).command_velocity == 0.0 and m1.bit("IP")
    actual.inputs["Execute"] = False
    system.cycle()
    trigger(system, actual)
    assert actual.bit("IP") and not actual.bit("ER") and not m1.bit("IP")
