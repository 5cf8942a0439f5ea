"""MCCP, MCSV, MAPC, MATC and the cam MotionStatus bits, with numbers worked by hand.

The master is a hand wheel whose positions the test sets exactly; on the linear tables of
``cam_support.TABLES`` the slave's command positions are exact binary fractions. The
rules are MOTION-RM002's (shared/references/camming.md, section 1) and the MGS seed's
(a group stop clears PositionCamStatus, TimeCamStatus, both Pending bits and
PositionCamLockStatus).
"""

from __future__ import annotations

import pytest

from motion_server.kernel import ErrorCode, MotionStatusBit

from .cam_support import bit, calc, cam_system, master_to, new, slave

B = MotionStatusBit


def mapc(s, **ops):  # type: ignore[no-untyped-def]
    base = {"SlaveAxis": 2, "MasterAxis": 1, "CamProfile": 3, "MasterReference": 0}
    base.update(ops)
    return new(s, "MAPC", **base)


def test_profile_status_counts_the_cams_running_on_it() -> None:
    s = cam_system()
    assert s.ctl.cams.slot(3).status == 0  # not calculated
    calc(s, 3)
    assert s.ctl.cams.slot(3).status == 2  # calculated
    mapc(s, SlaveAxis=2)
    mapc(s, SlaveAxis=3)
    assert s.ctl.cams.slot(3).status == 4  # in use by 4 - 2 = 2 cams
    new(s, "MAS", Axis=2, StopType=7)  # Position Cam
    assert s.ctl.cams.slot(3).status == 3


def test_mccp_refuses_a_profile_in_use() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s)
    again = new(s, "MCCP", Cam=3, Length=2, CamProfile=3)
    assert again.outputs["ER"] and again.outputs["ERR"] == ErrorCode.CAM_PROFILE_BEING_USED


@pytest.mark.parametrize(
    ("ops", "err", "exerr"),
    [
        ({"Cam": 3, "Length": 1, "CamProfile": 3}, ErrorCode.ILLEGAL_CAM_LENGTH, 0),
        ({"Cam": 3, "Length": 9, "CamProfile": 3}, ErrorCode.ILLEGAL_CAM_LENGTH, 0),
        ({"Cam": 3, "Length": 2, "CamStart": 7, "CamProfile": 3}, ErrorCode.ILLEGAL_CAM_LENGTH, 0),
        ({"Cam": 1, "Length": 3, "CamProfile": 4}, ErrorCode.ILLEGAL_CAM_PROFILE_LENGTH, 0),
        # elements 1..3 of table 1: the master values 100, 200, 0 do not increase
        ({"Cam": 1, "Length": 3, "CamStart": 1, "CamProfile": 1}, ErrorCode.ILLEGAL_CAM_ORDER, 0),
        ({"Cam": 99, "Length": 2, "CamProfile": 3}, ErrorCode.PARAMETER_OUT_OF_RANGE, 1),
        ({"Cam": 3, "Length": 2, "CamProfile": 99}, ErrorCode.PARAMETER_OUT_OF_RANGE, 5),
    ],
)
def test_mccp_errors(ops: dict[str, int], err: ErrorCode, exerr: int) -> None:
    s = cam_system()
    inst = new(s, "MCCP", **ops)
    assert inst.outputs["ER"] and not inst.outputs["DN"]
    assert (inst.outputs["ERR"], inst.outputs["EXERR"]) == (err, exerr)


def test_mccp_refuses_a_segment_type_other_than_linear_or_cubic() -> None:
    s = cam_system()
    s.ctl.cams.tables[3].segment[0] = 2
    inst = new(s, "MCCP", Cam=3, Length=2, CamProfile=3)
    assert inst.outputs["ERR"] == ErrorCode.ILLEGAL_CAM_TYPE


def test_an_edit_of_the_table_changes_nothing_until_the_next_mccp() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s)
    s.ctl.cams.tables[3].slave[1] = 1000.0  # the table changes; the profile does not
    master_to(s, 50.0)
    assert slave(s) == 50.0


