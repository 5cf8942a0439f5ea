"""Cams in the fast lanes change nothing but speed: random tables, masters, schedules and
commands, a controller with lanes and one without, compared bit for bit after every
cycle (``test_lanes.assert_same``: every kinematic array, every axis's state, status
word and base, every instruction output)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, CamTableConfig, Controller, GroupConfig

from .test_lanes import assert_same, laned

Script = list[tuple[str, dict[str, object], int]]


def cam_pair(tables: list[CamTableConfig]) -> tuple[MotionSystem, MotionSystem]:
    out = []
    for lanes in (True, False):
        axes = [
            AxisConfig(1, "M1", AxisType.VIRTUAL, max_acceleration=5000.0),
            AxisConfig(2, "M2", AxisType.VIRTUAL, rollover=360.0, max_acceleration=5000.0),
            *(
                AxisConfig(
                    n,
                    f"S{n}",
                    AxisType.SERVO,
                    following_error_limit=1e9,
                    rollover=360.0 if n % 3 == 0 else 0.0,
                )
                for n in range(3, 11)
            ),
        ]
        group = GroupConfig(1, "G", tuple(range(1, 11)), 0.002)
        s = MotionSystem(Controller(axes, [group], lanes=lanes, cams=tables))
        for n in range(1, 11):
            s.ctl.servo_on(s.ctl.axis(n))
        out.append(s)
    return out[0], out[1]


@st.composite
def table(draw: st.DrawFn, number: int) -> CamTableConfig:
    n = draw(st.integers(2, 7))
    steps = draw(
        st.lists(st.sampled_from([5.0, 10.0, 30.0, 45.0, 90.0]), min_size=n - 1, max_size=n - 1)
    )
    xs = [0.0]
    for d in steps:
        xs.append(xs[-1] + d)
    ys = draw(st.lists(st.floats(-50.0, 50.0, allow_nan=False), min_size=n, max_size=n))
    kinds = draw(st.lists(st.integers(0, 1), min_size=n, max_size=n))
    return CamTableConfig(number, f"T{number}", 8, tuple(zip(xs, ys, kinds, strict=True)))


@st.composite
def command(draw: st.DrawFn) -> tuple[str, dict[str, object], int]:
    kind = draw(
        st.sampled_from(
            ["MAPC", "MAPC", "MAPC", "MC_CamIn", "MAS", "MAJ", "MAM", "MC_CamOut", "MCCP", "MATC"]
        )
    )
    slave = draw(st.integers(3, 10))
    cycles = draw(st.integers(1, 80))
    if kind == "MAPC":
        ops: dict[str, object] = {
            "SlaveAxis": slave,
            "MasterAxis": draw(st.sampled_from([1, 2, 1, slave - 1])),
            "CamProfile": draw(st.integers(1, 3)),
            "ExecutionMode": draw(st.integers(0, 2)),
            "ExecutionSchedule": draw(st.integers(0, 4)),
            "MasterReference": draw(st.integers(0, 1)),
            "MasterDirection": draw(st.sampled_from([0, 0, 0, 1, 2])),
            "MasterScaling": draw(st.sampled_from([1.0, 3.0, 0.3, -1.5])),
            "SlaveScaling": draw(st.sampled_from([1.0, 0.7, -2.0])),
            "MasterLockPosition": draw(st.sampled_from([0.0, 10.0, 100.0, 350.0])),
            "CamLockPosition": draw(st.sampled_from([0.0, 5.0])),
            "Direction": draw(st.integers(0, 3)),
        }
    elif kind == "MC_CamIn":
        ops = {
            "Master": draw(st.integers(1, 2)),
            "Slave": slave,
            "CamTableID": draw(st.integers(1, 3)),
            "MasterValueSource": draw(st.integers(0, 1)),
            "StartMode": draw(st.integers(0, 1)),
            "MasterScaling": draw(st.sampled_from([1.0, 3.0])),
        }
    elif kind == "MAS":
        ops = {"Axis": slave, "StopType": draw(st.sampled_from([0, 7, 8]))}
    elif kind == "MAJ":
        ops = {
            "Axis": draw(st.sampled_from([1, 2, slave])),
            "Speed": draw(st.sampled_from([50.0, 200.0])),
            "Direction": draw(st.integers(0, 1)),
            "AccelRate": 2000.0,
            "DecelRate": 2000.0,
        }
    elif kind == "MAM":
        ops = {
            "Axis": slave,
            "MoveType": 1,
            "Position": 3.0,
            "Speed": 100.0,
            "AccelRate": 5000.0,
            "DecelRate": 5000.0,
        }
    elif kind == "MC_CamOut":
        ops = {"Slave": slave}
    elif kind == "MCCP":
        n = draw(st.integers(1, 3))
        ops = {"Cam": n, "Length": draw(st.integers(2, 4)), "CamProfile": n}
    else:
        ops = {
            "Axis": slave,
            "CamProfile": draw(st.integers(1, 3)),
            "TimeScaling": 0.01,
            "ExecutionMode": draw(st.integers(0, 1)),
        }
    return kind, ops, cycles


def run_pair(fast: MotionSystem, ref: MotionSystem, script: Script, prefix: str) -> int:
    most = 0
    for i, (type_name, ops, cycles) in enumerate(script):
        for s in (fast, ref):
            inst = s.add(type_name, f"{prefix}{i}", {})
            inst.inputs.update(ops)
            inst.inputs[inst.TRIGGER] = True
        for k in range(cycles + 1):
            if k == cycles:
                for s in (fast, ref):
                    inst = s.instances[f"{prefix}{i}"]
                    inst.inputs[inst.TRIGGER] = False
            fast.cycle()
            ref.cycle()
            assert_same(fast, ref, f"command {i} ({type_name} {ops}), cycle {k}")
            most = max(most, laned(fast))
        assert laned(ref) == 0
    return most


def preamble(tables: list[CamTableConfig]) -> Script:
    jogs: Script = [
        ("MAJ", {"Axis": 1, "Speed": 100.0, "AccelRate": 5000.0, "DecelRate": 5000.0}, 1),
        ("MAJ", {"Axis": 2, "Speed": 150.0, "AccelRate": 5000.0, "DecelRate": 5000.0}, 1),
    ]
    jogs += [
        ("MCCP", {"Cam": t.number, "Length": len(t.points), "CamProfile": t.number}, 1)
        for t in tables
    ]
    jogs += [("MC_CamTableSelect", {"CamTable": n, "Periodic": True}, 1) for n in (1, 2, 3)]
    jogs += [
        (
            "MAPC",
            {
                "SlaveAxis": n,
                "MasterAxis": 1 + n % 2,
                "CamProfile": 1 + n % 3,
                "ExecutionMode": 1,
                "MasterReference": n % 2,
                "MasterScaling": 0.3 * n,
            },
            1,
        )
        for n in range(3, 11)
    ]
    return [*jogs, ("MAS", {"Axis": 10, "StopType": 1}, 30)]


@settings(max_examples=40, deadline=None)
@given(
    tables=st.tuples(table(1), table(2), table(3)),
    script=st.lists(command(), min_size=1, max_size=8),
)
def test_random_cams_give_the_same_motion_with_and_without_lanes(
    tables: tuple[CamTableConfig, ...], script: Script
) -> None:
    fast, ref = cam_pair(list(tables))
    assert run_pair(fast, ref, preamble(list(tables)), "P") >= 6  # the cams on the jogging masters
    run_pair(fast, ref, script, "I")


def test_steady_cams_stay_in_the_lanes_through_their_passes() -> None:
    tables = [
        CamTableConfig(
            1, "Knife", 8, ((0.0, 0.0, 1), (90.0, 20.0, 1), (180.0, 180.0, 1), (360.0, 360.0, 1))
        ),
        CamTableConfig(2, "Dwell", 8, ((0.0, 0.0, 0), (30.0, 10.0, 1), (60.0, 10.0, 0))),
        CamTableConfig(3, "Line", 8, ((0.0, 0.0, 0), (10.0, 5.0, 0))),
    ]
    fast, ref = cam_pair(tables)
    run_pair(fast, ref, preamble(list(tables)), "P")
    passes = []
    for k in range(1500):  # 3 s: many passes of every table
        if k % 300 == 0:  # the masters change speed: the cams follow their acceleration
            speed = 60.0 + k / 10.0
            run_pair(
                fast,
                ref,
                [("MAJ", {"Axis": 1, "Speed": speed, "AccelRate": 500.0, "DecelRate": 500.0}, 1)],
                f"J{k}",
            )
        fast.cycle()
        ref.cycle()
        assert_same(fast, ref, "steady")
        passes.append(laned(fast))
    assert min(passes[-100:]) >= 7  # every camming slave laned through its passes
    assert np.array_equal(fast.ctl.cmd_pos, ref.ctl.cmd_pos)
