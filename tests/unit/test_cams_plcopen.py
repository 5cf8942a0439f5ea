"""MC_CamTableSelect, MC_CamIn and MC_CamOut (PLCopen Part 1 v2.0 through the vendors'
pages, shared/references/camming.md section 2), with numbers worked by hand on the
linear tables of ``cam_support.TABLES`` and a hand-wheel master set exactly."""

from __future__ import annotations

import itertools

import pytest

from motion_server.kernel import ErrorCode, PLCopenState

from .cam_support import cam_system, master_to, new, run, slave

STEP = 0.2  # the master moves 0.2 mm per 2 ms cycle: 100 mm/s


def select(
    s,
    table: int,
    periodic: bool = False,
    master_abs: bool = True,  # type: ignore[no-untyped-def]
    slave_abs: bool = True,
) -> int:
    inst = new(
        s,
        "MC_CamTableSelect",
        Master=1,
        Slave=2,
        CamTable=table,
        Periodic=periodic,
        MasterAbsolute=master_abs,
        SlaveAbsolute=slave_abs,
    )
    assert inst.outputs["Done"] and not inst.outputs["Error"], inst.outputs
    return int(inst.outputs["CamTableID"])


def cam_in(s, table_id: int, **ops):  # type: ignore[no-untyped-def]
    base = {"Master": 1, "Slave": 2, "CamTableID": table_id, "MasterValueSource": 1}
    base.update(ops)
    return new(s, "MC_CamIn", **base)


def park_slave(s, position: float) -> None:  # type: ignore[no-untyped-def]
    """Put the slave's command at ``position`` (a redefinition moves nothing)."""
    s.ctl.redefine_position(s.ctl.axis(2), position, actual=False)
    s.cycle()


def test_select_gives_ids_and_changes_no_axis_state() -> None:
    s = cam_system()
    before = s.ctl.axis(2).plcopen_state
    first = select(s, 3)
    second = select(s, 1)
    assert second == first + 1
    assert s.ctl.axis(2).plcopen_state == before


def test_absolute_cam_places_the_slave_on_the_table() -> None:
    s = cam_system()
    park_slave(s, 7.0)
    master_to(s, 30.0)
    inst = cam_in(s, select(s, 3), SlaveOffset=5.0)
    assert inst.outputs["Busy"] and inst.outputs["Active"] and inst.outputs["InSync"]
    assert s.ctl.axis(2).plcopen_state == PLCopenState.SYNCHRONIZED_MOTION
    assert slave(s) == 35.0  # f(30) + 5: a jump from 7, as absolute coupling does
    master_to(s, 60.0)
    assert slave(s) == 65.0


def test_master_offset_and_scaling_divide_the_master() -> None:
    s = cam_system()
    master_to(s, 50.0)
    cam_in(s, select(s, 3), MasterOffset=10.0, MasterScaling=2.0, SlaveScaling=3.0)
    assert slave(s) == 60.0  # x = (50 - 10) / 2 = 20; 3 x 20
    master_to(s, 70.0)
    assert slave(s) == 90.0


def test_relative_cam_starts_where_master_and_slave_are() -> None:
    s = cam_system()
    park_slave(s, 7.0)
    master_to(s, 30.0)
    cam_in(s, select(s, 3, master_abs=False, slave_abs=False))
    assert slave(s) == 7.0
    master_to(s, 60.0)  # x = 30 from the coupling point
    assert slave(s) == 37.0


def test_start_mode_relative_makes_an_absolute_selection_relative_for_the_slave() -> None:
    s = cam_system()
    park_slave(s, 7.0)
    master_to(s, 30.0)
    cam_in(s, select(s, 3), StartMode=1)
    assert slave(s) == 7.0
    master_to(s, 40.0)
    assert slave(s) == 17.0