def test_mapc_needs_a_calculated_profile() -> None:
    s = cam_system()
    inst = mapc(s)
    assert inst.outputs["ERR"] == ErrorCode.CAM_PROFILE_NOT_CALCULATED


def test_once_follows_the_table_then_completes_with_pc() -> None:
    s = cam_system()
    calc(s, 1)
    inst = mapc(s, CamProfile=1, ExecutionMode=0)
    assert inst.outputs["DN"] and inst.outputs["IP"]  # in the same scan
    assert bit(s, 2, B.POSITION_CAM) and bit(s, 2, B.POSITION_CAM_LOCK)
    for m, expected in ((25.0, 12.5), (100.0, 50.0), (150.0, 50.0), (200.0, 50.0)):
        master_to(s, m)
        assert slave(s) == expected
        assert inst.outputs["IP"] and not inst.outputs["PC"]
    master_to(s, 210.0)  # beyond the profile: the cam is complete
    assert slave(s) == 50.0
    assert inst.outputs["PC"] and not inst.outputs["IP"]
    assert not bit(s, 2, B.POSITION_CAM) and not bit(s, 2, B.POSITION_CAM_LOCK)
    master_to(s, 100.0)  # no resume when the master comes back
    assert slave(s) == 50.0


def test_the_segment_follows_the_cam() -> None:
    s = cam_system()
    calc(s, 1)
    inst = mapc(s, CamProfile=1, ExecutionMode=1)
    master_to(s, 50.0)
    assert inst.outputs["SEGMENT"] == 0
    master_to(s, 150.0)
    assert inst.outputs["SEGMENT"] == 1
    master_to(s, 250.0)  # the second pass, first segment again
    assert inst.outputs["SEGMENT"] == 0


def test_continuous_adds_the_rise_per_pass_both_ways() -> None:
    s = cam_system()
    calc(s, 1)
    mapc(s, CamProfile=1, ExecutionMode=1)
    master_to(s, 450.0)  # two passes (2 x 50) and a quarter (f(50) = 25)
    assert slave(s) == 125.0
    master_to(s, -100.0)  # one pass back: f(100) - 50
    assert slave(s) == 0.0
    master_to(s, -150.0)  # f(50) - 50
    assert slave(s) == -25.0


def test_persistent_holds_outside_the_range_and_follows_again() -> None:
    s = cam_system()
    calc(s, 3)
    inst = mapc(s, CamProfile=3, ExecutionMode=2)
    master_to(s, 150.0)
    assert slave(s) == 100.0
    assert bit(s, 2, B.POSITION_CAM) and not bit(s, 2, B.POSITION_CAM_LOCK)
    assert inst.outputs["IP"]
    master_to(s, 40.0)
    assert slave(s) == 40.0 and bit(s, 2, B.POSITION_CAM_LOCK)
    master_to(s, -10.0)
    assert slave(s) == 0.0 and not bit(s, 2, B.POSITION_CAM_LOCK)


def test_lock_position_and_scalings() -> None:
    # x = CamLock + (m - m_lock) / MasterScaling; slave = SlaveScaling (f(x) - f(CamLock))
    s = cam_system()
    master_to(s, 10.0)
    calc(s, 3)
    mapc(s, CamLockPosition=50.0, MasterScaling=2.0, SlaveScaling=3.0, ExecutionMode=2)
    master_to(s, 30.0)  # x = 50 + 20 / 2 = 60
    assert slave(s) == 30.0
    master_to(s, 120.0)  # x = 105: beyond the end, held at f(100): 3 x 50
    assert slave(s) == 150.0


