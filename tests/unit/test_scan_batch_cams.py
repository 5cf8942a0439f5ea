"""MAPC instances that fire in one scan and hand their cams to the kernel together
(``instructions/scan_pass.py``, ``kernel/cam_batch.start_position_cams``) against the same
scans executed instance by instance (``MotionSystem(batch=False)``).

Random scans fire random subsets of MAPC, mixed with MAJ (moving the masters), MAG and MAS
(which cut a batch), with random, partly invalid operands: two cams on one slave, a cam
whose master is a slave cammed in the same scan, loops, profiles that are not calculated
or do not exist, scalings of zero, lock positions outside the profile, the Pending and
lock-position schedules, a master direction of one way, a feedback-only master on its
command position, slaves that cannot move. After every cycle both systems must show the
same outputs (ERR, EXERR, SEGMENT ...), mark the same instances changed, command the same
position, velocity and acceleration bit for bit, hold the same processes (their
attributes, a successor's too), the same cam directions, motion status words and profile
Status words, lanes on and off.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, scan_pass
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    CamTableConfig,
    Controller,
    ErrorCode,
    GroupConfig,
)
from motion_server.kernel.cams import CamProcess, MasterDirection

from .test_scan_batch import processes, same_scan, scan_plans, write_scan

L = 0  # SegmentType linear
#: profile 1: slope 1/2 over 0..100, flat to 200; 2: y = x over 0..100; 3: the same
#: table, never calculated (ERR 32); 99 does not exist (ERR 13)
TABLES = {
    1: ("Half", ((0.0, 0.0, L), (100.0, 50.0, L), (200.0, 50.0, L))),
    2: ("Line", ((0.0, 0.0, L), (100.0, 100.0, L))),
    3: ("Raw", ((0.0, 0.0, L), (100.0, 100.0, L))),
}
#: axes 1..6 servo (on), 7 feedback only, 8 servo off; 9 does not exist
AXES = [1, 2, 3, 4, 5, 6, 1, 2, 3, 7, 8, 9]
POOLS: dict[str, dict[str, list[Any]]] = {
    "MAPC": {
        "SlaveAxis": AXES,
        "MasterAxis": AXES,
        "Direction": [0, 1, 2, 3],
        "CamProfile": [1, 2, 1, 2, 3, 99],
        "SlaveScaling": [1.0, 2.0, -0.5, 0.0],
        "MasterScaling": [1.0, 0.5, 0.0],
        "ExecutionMode": [0, 1, 2],
        "ExecutionSchedule": [0, 0, 0, 0, 1, 2, 4],
        "MasterLockPosition": [0.0, 5.0, -0.0],
        "CamLockPosition": [0.0, 50.0, 100.0, 150.0, -1.0],
        "MasterReference": [0, 1],
        "MasterDirection": [0, 0, 0, 1],
    },
    "MAJ": {"Axis": AXES, "Direction": [0, 1], "Speed": [5.0, 50.0], "AccelRate": [100.0]},
    "MAG": {"SlaveAxis": AXES, "MasterAxis": AXES, "Ratio": [0.5, 2.0]},
    "MAS": {"Axis": AXES, "StopType": [0, 1, 7]},  # all, jog, position cam
}
ORDER = [
    ("MAJ1", "MAJ"), ("MAPC1", "MAPC"), ("MAPC2", "MAPC"), ("MAPC3", "MAPC"),
    ("MAG1", "MAG"), ("MAPC4", "MAPC"), ("MAS1", "MAS"), ("MAPC5", "MAPC"),
    ("MAJ2", "MAJ"), ("MAPC6", "MAPC"), ("MAPC7", "MAPC"),
]  # fmt: skip


def cam_system(
    batch: bool, lanes: bool, tables: dict[int, tuple[str, Any]] = TABLES
) -> MotionSystem:
    """Axes 1..6 servo (on), 7 feedback only, 8 servo (off), in one group at 2 ms, with
    the cam tables ``tables``; batched or one instance at a time."""
    axes = [
        AxisConfig(n, f"A{n}", AxisType.SERVO, max_velocity=1000.0, max_acceleration=500.0,
                   max_deceleration=400.0)
        for n in range(1, 7)
    ] + [AxisConfig(7, "A7", AxisType.FEEDBACK_ONLY),
         AxisConfig(8, "A8", AxisType.SERVO)]  # fmt: skip
    cams = [CamTableConfig(n, name, 8, points) for n, (name, points) in tables.items()]
    group = GroupConfig(1, "Group1", tuple(a.number for a in axes), 0.002)
    system = MotionSystem(Controller(axes, [group], lanes, cams), batch=batch)
    for ax in system.ctl.axes[:6]:
        system.ctl.servo_on(ax)
    return system


def build(batch: bool, lanes: bool) -> MotionSystem:
    system = cam_system(batch, lanes)
    for n in (1, 2):  # MCCP of tables 1 and 2 into their own profiles
        mccp = system.add("MCCP", f"MCCP{n}", {})
        mccp.inputs.update(
            {"Cam": n, "Length": len(TABLES[n][1]), "CamProfile": n, mccp.TRIGGER: True}
        )
        system.cycle()
        assert mccp.outputs["DN"] and not mccp.outputs["ER"], mccp.outputs
        mccp.inputs[mccp.TRIGGER] = False
    for name, type_name in ORDER:
        system.add(type_name, name)
    return system


def scans() -> st.SearchStrategy[list[list[tuple[str, dict[str, Any], bool]]]]:
    return scan_plans(ORDER, POOLS, 6)


def same(batched: MotionSystem, alone: MotionSystem, when: object) -> None:
    same_scan(batched, alone, when)
    for a, b in zip(batched.ctl.axes, alone.ctl.axes, strict=True):
        assert a.cam_direction == b.cam_direction, (when, a.name)
        assert a.motion_status == b.motion_status, (when, a.name)
        assert processes(a.preloaded_cams) == processes(b.preloaded_cams), (when, a.name)
    for n in TABLES:
        assert batched.ctl.cams.slot(n).status == alone.ctl.cams.slot(n).status, (when, n)


@pytest.mark.parametrize("lanes", [True, False])
@settings(max_examples=150, deadline=None)
@given(plan=scans(), wheel=st.lists(st.sampled_from([0.0, 2.5, 40.0, -3.0]), max_size=6))
def test_a_scan_with_cam_batches_acts_as_one_instance_at_a_time(
    lanes: bool, plan: list[list[tuple[str, dict[str, Any], bool]]], wheel: list[float]
) -> None:
    batched, alone = build(True, lanes), build(False, lanes)
    for k, cycle in enumerate(plan + [[]] * 3):
        for system in (batched, alone):
            if k < len(wheel):
                system.ctl.set_feedback_input(system.ctl.axis(7), wheel[k])
            write_scan(system, cycle)
        batched.cycle()
        alone.cycle()
        same(batched, alone, (k, cycle))


def pair() -> tuple[MotionSystem, MotionSystem]:
    return build(True, True), build(False, True)


def fire(systems: tuple[MotionSystem, ...], operands: dict[str, dict[str, Any]]) -> None:
    """Write ``operands`` to their instances with Execute high, run one cycle, compare."""
    for system in systems:
        for name, values in operands.items():
            system[name].inputs.update({"CamProfile": 2, **values, "Execute": True})
        system.cycle()
    same(systems[0], systems[1], operands)


def cam_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The number of cams of each ``start_position_cams`` call the scans make from now on."""
    calls: list[int] = []
    real = scan_pass.start_position_cams

    def spy(ctl: Controller, starts: Any) -> Any:
        calls.append(len(starts))
        return real(ctl, starts)

    monkeypatch.setattr(scan_pass, "start_position_cams", spy)
    return calls