def test_periodic_relative_cam_accumulates_the_rise_and_pulses_end_of_profile() -> None:
    s = cam_system()
    master_to(s, 1000.0)
    inst = cam_in(s, select(s, 1, periodic=True, master_abs=False, slave_abs=False))
    pulses = []
    m = 1000.0
    for _ in range(65):  # to 1650: ends of the profile at 1200, 1400, 1600
        m += 10.0
        master_to(s, m)
        pulses.append(bool(inst.outputs["EndOfProfile"]))
    assert sum(pulses) == 3
    assert [i for i, p in enumerate(pulses) if p] == [19, 39, 59]  # one cycle each
    assert slave(s) == 3 * 50.0 + 25.0  # three passes and f(50)
    assert inst.outputs["InSync"]


def test_non_periodic_cam_holds_outside_and_is_not_in_sync() -> None:
    s = cam_system()
    master_to(s, 10.0)
    inst = cam_in(s, select(s, 3))
    master_to(s, 130.0)
    assert slave(s) == 100.0
    assert inst.outputs["Busy"] and not inst.outputs["InSync"]
    assert inst.outputs["EndOfProfile"]
    master_to(s, 80.0)  # back in the range: the cam drives the slave again
    assert slave(s) == 80.0 and inst.outputs["InSync"]


def test_a_non_periodic_coupling_outside_the_table_is_refused() -> None:
    s = cam_system()
    master_to(s, 150.0)
    inst = cam_in(s, select(s, 3))
    assert inst.outputs["Error"] and inst.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert slave(s) == 0.0


@pytest.mark.parametrize(
    ("ops", "code"),
    [
        ({"CamTableID": 999}, ErrorCode.PARAMETER_OUT_OF_RANGE),
        ({"MasterScaling": 0.0}, ErrorCode.PARAMETER_OUT_OF_RANGE),
        ({"SlaveScaling": 1e12}, ErrorCode.PARAMETER_OUT_OF_RANGE),
        ({"MasterValueSource": 0}, ErrorCode.WRONG_AXIS_TYPE),  # set value of a hand wheel
        ({"Master": 2}, ErrorCode.MASTER_AXIS_CONFLICT),  # the slave as its own master
    ],
)
def test_cam_in_errors(ops: dict[str, object], code: ErrorCode) -> None:
    s = cam_system()
    table_id = select(s, 3)
    inst = cam_in(s, table_id, **ops)
    assert inst.outputs["Error"] and inst.outputs["ErrorID"] == code


def test_the_selection_is_a_snapshot() -> None:
    s = cam_system()
    master_to(s, 10.0)
    inst = cam_in(s, select(s, 3))
    s.ctl.cams.tables[3].slave[1] = 500.0  # edited while the cam runs
    again = select(s, 3)  # selected again: the running cam keeps its profile
    master_to(s, 50.0)
    assert slave(s) == 50.0 and inst.outputs["InSync"]
    assert again > 0


def test_cam_out_leaves_the_slave_at_its_velocity() -> None:
    s = cam_system()
    inst = cam_in(s, select(s, 3))
    m = 0.0
    for _ in range(20):
        m += STEP
        master_to(s, m)
    v = s.ctl.axis(2).command_velocity
    assert v == pytest.approx(100.0, rel=1e-9)  # slope 1 x the master's 100 mm/s
    out = new(s, "MC_CamOut", Slave=2)
    assert out.outputs["Done"]
    assert inst.outputs["CommandAborted"] and not inst.outputs["Busy"]
    assert s.ctl.axis(2).plcopen_state == PLCopenState.CONTINUOUS_MOTION
    before = slave(s)
    for _ in range(10):
        master_to(s, m)  # the master stops; the slave goes on at its velocity
    assert s.ctl.axis(2).command_velocity == v
    assert slave(s) - before == pytest.approx(v * 10 * 0.002, rel=1e-9)


def test_cam_out_without_a_cam_is_an_error() -> None:
    s = cam_system()
    out = new(s, "MC_CamOut", Slave=2)
    assert out.outputs["Error"] and out.outputs["ErrorID"] == ErrorCode.NOT_CAMMING