def test_deltas_scaling_example() -> None:
    # a 360 master table whose slave travels 120: SlaveScaling 2 -> 240, MasterScaling
    # 0.5 -> the table spans 180 of the master
    s = cam_system()
    calc(s, 5)
    inst = mapc(s, CamProfile=5, SlaveScaling=2.0, MasterScaling=0.5)
    master_to(s, 90.0)
    assert slave(s) == 120.0
    master_to(s, 180.0)
    assert slave(s) == 240.0 and inst.outputs["IP"]
    master_to(s, 181.0)
    assert inst.outputs["PC"] and slave(s) == 240.0


def stop_cam(s, axis: int = 2) -> float:  # type: ignore[no-untyped-def]
    """MAS Position Cam, then cycles until the slave is at rest; its position."""
    new(s, "MAS", Axis=axis, StopType=7)
    for _ in range(2000):
        if not s.ctl.axis(axis).moving:
            break
        s.cycle()
    assert not s.ctl.axis(axis).moving
    return slave(s, axis)


def test_direction_same_opposite_reverse_unchanged() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s, Direction=1, ExecutionMode=2)  # opposite
    master_to(s, 20.0)
    assert slave(s) == -20.0
    base = stop_cam(s)
    master_to(s, 0.0)
    mapc(s, Direction=2, ExecutionMode=2)  # reverse of opposite: same
    master_to(s, 20.0)
    assert slave(s) - base == 20.0
    base = stop_cam(s)
    master_to(s, 0.0)
    mapc(s, Direction=3, ExecutionMode=2)  # unchanged: same
    master_to(s, 20.0)
    assert slave(s) - base == 20.0


def test_first_reverse_is_opposite() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s, Direction=2, ExecutionMode=2)
    master_to(s, 20.0)
    assert slave(s) == -20.0


@pytest.mark.parametrize(
    ("schedule", "path", "lock_at", "end"),
    [
        # forward only: no lock on the way back down through 50, lock going up through it
        (2, (40.0, 60.0), 50.0, 70.0),
        (3, (60.0, 40.0), 50.0, 30.0),  # reverse only
        (4, (60.0, 40.0), 50.0, 30.0),  # bi-directional, the reverse crossing
    ],
)
def test_lock_position_schedules_lock_where_the_master_passes_it(
    schedule: int, path: tuple[float, ...], lock_at: float, end: float
) -> None:
    s = cam_system()
    master_to(s, 45.0)
    calc(s, 3)
    inst = mapc(s, ExecutionSchedule=schedule, MasterLockPosition=lock_at, CamLockPosition=50.0)
    assert inst.outputs["DN"] and inst.outputs["IP"]
    assert bit(s, 2, B.POSITION_CAM) and not bit(s, 2, B.POSITION_CAM_LOCK)
    if schedule == 2:
        master_to(s, 30.0)  # down: not a forward crossing
        assert slave(s) == 0.0
    for m in path:
        master_to(s, m)
    # locked exactly at the crossing: the slave moved by the master's travel since 50
    assert bit(s, 2, B.POSITION_CAM_LOCK)
    assert slave(s) == path[-1] - lock_at
    master_to(s, end)
    assert slave(s) == end - lock_at


def test_forward_only_does_not_lock_going_backwards() -> None:
    s = cam_system()
    master_to(s, 60.0)
    calc(s, 3)
    mapc(s, ExecutionSchedule=2, MasterLockPosition=50.0)
    for m in (55.0, 40.0, 10.0):
        master_to(s, m)
        assert slave(s) == 0.0 and not bit(s, 2, B.POSITION_CAM_LOCK)


def test_a_rotary_master_locks_in_any_turn() -> None:
    s = cam_system()
    master_to(s, 350.0, axis=5)
    calc(s, 3)
    mapc(s, MasterAxis=5, ExecutionSchedule=2, MasterLockPosition=10.0)
    master_to(s, 5.0, axis=5)  # 365 unwound: not yet
    assert slave(s) == 0.0
    master_to(s, 20.0, axis=5)  # 380: passed 370 = 10 of the next turn
    assert slave(s) == 10.0
    assert bit(s, 2, B.POSITION_CAM_LOCK)