def test_cams_of_one_scan_reach_the_kernel_in_one_call(monkeypatch: pytest.MonkeyPatch) -> None:
    """MAPC1..3 (a run) and MAPC4, 5 (after a MAG): two calls of three and two cams; every
    cam runs, DN and IP set, as one by one."""
    calls = cam_calls(monkeypatch)
    systems = pair()
    fire(
        systems,
        {
            "MAPC1": {"SlaveAxis": 2, "MasterAxis": 1},
            "MAPC2": {"SlaveAxis": 3, "MasterAxis": 1},
            "MAPC3": {"SlaveAxis": 4, "MasterAxis": 1},
            "MAG1": {"SlaveAxis": 6, "MasterAxis": 1},
            "MAPC4": {"SlaveAxis": 5, "MasterAxis": 1},
        },
    )
    assert calls == [3, 1]
    for name in ("MAPC1", "MAPC2", "MAPC3", "MAPC4"):
        out = systems[0][name].outputs
        assert out["DN"] and out["IP"] and not out["ER"], name
    assert systems[0].ctl.cams.slot(2).status == 2 + 4  # calculated, in use by four cams


def test_a_second_cam_on_a_slave_of_the_same_scan_is_refused() -> None:
    """MAPC2 on the slave MAPC1 cams in the same scan: ERR 23 (the slave is position
    camming), as when MAPC1 had executed before it."""
    systems = pair()
    ops = {"SlaveAxis": 2, "MasterAxis": 1}
    fire(systems, {"MAPC1": ops, "MAPC2": ops})
    out = systems[0]["MAPC2"].outputs
    assert out["ER"] and out["ERR"] == ErrorCode.ILLEGAL_DYNAMIC_CHANGE
    assert len(systems[0].ctl.axis(2).processes) == 1