def test_a_buffered_cam_starts_when_the_move_is_done() -> None:
    s = cam_system()
    master_to(s, 10.0)
    move = new(
        s,
        "MC_MoveRelative",
        Axis=2,
        Distance=5.0,
        Velocity=100.0,
        Acceleration=10000.0,
        Deceleration=10000.0,
    )
    inst = cam_in(s, select(s, 3, master_abs=False, slave_abs=False), BufferMode=1)
    assert inst.outputs["Busy"] and not inst.outputs["Active"]
    for _ in range(200):
        s.cycle()
    # the move is done (its Done was shown and released with Execute low): the cam runs
    assert not move.outputs["Busy"] and inst.outputs["Active"]
    assert slave(s) == pytest.approx(5.0, abs=1e-12)
    master_to(s, 20.0)
    assert slave(s) == pytest.approx(15.0, abs=1e-12)


def test_a_gear_in_aborts_a_cam() -> None:
    s = cam_system()
    inst = cam_in(s, select(s, 3))
    run(s, s.add("MC_GearIn", "G", {}), Master=6, Slave=2, MasterValueSource=0)
    assert inst.outputs["CommandAborted"]


def test_ramp_in_over_the_start_distance_ends_in_sync() -> None:
    # the line y = x, absolute; the slave at 7; MasterSyncPosition 60, distance 20: idle
    # to 40, then the quintic q(u) = p1 (10u^3 - 15u^4 + 6u^5) + v1 (-4u^3 + 7u^4 - 3u^5)
    # from rest to the cam's position 60 (p1 = 53) and slope 1 (v1 = 1 x 20) at 60
    s = cam_system()
    park_slave(s, 7.0)
    inst = cam_in(s, select(s, 3), MasterStartDistance=20.0, MasterSyncPosition=60.0)
    master_to(s, 30.0)
    assert slave(s) == 7.0
    assert inst.outputs["Busy"] and not inst.outputs["Active"] and not inst.outputs["InSync"]
    master_to(s, 50.0)  # u = 1/2: 53 x 1/2 + 20 x (-5/32) = 23.375
    assert slave(s) == pytest.approx(7.0 + 23.375, abs=1e-12)
    assert inst.outputs["Active"] and not inst.outputs["InSync"]
    master_to(s, 60.0)
    assert slave(s) == 60.0 and inst.outputs["InSync"]
    master_to(s, 70.0)
    assert slave(s) == 70.0


def test_ramp_in_arrives_with_the_master_speed() -> None:
    s = cam_system()
    park_slave(s, 7.0)
    inst = cam_in(s, select(s, 3), MasterStartDistance=20.0, MasterSyncPosition=60.0)
    m = 30.0
    velocities = []
    while m < 70.0:
        m = round(m + STEP, 10)
        master_to(s, m)
        velocities.append(s.ctl.axis(2).command_velocity)
    assert inst.outputs["InSync"]
    # the slope of the quintic is 0 at the start and 1 at the sync point: from rest to
    # the master's 100 mm/s
    assert velocities[0] == 0.0
    assert velocities[-1] == pytest.approx(100.0, rel=1e-6)
    # no velocity step: per 2 ms cycle at most the quintic's peak curvature, q''(u) =
    # p1 (60u - 180u^2 + 120u^3) + v1 (-24u + 84u^2 - 60u^3), over 20 mm at 100 mm/s
    peak = max(
        abs(53.0 * (60 * u - 180 * u**2 + 120 * u**3) + 20.0 * (-24 * u + 84 * u**2 - 60 * u**3))
        for u in (k / 1000 for k in range(1001))
    )
    bound = peak / 20.0**2 * 100.0**2 * 0.002
    steps = [abs(b - a) for a, b in itertools.pairwise(velocities)]
    assert max(steps) <= bound * 1.01


def test_a_sync_position_outside_a_non_periodic_table_is_refused() -> None:
    s = cam_system()
    inst = cam_in(s, select(s, 3), MasterStartDistance=20.0, MasterSyncPosition=160.0)
    assert inst.outputs["Error"] and inst.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