def test_master_direction_forward_only_is_a_slip_clutch() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s, MasterDirection=1, ExecutionMode=2)
    master_to(s, 60.0)
    assert slave(s) == 60.0
    master_to(s, 40.0)  # the master goes back: the slave stays where it was
    assert slave(s) == 60.0 and not bit(s, 2, B.POSITION_CAM_LOCK)
    master_to(s, 55.0)
    assert slave(s) == 60.0
    master_to(s, 70.0)  # beyond the point it reached: the slave follows again
    assert slave(s) == 70.0 and bit(s, 2, B.POSITION_CAM_LOCK)


def test_an_immediate_mapc_on_a_camming_slave_is_an_illegal_dynamic_change() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s)
    second = mapc(s)
    assert second.outputs["ERR"] == ErrorCode.ILLEGAL_DYNAMIC_CHANGE


def test_a_cam_waiting_for_its_lock_counts_as_camming() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s, ExecutionSchedule=2, MasterLockPosition=50.0)
    assert mapc(s).outputs["ERR"] == ErrorCode.ILLEGAL_DYNAMIC_CHANGE


def test_cam_lock_position_outside_the_profile_is_err_13_naming_it() -> None:
    s = cam_system()
    calc(s, 3)
    inst = mapc(s, CamLockPosition=101.0)
    # SlaveAxis 0, MasterAxis 1, MotionControl 2, Direction 3, CamProfile 4, SlaveScaling
    # 5, MasterScaling 6, ExecutionMode 7, ExecutionSchedule 8, MasterLockPosition 9,
    # CamLockPosition 10
    assert (inst.outputs["ERR"], inst.outputs["EXERR"]) == (ErrorCode.PARAMETER_OUT_OF_RANGE, 10)
    zero = mapc(s, MasterScaling=0.0)
    assert (zero.outputs["ERR"], zero.outputs["EXERR"]) == (ErrorCode.PARAMETER_OUT_OF_RANGE, 6)


def test_pending_takes_over_at_the_end_of_a_once_cam() -> None:
    s = cam_system()
    calc(s, 3)
    calc(s, 1)
    first = mapc(s, CamProfile=3, ExecutionMode=0)
    second = mapc(s, CamProfile=1, ExecutionMode=0, ExecutionSchedule=1)
    assert second.outputs["DN"] and second.outputs["IP"]
    assert bit(s, 2, B.POSITION_CAM_PENDING)
    master_to(s, 100.0)
    assert slave(s) == 100.0
    master_to(s, 140.0)  # the first ended at 100; the second runs from there: 0.5 x 40
    assert slave(s) == 120.0
    assert first.outputs["PC"] and not first.outputs["IP"]
    assert second.outputs["IP"] and not bit(s, 2, B.POSITION_CAM_PENDING)
    assert bit(s, 2, B.POSITION_CAM_LOCK)


def test_pending_takes_over_at_the_end_of_a_pass_of_a_continuous_cam() -> None:
    s = cam_system()
    calc(s, 3)
    calc(s, 1)
    first = mapc(s, CamProfile=3, ExecutionMode=1)
    master_to(s, 30.0)
    mapc(s, CamProfile=1, ExecutionMode=0, ExecutionSchedule=1)
    master_to(s, 90.0)
    assert slave(s) == 90.0
    master_to(s, 120.0)  # the pass ended at 100: 100 + 0.5 x 20
    assert slave(s) == 110.0
    assert not first.outputs["IP"] and not first.outputs["PC"]  # superseded


def test_pending_without_a_running_cam_is_preloaded() -> None:
    s = cam_system()
    calc(s, 3)
    calc(s, 1)
    pending = mapc(s, CamProfile=1, ExecutionMode=0, ExecutionSchedule=1)
    master_to(s, 50.0)
    assert slave(s) == 0.0  # preloaded: no motion
    assert bit(s, 2, B.POSITION_CAM_PENDING) and not bit(s, 2, B.POSITION_CAM)
    mapc(s, CamProfile=3, ExecutionMode=0)  # locks at 50, x from 0
    master_to(s, 150.0)
    assert slave(s) == 100.0
    master_to(s, 170.0)  # the first ended at master 150: the preloaded one follows
    assert slave(s) == 110.0 and pending.outputs["IP"]


