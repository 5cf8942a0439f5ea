"""MRP and MC_SetPosition: a redefined position moves nothing.

MOTION-RM002 (MRP): "If Absolute is selected the Position value is assigned to the
current Actual or Command position. If Relative is selected the Position value is added
as a displacement ... The process of redefining the current axis position has no affect
on motion in progress as the instruction preserves the current servo following error".
So each test runs a twin system without the redefinition: afterwards every position
differs from the twin's by the shift alone, every velocity is the twin's.
"""

from __future__ import annotations

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisFault, AxisType, ErrorCode

from ..support import make_system, trigger

DT = 0.002


def plant() -> MotionSystem:
    """Axis1 servo (master), Axis2 servo (slave), Axis3 rotary servo, Axis4 hand wheel;
    MSO powers 1 to 3. ω = 2π · 40 rad/s: the following error at v is 2v/ω."""
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.SERVO),
        AxisConfig(2, "Axis2", AxisType.SERVO),
        AxisConfig(3, "Axis3", AxisType.SERVO, units="deg", rollover=360.0),
        AxisConfig(4, "Wheel", AxisType.FEEDBACK_ONLY),
    )
    for name in ("MSO", "MAJ", "MAM", "MAG", "MRP", "MASD", "MC_SetPosition", "MC_GearInPos"):
        system.add(name, f"{name}_1")
    for axis in (1, 2, 3):
        trigger(system, system["MSO_1"], Axis=axis)
        system["MSO_1"].inputs["Execute"] = False
        system.cycle()
    return system


def twins() -> tuple[MotionSystem, MotionSystem]:
    return plant(), plant()


def both(systems: tuple[MotionSystem, ...], name: str, **operands: object) -> None:
    """Pulse ``name`` in every system (rising edge, then low)."""
    for s in systems:
        inst = s[name]
        inst.inputs.update(operands)
        inst.inputs[inst.TRIGGER] = True
    for s in systems:
        s.cycle()
    for s in systems:
        s[name].inputs[s[name].TRIGGER] = False


def run(systems: tuple[MotionSystem, ...], cycles: int) -> None:
    for _ in range(cycles):
        for s in systems:
            s.cycle()


def assert_shifted(a: MotionSystem, b: MotionSystem, axis: int, d: float) -> None:
    """``a``'s axis reads ``b``'s plus ``d``, moving as ``b``'s does (to rounding: a
    drive state moved by ``d`` rounds differently in the last bits)."""
    xa, xb = a.ctl.axis(axis), b.ctl.axis(axis)
    assert xa.command_position_unwound == pytest.approx(xb.command_position_unwound + d, abs=1e-9)
    assert xa.actual_position_unwound == pytest.approx(xb.actual_position_unwound + d, abs=1e-9)
    assert xa.command_velocity == pytest.approx(xb.command_velocity, abs=1e-9)
    assert xa.actual_velocity == pytest.approx(xb.actual_velocity, abs=1e-9)


JOG = {"Speed": 100.0, "AccelRate": 1000.0, "DecelRate": 1000.0}


def test_absolute_actual_keeps_the_following_error_of_a_jogging_servo() -> None:
    """At 100 mm/s the servo lags 2 · 100 / (2π · 40) = 0.7958 mm: after MRP Actual 0 the
    actual position reads 0 (quantised to the count) and the command that lag ahead."""
    a, b = twins()
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 300)
    ax = a.ctl.axis(1)
    lag = ax.position_error
    assert lag == pytest.approx(2 * 100.0 / (2 * 3.141592653589793 * 40.0), abs=1e-3)
    before = ax.actual_position
    trigger(a, a["MRP_1"], Axis=1, Type=0, PositionSelect=0, Position=0.0)
    b.cycle()
    a["MRP_1"].inputs["Execute"] = False
    assert a["MRP_1"].outputs["DN"] and not a["MRP_1"].outputs["ER"]
    # redefined in the scan of the edge, then one cycle of the jog (0.2 mm) went by
    d = -before
    assert_shifted(a, b, 1, d)
    assert ax.position_error == pytest.approx(b.ctl.axis(1).position_error, abs=1e-9)
    run((a, b), 500)
    assert_shifted(a, b, 1, d)
    assert not ax.fault