def test_a_cam_whose_master_is_a_slave_of_the_same_scan_closing_a_loop_is_refused() -> None:
    """MAPC1 cams 2 to 1, MAPC2 cams 1 to 2 in the same scan: ERR 10 (a loop)."""
    systems = pair()
    fire(
        systems,
        {"MAPC1": {"SlaveAxis": 2, "MasterAxis": 1}, "MAPC2": {"SlaveAxis": 1, "MasterAxis": 2}},
    )
    out = systems[0]["MAPC2"].outputs
    assert out["ER"] and out["ERR"] == ErrorCode.MASTER_AXIS_CONFLICT
    assert not systems[0].ctl.axis(1).processes


def test_a_cam_whose_master_follows_a_slave_of_the_same_scan_sees_its_cam() -> None:
    """Axis 1 is geared to 4 (an earlier scan); MAPC1 cams 2 to 1 and MAPC2 cams 4 to 2
    in one scan: 4 -> 2 -> 1 -> 4 is a loop through MAPC1's cam, ERR 10 for MAPC2."""
    systems = pair()
    for system in systems:
        system["MAG1"].inputs.update({"SlaveAxis": 1, "MasterAxis": 4, "Execute": True})
    fire(systems, {})
    assert systems[0]["MAG1"].outputs["IP"]
    fire(
        systems,
        {"MAPC1": {"SlaveAxis": 2, "MasterAxis": 1}, "MAPC2": {"SlaveAxis": 4, "MasterAxis": 2}},
    )
    out = systems[0]["MAPC2"].outputs
    assert out["ER"] and out["ERR"] == ErrorCode.MASTER_AXIS_CONFLICT
    assert systems[0]["MAPC1"].outputs["IP"]


def test_a_cam_preloaded_on_the_slave_follows_the_immediate_cam() -> None:
    """A Pending MAPC on a slave without a cam is preloaded; the Immediate MAPC of a later
    scan starts and the preloaded cam is its successor (as ``execute`` does: such a
    slave executes alone)."""
    systems = pair()
    fire(systems, {"MAPC1": {"SlaveAxis": 3, "MasterAxis": 1, "ExecutionSchedule": 1}})
    assert systems[0].ctl.axis(3).preloaded_cams
    fire(
        systems,
        {"MAPC2": {"SlaveAxis": 2, "MasterAxis": 1}, "MAPC3": {"SlaveAxis": 3, "MasterAxis": 1}},
    )
    cam = systems[0]["MAPC3"].process
    assert isinstance(cam, CamProcess) and cam.successor is systems[0]["MAPC1"].process


def test_one_way_master_direction_and_lock_position_keep_their_values() -> None:
    """A MAPC with MasterDirection Forward only keeps it (executed alone); an Immediate
    MAPC keeps its MasterLockPosition in its cam, as ``execute`` builds it."""
    systems = pair()
    fire(
        systems,
        {
            "MAPC1": {"SlaveAxis": 2, "MasterAxis": 1, "MasterDirection": 1},
            "MAPC2": {"SlaveAxis": 3, "MasterAxis": 1, "MasterLockPosition": 5.0},
        },
    )
    first = systems[0]["MAPC1"].process
    second = systems[0]["MAPC2"].process
    assert isinstance(first, CamProcess) and isinstance(second, CamProcess)
    assert first.master_direction == MasterDirection.FORWARD_ONLY
    assert second.master_lock == 5.0