def test_mas_stops_position_cams_only_with_their_type() -> None:
    s = cam_system()
    calc(s, 3)
    inst = mapc(s, ExecutionMode=2)
    master_to(s, 10.0)
    new(s, "MAS", Axis=2, StopType=8)  # Time Cam: not this one
    assert inst.outputs["IP"]
    stop = new(s, "MAS", Axis=2, StopType=7)
    assert stop.outputs["DN"] and not inst.outputs["IP"]
    assert not bit(s, 2, B.POSITION_CAM)


def test_a_group_stop_clears_every_cam_bit() -> None:
    s = cam_system()
    calc(s, 3)
    calc(s, 6)
    mapc(s, ExecutionMode=1)
    mapc(s, ExecutionMode=0, ExecutionSchedule=1)  # pending
    new(s, "MATC", Axis=3, CamProfile=6, ExecutionMode=1)
    new(s, "MATC", Axis=3, CamProfile=6, ExecutionSchedule=1)
    master_to(s, 20.0)
    cams = (8, 9, 10, 11, 13, 14)
    assert {b for b in cams if bit(s, 2, MotionStatusBit(b))} == {8, 10, 13}
    assert {b for b in cams if bit(s, 3, MotionStatusBit(b))} == {9, 11, 14}
    new(s, "MGS", Group=1, StopMode=1)
    for _ in range(400):
        s.cycle()
    for axis in (2, 3):
        assert not any(bit(s, axis, MotionStatusBit(b)) for b in cams), axis


def test_a_move_superimposes_on_a_position_cam() -> None:
    s = cam_system()
    calc(s, 3)
    mapc(s, ExecutionMode=2)
    master_to(s, 10.0)
    new(
        s,
        "MAM",
        Axis=2,
        MoveType=1,
        Position=5.0,
        Speed=100.0,
        AccelRate=10000.0,
        DecelRate=10000.0,
    )
    for _ in range(200):
        master_to(s, 10.0)
    assert slave(s) == pytest.approx(15.0, abs=1e-9)


def test_matc_runs_on_time_and_completes() -> None:
    s = cam_system()
    calc(s, 6)
    inst = new(s, "MATC", Axis=2, CamProfile=6)
    assert inst.outputs["DN"] and inst.outputs["IP"]
    assert bit(s, 2, B.TIME_CAM) and bit(s, 2, B.TIME_CAM_LOCK)
    for _ in range(249):  # the trigger's cycle was the first: 250 x 2 ms = 0.5 s
        s.cycle()
    assert slave(s) == pytest.approx(5.0, abs=1e-12)
    for _ in range(251):  # 1.002 s: beyond the profile's 1 s
        s.cycle()
    assert inst.outputs["PC"] and slave(s) == 10.0
    assert not bit(s, 2, B.TIME_CAM)


def test_matc_time_and_distance_scaling() -> None:
    s = cam_system()
    calc(s, 6)
    new(s, "MATC", Axis=2, CamProfile=6, TimeScaling=2.0, DistanceScaling=3.0)
    for _ in range(249):
        s.cycle()
    # 0.5 s at TimeScaling 2 is x = 0.25: 3 x 2.5
    assert slave(s) == pytest.approx(7.5, abs=1e-12)


def test_matc_refuses_persistent_and_a_second_immediate() -> None:
    s = cam_system()
    calc(s, 6)
    bad = new(s, "MATC", Axis=2, CamProfile=6, ExecutionMode=2)
    # Axis 0, MotionControl 1, Direction 2, CamProfile 3, DistanceScaling 4,
    # TimeScaling 5, ExecutionMode 6
    assert (bad.outputs["ERR"], bad.outputs["EXERR"]) == (ErrorCode.PARAMETER_OUT_OF_RANGE, 6)
    new(s, "MATC", Axis=2, CamProfile=6)
    again = new(s, "MATC", Axis=2, CamProfile=6)
    assert again.outputs["ERR"] == ErrorCode.ILLEGAL_DYNAMIC_CHANGE