def test_absolute_command_assigns_the_command_position() -> None:
    a, b = twins()
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 300)
    before = b.ctl.axis(1).command_position
    for s in (a, b):
        s["MRP_1"].inputs.update(Axis=1, Type=0, PositionSelect=1, Position=1000.0)
    a["MRP_1"].inputs["Execute"] = True
    run((a, b), 1)
    # the edge's scan: the command became 1000, then the cycle moved it on by 0.2 mm
    ax = a.ctl.axis(1)
    assert ax.command_position == pytest.approx(1000.0 + 0.2, abs=1e-9)
    assert_shifted(a, b, 1, 1000.0 - before)


def test_relative_moves_both_positions_by_the_displacement() -> None:
    a, b = twins()
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 50)
    trigger(a, a["MRP_1"], Axis=1, Type=1, PositionSelect=0, Position=-12.5)
    b.cycle()
    run((a, b), 200)
    assert_shifted(a, b, 1, -12.5)


def test_a_move_in_progress_ends_on_the_same_spot() -> None:
    """An absolute MAM to 50 mm, redefined by +10 mm half way: it ends where it would
    have, which now reads 60 (CODESYS: "does not affect the trajectory of already
    commanded movements")."""
    a, b = twins()
    both((a, b), "MAM_1", Axis=1, MoveType=0, Position=50.0, **JOG)
    run((a, b), 100)
    trigger(a, a["MRP_1"], Axis=1, Type=1, PositionSelect=1, Position=10.0)
    b.cycle()
    run((a, b), 1000)
    assert b.ctl.axis(1).command_position == 50.0
    assert a.ctl.axis(1).command_position == 60.0
    assert a["MAM_1"].outputs["PC"] and b["MAM_1"].outputs["PC"]


def test_a_geared_slave_does_not_move_when_its_master_is_redefined() -> None:
    """MAG at 0.5 on the master's actual position: redefining the master (-1000 mm) leaves
    the slave where it is, and it keeps following the master's travel at 0.5."""
    a, b = twins()
    both((a, b), "MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5, MasterReference=0, Clutch=1)
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 300)
    trigger(a, a["MRP_1"], Axis=1, Type=1, PositionSelect=0, Position=-1000.0)
    b.cycle()
    assert_shifted(a, b, 1, -1000.0)
    assert_shifted(a, b, 2, 0.0)
    run((a, b), 300)
    assert_shifted(a, b, 2, 0.0)
    assert a["MAG_1"].outputs["IP"]


def test_an_exact_fraction_gear_stays_exact_across_its_masters_redefinition() -> None:
    """A fraction ratio (1 slave count per 3 master counts, 1000 counts/mm) is integer
    arithmetic; a redefinition by a whole number of master counts keeps the slave's
    counts equal to the twin's, count for count."""
    a, b = twins()
    gear = {"SlaveCounts": 1, "MasterCounts": 3, "RatioFormat": 1, "MasterReference": 1}
    both((a, b), "MAG_1", SlaveAxis=2, MasterAxis=1, Clutch=1, **gear)
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 123)
    trigger(a, a["MRP_1"], Axis=1, Type=1, PositionSelect=1, Position=7.123)
    b.cycle()
    for _ in range(400):
        run((a, b), 1)
        sa = round(a.ctl.axis(2).command_position_unwound * 1000)
        sb = round(b.ctl.axis(2).command_position_unwound * 1000)
        assert sa == sb


def test_redefining_the_slave_shifts_only_the_slave() -> None:
    a, b = twins()
    both((a, b), "MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=2.0, MasterReference=1, Clutch=1)
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 100)
    trigger(a, a["MRP_1"], Axis=2, Type=0, PositionSelect=1, Position=0.0)
    b.cycle()
    d = a.ctl.axis(2).command_position - b.ctl.axis(2).command_position
    run((a, b), 200)
    assert_shifted(a, b, 1, 0.0)
    assert_shifted(a, b, 2, d)
    assert a.ctl.axis(2).command_velocity == 2.0 * 100.0


def test_mc_gearinpos_syncs_on_the_same_spot_after_its_master_is_redefined() -> None:
    """A waiting MC_GearInPos holds its sync positions in the master's coordinates: when
    the master is redefined by +100 mm they move with it, and the lock-on happens at the
    same place as in the twin."""
    a, b = twins()
    sync = {
        "Master": 1,
        "Slave": 2,
        "RatioNumerator": 1,
        "RatioDenominator": 1,
        "MasterSyncPosition": 60.0,
        "SlaveSyncPosition": 30.0,
        "MasterStartDistance": 20.0,
        "BufferMode": 0,
    }
    both((a, b), "MC_GearInPos_1", **sync)
    both((a, b), "MAJ_1", Axis=1, Speed=50.0, AccelRate=1000.0, DecelRate=1000.0)
    run((a, b), 100)  # the master is at about 5 mm: still waiting
    trigger(a, a["MRP_1"], Axis=1, Type=1, PositionSelect=0, Position=100.0)
    b.cycle()
    run((a, b), 2000)
    assert b["MC_GearInPos_1"].outputs["InSync"] and a["MC_GearInPos_1"].outputs["InSync"]
    assert_shifted(a, b, 2, 0.0)
    assert_shifted(a, b, 1, 100.0)


