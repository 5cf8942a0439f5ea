"""MC_CamIn instances that fire in one scan and hand their cams to the kernel together
(``instructions/scan_pass.py``, ``kernel/cam_batch.start_position_cams``) against the
same scans executed instance by instance (``MotionSystem(batch=False)``).

The operands are mostly valid, so that runs of MC_CamIn fire together: random scans fire
random subsets of them on selections of every kind (periodic or not, master and slave
absolute or relative), mixed with MC_MoveVelocity (moving masters, and slaves, whose cam
then executes alone) and MC_Stop (which cuts a batch), with a second cam on one slave,
a cam whose master is a slave cammed in the same scan, loops, a master outside a
non-periodic table, scalings of zero, an unknown CamTableID, ramp-ins and buffered
blocks (executed alone), a feedback-only master on its set value, slaves that cannot
move. After every cycle both systems must show the same outputs on every instance, mark
the same instances changed, command the same position, velocity and acceleration bit for
bit, hold the same processes and the same profile Status words, lanes on and off.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given, settings

from motion_server.instructions import MotionSystem
from motion_server.kernel import (
    ErrorCode,
)

from . import test_scan_batch_cams
from .test_scan_batch import run_side_by_side, same, scan_plans

#: MAPC's tables 1 (slope 1/2 over 0..100, flat to 200) and 2 (y = x over 0..100)
TABLES = {n: test_scan_batch_cams.TABLES[n] for n in (1, 2)}
#: the selections MC_CamTableSelect makes before the scans, CamTableID 1..4 in order:
#: (table, periodic, master absolute, slave absolute)
SELECTIONS = [(1, True, True, True), (2, False, True, True), (1, True, False, False),
              (2, False, True, False)]  # fmt: skip
#: axes 1..6 servo (on), 7 feedback only, 8 servo off; 9 does not exist
AXES = [1, 2, 3, 4, 5, 6, 1, 2, 3, 4, 7, 8, 9]
POOLS: dict[str, dict[str, list[Any]]] = {
    "MC_CamIn": {
        "Master": AXES,
        "Slave": AXES,
        "CamTableID": [1, 2, 3, 4, 1, 3, 99],
        "MasterOffset": [0.0, 0.0, 10.0, -300.0],
        "SlaveOffset": [0.0, 5.0],
        "MasterScaling": [1.0, 1.0, 2.0, 0.0],
        "SlaveScaling": [1.0, 1.0, -0.5, 0.0],
        "MasterStartDistance": [0.0, 0.0, 0.0, 20.0],
        "MasterSyncPosition": [0.0, 50.0, 500.0],
        "StartMode": [0, 0, 1],
        "MasterValueSource": [0, 0, 1],
        "BufferMode": [0, 0, 0, 1],
    },
    "MC_MoveVelocity": {"Axis": AXES, "Velocity": [5.0, 50.0], "Direction": [1, 2]},
    "MC_Stop": {"Axis": AXES},
}
#: what every instance holds before the scans write to it
START: dict[str, dict[str, Any]] = {
    "MC_CamIn": {"CamTableID": 1},
    "MC_MoveVelocity": {"Velocity": 50.0, "Acceleration": 100.0, "Deceleration": 100.0,
                        "Direction": 1},
    "MC_Stop": {"Deceleration": 200.0},
}  # fmt: skip
ORDER = [
    ("MC_MoveVelocity1", "MC_MoveVelocity"), ("MC_CamIn1", "MC_CamIn"),
    ("MC_CamIn2", "MC_CamIn"), ("MC_CamIn3", "MC_CamIn"), ("MC_Stop1", "MC_Stop"),
    ("MC_CamIn4", "MC_CamIn"), ("MC_CamIn5", "MC_CamIn"),
    ("MC_MoveVelocity2", "MC_MoveVelocity"), ("MC_CamIn6", "MC_CamIn"),
]  # fmt: skip


def build(batch: bool, lanes: bool) -> MotionSystem:
    system = test_scan_batch_cams.cam_system(batch, lanes, TABLES)
    for k, (table, periodic, master_abs, slave_abs) in enumerate(SELECTIONS):
        sel = system.add("MC_CamTableSelect", f"Select{k + 1}", {})
        sel.inputs.update({"Master": 1, "Slave": 2, "CamTable": table, "Periodic": periodic,
                           "MasterAbsolute": master_abs, "SlaveAbsolute": slave_abs,
                           "Execute": True})  # fmt: skip
        system.cycle()
        assert sel.outputs["Done"] and sel.outputs["CamTableID"] == k + 1, sel.outputs
        sel.inputs["Execute"] = False
    for k, (name, type_name) in enumerate(ORDER):
        inst = system.add(type_name, name)
        # valid operands to start from: masters 1 and 2, a slave of its own among 3..6
        inst.inputs.update(START[type_name])
        if type_name == "MC_CamIn":
            inst.inputs.update({"Master": 1 + k % 2, "Slave": 3 + k % 4})
        else:
            inst.inputs["Axis"] = 1 + k % 2
    return system


def check(batched: MotionSystem, alone: MotionSystem, when: object) -> None:
    same(batched, alone, when)
    for n in TABLES:
        assert batched.ctl.cams.slot(n).status == alone.ctl.cams.slot(n).status, (when, n)


@pytest.mark.parametrize("lanes", [True, False])
@settings(max_examples=150, deadline=None)
@given(plan=scan_plans(ORDER, POOLS, 6))
def test_a_scan_with_cam_in_batches_acts_as_one_instance_at_a_time(
    lanes: bool, plan: list[list[tuple[str, dict[str, Any], bool]]]
) -> None:
    run_side_by_side(build, lanes, plan, check)


def test_cams_of_one_scan_reach_the_kernel_in_one_call(monkeypatch: pytest.MonkeyPatch) -> None:
    """Masters 1 and 2 jogging; MC_CamIn 1, 2, 3 on slaves 3, 4, 5 (a run), MC_Stop on
    axis 8 (refused: its drive is off; executed alone, it cuts the run), MC_CamIn 4 on
    slave 6 (absolute, so the slave jumps onto the cam), then MC_CamIn 5 buffered on the
    jogging axis 2 (alone): two calls of three cams and one; every cam runs, Busy and
    Active as one by one, and slave 6 stands where the table puts it."""
    calls = test_scan_batch_cams.cam_calls(monkeypatch)
    systems = (build(True, True), build(False, True))
    for system in systems:
        for name, axis in (("MC_MoveVelocity1", 1), ("MC_MoveVelocity2", 2)):
            system[name].inputs.update({"Axis": axis, "Velocity": 50.0, "Execute": True})
        system.cycle()
    for _ in range(100):  # 0.2 s at 100 mm/s²: 20 mm/s, 2 mm
        for system in systems:
            system.cycle()
    fired: dict[str, dict[str, Any]] = {
        "MC_CamIn1": {"Master": 1, "Slave": 3, "CamTableID": 1},
        "MC_CamIn2": {"Master": 2, "Slave": 4, "CamTableID": 1},
        "MC_CamIn3": {"Master": 1, "Slave": 5, "CamTableID": 3},
        "MC_Stop1": {"Axis": 8},
        "MC_CamIn4": {"Master": 1, "Slave": 6, "CamTableID": 1, "SlaveOffset": 5.0},
        "MC_CamIn5": {"Master": 1, "Slave": 2, "CamTableID": 1, "BufferMode": 1},
    }
    for system in systems:
        for name, values in fired.items():
            system[name].inputs.update({**values, "Execute": True})
        system.cycle()
    check(systems[0], systems[1], fired)
    assert calls == [3, 1]
    ctl = systems[0].ctl
    for name in ("MC_CamIn1", "MC_CamIn2", "MC_CamIn3", "MC_CamIn4"):
        out = systems[0][name].outputs
        assert out["Busy"] and out["Active"] and not out["Error"], (name, out)
    # table 1 is y = x/2 up to 100: slave 6 on master 1's command, plus 5
    master = ctl.axis(1).command_position
    assert 0.0 < master < 100.0
    assert ctl.axis(6).command_position == pytest.approx(0.5 * master + 5.0, abs=1e-12)
    for _ in range(20):
        for system in systems:
            system.cycle()
        check(systems[0], systems[1], "after")


def fire_pair(operands: dict[str, dict[str, Any]]) -> tuple[MotionSystem, MotionSystem]:
    """A batched and a one-by-one system, ``operands`` written to their instances with
    Execute high, one cycle run, compared."""
    systems = (build(True, True), build(False, True))
    for system in systems:
        for name, values in operands.items():
            system[name].inputs.update({**values, "Execute": True})
        system.cycle()
    check(systems[0], systems[1], operands)
    return systems


def test_a_second_cam_on_a_slave_of_the_same_scan_replaces_the_first() -> None:
    """MC_CamIn1 and MC_CamIn2 on slave 3 in one scan: the second aborts the first
    (CommandAborted), as when the first had executed before it; one cam on the slave."""
    batched, _ = fire_pair(
        {
            "MC_CamIn1": {"Master": 1, "Slave": 3, "CamTableID": 1},
            "MC_CamIn2": {"Master": 2, "Slave": 3, "CamTableID": 3},
        }
    )
    assert batched["MC_CamIn1"].outputs["CommandAborted"]
    assert batched["MC_CamIn2"].outputs["Busy"]
    procs = batched.ctl.axis(3).processes
    assert len(procs) == 1 and procs[0].owner is batched["MC_CamIn2"]


def test_a_cam_closing_a_loop_with_a_cam_of_the_same_scan_is_refused() -> None:
    """MC_CamIn1 cams 3 to 1, MC_CamIn2 cams 1 to 3 in the same scan: ErrorID 10 (a
    master/slave loop) for the second, as one by one; axis 1 keeps no cam."""
    batched, _ = fire_pair(
        {
            "MC_CamIn1": {"Master": 1, "Slave": 3, "CamTableID": 1},
            "MC_CamIn2": {"Master": 3, "Slave": 1, "CamTableID": 1},
        }
    )
    out = batched["MC_CamIn2"].outputs
    assert out["Error"] and out["ErrorID"] == ErrorCode.MASTER_AXIS_CONFLICT
    assert not batched.ctl.axis(1).processes