def test_mcsv_gives_value_and_slopes_of_the_smooth_step() -> None:
    s = cam_system()
    calc(s, 2)
    inst = new(s, "MCSV", CamProfile=2, MasterValue=25.0)
    # u = 1/4: 100 (3/16 - 2/64) = 15.625; slope 6u - 6u^2 = 1.125; (6 - 12 u)/100 = 0.03
    assert inst.outputs["DN"]
    assert inst.outputs["SlaveValue"] == pytest.approx(15.625, abs=1e-12)
    assert inst.outputs["SlopeValue"] == pytest.approx(1.125, abs=1e-12)
    assert inst.outputs["SlopeDerivative"] == pytest.approx(0.03, abs=1e-12)
    out = new(s, "MCSV", CamProfile=2, MasterValue=150.0)
    assert (out.outputs["ERR"], out.outputs["EXERR"]) == (ErrorCode.PARAMETER_OUT_OF_RANGE, 2)
    none = new(s, "MCSV", CamProfile=3, MasterValue=1.0)
    assert none.outputs["ERR"] == ErrorCode.CAM_PROFILE_NOT_CALCULATED


def test_matc_master_driven_runs_on_the_mdac_masters_travel() -> None:
    # MDAC Time Cam: t is the hand wheel's travel; TimeScaling 100 master units per second
    # of the profile: master 50 -> x = 0.5 -> 5; forward travel only
    s = cam_system()
    calc(s, 6)
    mdac = new(s, "MDAC", SlaveAxis=2, MasterAxis=1, MotionType=3)
    assert mdac.outputs["DN"] and mdac.outputs["IP"]
    inst = new(s, "MATC", Axis=2, CamProfile=6, TimeScaling=100.0)
    for _ in range(100):  # time alone moves nothing
        s.cycle()
    assert slave(s) == 0.0 and inst.outputs["IP"] and mdac.outputs["AC"]
    assert bit(s, 2, B.TIME_CAM) and not bit(s, 2, B.POSITION_CAM)
    master_to(s, 50.0)
    assert slave(s) == 5.0
    master_to(s, 30.0)  # the master goes back: the axis holds
    assert slave(s) == 5.0
    master_to(s, 100.0)
    assert slave(s) == 10.0
    master_to(s, 101.0)  # the profile's end: Once completes
    assert inst.outputs["PC"] and not mdac.outputs["AC"]


def test_a_stop_that_breaks_the_mdac_ends_the_master_driven_time_cam() -> None:
    s = cam_system()
    calc(s, 6)
    mdac = new(s, "MDAC", SlaveAxis=2, MasterAxis=1, MotionType=0)
    inst = new(s, "MATC", Axis=2, CamProfile=6, TimeScaling=100.0)
    master_to(s, 20.0)
    new(s, "MAS", Axis=2, StopType=0)
    assert not inst.outputs["IP"] and not mdac.outputs["IP"]


def test_a_group_shutdown_clears_the_cam_bits_too() -> None:
    s = cam_system()
    calc(s, 3)
    calc(s, 6)
    mapc(s, ExecutionMode=1)
    mapc(s, ExecutionMode=0, ExecutionSchedule=1)
    new(s, "MATC", Axis=3, CamProfile=6, ExecutionMode=1)
    master_to(s, 20.0)
    assert bit(s, 2, B.POSITION_CAM) and bit(s, 3, B.TIME_CAM)
    new(s, "MGSD", Group=1)
    s.cycle()
    for axis in (2, 3):
        assert not any(bit(s, axis, MotionStatusBit(b)) for b in (8, 9, 10, 11, 13, 14)), axis