def test_a_hand_wheel_reads_its_redefined_position() -> None:
    system = plant()
    wheel = system.ctl.axis(4)
    system.ctl.set_feedback_input(wheel, 3.0)
    system.cycle()
    trigger(system, system["MRP_1"], Axis=4, Type=0, PositionSelect=0, Position=10.0)
    assert wheel.actual_position == 10.0
    system.ctl.set_feedback_input(wheel, 4.5)
    system.cycle()
    assert wheel.actual_position == 11.5


def test_rotary_absolute_position_outside_the_turn_is_refused() -> None:
    """ERR 13 with EXERR 4: Position counted in MRP(Axis, MotionControl, Type,
    PositionSelect, Position)."""
    system = plant()
    mrp = system["MRP_1"]
    trigger(system, mrp, Axis=3, Type=0, PositionSelect=0, Position=400.0)
    assert mrp.outputs["ER"] and mrp.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert mrp.outputs["EXERR"] == 4
    assert system.ctl.axis(3).actual_position == 0.0
    mrp.inputs["Execute"] = False
    system.cycle()
    trigger(system, mrp, Position=359.5)
    assert system.ctl.axis(3).actual_position == pytest.approx(359.5, abs=1e-9)


def test_a_position_beyond_2_53_counts_is_refused() -> None:
    system = plant()
    mrp = system["MRP_1"]
    trigger(system, mrp, Axis=1, Type=0, PositionSelect=0, Position=1e13)
    assert mrp.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE and mrp.outputs["EXERR"] == 4
    assert system.ctl.axis(1).actual_position == 0.0


def test_faulted_and_shut_down_axes_refuse() -> None:
    system = plant()
    mrp = system["MRP_1"]
    system.ctl.fault(system.ctl.axis(1), AxisFault.WATCHDOG)
    trigger(system, mrp, Axis=1, Type=0, PositionSelect=0, Position=5.0)
    assert mrp.outputs["ERR"] == ErrorCode.AXIS_FAULTED
    mrp.inputs["Execute"] = False
    system.cycle()
    trigger(system, system["MASD_1"], Axis=2)
    trigger(system, mrp, Axis=2)
    assert mrp.outputs["ERR"] == ErrorCode.SHUTDOWN_STATE


def test_mc_set_position_sets_the_actual_or_the_set_value() -> None:
    """ValueSource 1 (actual, the default): the actual position reads Position; 0 (set
    value): the command does. Either way the following error stays."""
    a, b = twins()
    both((a, b), "MAJ_1", Axis=1, **JOG)
    run((a, b), 300)
    block = a["MC_SetPosition_1"]
    trigger(a, block, Axis=1, Position=0.0)
    b.cycle()
    assert block.outputs["Done"] and not block.outputs["Busy"]
    lag = b.ctl.axis(1).position_error
    # redefined in the scan, then one cycle of travel
    assert a.ctl.axis(1).actual_position == pytest.approx(
        b.ctl.axis(1).actual_position - (b.ctl.axis(1).actual_position - 0.2), abs=0.01
    )
    assert a.ctl.axis(1).position_error == pytest.approx(lag, abs=1e-9)
    block.inputs["Execute"] = False
    run((a, b), 1)
    trigger(a, block, Position=500.0, ValueSource=0)
    b.cycle()
    assert a.ctl.axis(1).command_position == pytest.approx(500.0 + 0.2, abs=1e-9)
    block.inputs["Execute"] = False
    run((a, b), 1)
    trigger(a, block, Position=-500.0, Relative=True)
    b.cycle()
    assert a.ctl.axis(1).command_position == pytest.approx(0.2 + 0.2 + 0.2, abs=1e-9)
    assert a.ctl.axis(1).command_velocity == b.ctl.axis(1).command_velocity


def test_redefinition_leaves_homed_alone() -> None:
    """MRP does not set the Homed bit (only homing does)."""
    system = plant()
    trigger(system, system["MRP_1"], Axis=1, Type=0, PositionSelect=0, Position=5.0)
    assert not system.ctl.axis(1).homed
