"""Many cams started in one scan join the cam lane as columns (``CamLane._batch_columns``)
and change nothing but speed.

- The columns a batch of cams gives the lane are, field by field and bit for bit, the
  rows :meth:`CamLane._load` reads from each cam, whatever state the cams are in (just
  started, waited for their lock position, stepped in Python for a while, on several
  profiles, Continuous, Once or Persistent).
- Random scans on many slaves, each starting several cams in the same scan (some on the
  same slave, some stopped or touched again in that scan, the slaves' motion read through
  ``Controller.settle`` at random moments), run with and without lanes: every kinematic
  array, axis state and instruction output the same after every cycle.
- A profile pickled before it kept its range and rise is derived again when loaded.
"""

from __future__ import annotations

import pickle

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, CamTableConfig, Controller, GroupConfig
from motion_server.kernel.cam_profile import CamProfile, SegmentType, compute_profile
from motion_server.kernel.cams import CamMode, CamProcess, LockDirection
from motion_server.kernel.enums import MasterReference, ProcessKind
from motion_server.kernel.lanes.cams import CamLane
from motion_server.kernel.processes import JogProcess
from motion_server.kernel.profiles import Limits

from .test_lanes import assert_same, laned

SLAVES = 16  # axes 3..18; 1 and 2 are the masters


def profiles() -> list[CamProfile]:
    return [
        compute_profile((0.0, 90.0, 180.0, 360.0), (0.0, 20.0, 180.0, 360.0), [1, 1, 1, 1]),
        compute_profile((0.0, 30.0, 60.0), (0.0, 10.0, 10.0), [0, 1, 0]),
        compute_profile((-5.0, 5.0), (-0.0, 2.5), [SegmentType.LINEAR] * 2),
    ]


def controller(lanes: bool) -> Controller:
    axes = [
        AxisConfig(1, "M1", AxisType.VIRTUAL, max_acceleration=5000.0),
        AxisConfig(2, "M2", AxisType.VIRTUAL, rollover=360.0, max_acceleration=5000.0),
        *(
            AxisConfig(n, f"S{n}", AxisType.SERVO, following_error_limit=1e9)
            for n in range(3, 3 + SLAVES)
        ),
    ]
    ctl = Controller(axes, [GroupConfig(1, "G", tuple(range(1, 3 + SLAVES)), 0.002)], lanes=lanes)
    for n in range(1, 3 + SLAVES):
        ctl.servo_on(ctl.axis(n))
    return ctl


@settings(max_examples=30, deadline=None)
@given(
    cams=st.lists(
        st.tuples(
            st.integers(0, 2),  # profile
            st.sampled_from(list(CamMode)),
            st.sampled_from([1.0, -2.0, 0.7]),  # scale
            st.sampled_from([0.1, 1.0, -0.3]),  # master scaling
            st.sampled_from([0.0, 0.5]),  # cam lock, as a fraction of the profile
            st.sampled_from([0.0, 3.25, -1.0]),  # origin
            st.sampled_from([LockDirection.IMMEDIATE, LockDirection.FORWARD]),
            st.integers(0, 30),  # cycles stepped in Python before joining
        ),
        min_size=1,
        max_size=SLAVES,
    )
)
def test_batch_columns_are_the_rows_the_lane_loads(
    cams: list[tuple[int, CamMode, float, float, float, float, LockDirection, int]],
) -> None:
    ctl = controller(lanes=False)
    master = ctl.axis(1)
    ctl.start(
        master,
        lambda v, a: JogProcess(0.002, 100.0, Limits(100.0, 5000.0, 5000.0), v, a),
        replace=(ProcessKind.JOG,),
    )
    profs = profiles()
    joining = []
    for n, (pk, mode, scale, ms, lock_at, origin, lock, cycles) in enumerate(cams):
        prof = profs[pk]
        slave = ctl.axis(3 + n)
        p = CamProcess(
            ctl,
            prof,
            mode,
            scale,
            ms,
            prof.start + lock_at * prof.length,
            master=master.index,
            source=MasterReference.COMMAND,
            master_number=1,
            lock=lock,
            master_lock=0.5,
            origin=origin,
        )
        for _ in range(cycles):
            ctl.step()
            p.step(ctl.arrays, ctl.axes[0].period)
        slave.base = 0.125 * n - 1.0
        joining.append((p, slave))
    lane = CamLane(ctl.motion.lanes[1], MasterReference.COMMAND)
    columns = lane._batch_columns(joining)
    assert columns is not None
    for j, field in enumerate(CamLane.FIELDS):
        rows = np.array(
            [lane._load(p, ax)[j] for p, ax in joining], dtype=CamLane.DTYPES.get(field, float)
        )
        assert columns[j].dtype == rows.dtype, field
        assert columns[j].tobytes() == rows.tobytes(), f"{field}: {columns[j]} != {rows}"


def pair() -> tuple[MotionSystem, MotionSystem]:
    tables = [
        CamTableConfig(1, "Knife", 8, ((0.0, 0.0, 1), (90.0, 20.0, 1), (180.0, 180.0, 1),
                                       (360.0, 360.0, 1))),
        CamTableConfig(2, "Dwell", 8, ((0.0, 0.0, 0), (30.0, 10.0, 1), (60.0, 10.0, 0))),
        CamTableConfig(3, "Line", 8, ((0.0, 0.0, 0), (10.0, 5.0, 0))),
    ]  # fmt: skip
    out = []
    for lanes in (True, False):
        axes = [
            AxisConfig(1, "M1", AxisType.VIRTUAL, max_acceleration=5000.0),
            AxisConfig(2, "M2", AxisType.VIRTUAL, rollover=360.0, max_acceleration=5000.0),
            *(
                AxisConfig(n, f"S{n}", AxisType.SERVO, following_error_limit=1e9)
                for n in range(3, 3 + SLAVES)
            ),
        ]
        group = GroupConfig(1, "G", tuple(range(1, 3 + SLAVES)), 0.002)
        s = MotionSystem(Controller(axes, [group], lanes=lanes, cams=tables))
        for n in range(1, 3 + SLAVES):
            s.ctl.servo_on(s.ctl.axis(n))
        out.append(s)
    return out[0], out[1]


@st.composite
def scan_command(draw: st.DrawFn) -> tuple[str, dict[str, object]]:
    slave = draw(st.integers(3, 2 + SLAVES))
    kind = draw(st.sampled_from(["MAPC"] * 6 + ["MAS", "MAJ", "MC_CamOut"]))
    if kind == "MAPC":
        return kind, {
            "SlaveAxis": slave,
            "MasterAxis": draw(st.sampled_from([1, 2, slave - 1])),
            "CamProfile": draw(st.integers(1, 3)),
            "ExecutionMode": draw(st.integers(0, 2)),
            "ExecutionSchedule": draw(st.sampled_from([0, 0, 0, 1, 2])),
            "MasterReference": draw(st.integers(0, 1)),
            "MasterScaling": draw(st.sampled_from([1.0, 0.3, -1.5])),
            "SlaveScaling": draw(st.sampled_from([1.0, -2.0])),
            "MasterLockPosition": draw(st.sampled_from([0.0, 100.0])),
            "CamLockPosition": draw(st.sampled_from([0.0, 5.0])),
        }
    if kind == "MAS":
        return kind, {"Axis": slave, "StopType": draw(st.sampled_from([0, 8]))}
    if kind == "MAJ":
        return kind, {"Axis": slave, "Speed": 50.0, "AccelRate": 2000.0, "DecelRate": 2000.0}
    return kind, {"Slave": slave}


Scan = tuple[list[tuple[str, dict[str, object]]], list[int], int]


@settings(max_examples=25, deadline=None)
@given(
    scans=st.lists(
        st.tuples(
            st.lists(scan_command(), min_size=1, max_size=12),
            # slaves whose motion is read (settled) before the scan's step, and cycles after
            st.lists(st.integers(3, 2 + SLAVES), max_size=4),
            st.integers(1, 40),
        ),
        min_size=1,
        max_size=5,
    ),
    one_profile=st.booleans(),
)
def test_cams_started_together_give_the_same_motion_with_and_without_lanes(
    scans: list[Scan], one_profile: bool
) -> None:
    fast, ref = pair()
    setup = [
        ("MAJ", {"Axis": 1, "Speed": 100.0, "AccelRate": 5000.0, "DecelRate": 5000.0}),
        ("MAJ", {"Axis": 2, "Speed": 150.0, "AccelRate": 5000.0, "DecelRate": 5000.0}),
        *(("MCCP", {"Cam": n, "Length": (4, 3, 2)[n - 1], "CamProfile": n}) for n in (1, 2, 3)),
    ]
    # every slave on a cam in one scan, as many MAPC executed together do (on one table:
    # the lane evaluates it once for all; on three: once per table)
    first = [
        (
            "MAPC",
            {
                "SlaveAxis": n,
                "MasterAxis": 1 + n % 2,
                "CamProfile": 1 if one_profile else 1 + n % 3,
                "ExecutionMode": 1,
                "MasterReference": 1,
                "MasterScaling": 0.1 * n,
            },
        )
        for n in range(3, 3 + SLAVES)
    ]
    most = 0
    plan: list[Scan] = [(setup, [], 20), (first, [], 5), *scans]
    for i, (commands, read, cycles) in enumerate(plan):
        for s in (fast, ref):
            for j, (type_name, ops) in enumerate(commands):
                inst = s.add(type_name, f"I{i}_{j}", {})
                inst.inputs.update(ops)
                inst.inputs[inst.TRIGGER] = True
        for k in range(cycles):
            if k == 1:
                for s in (fast, ref):
                    for j in range(len(commands)):
                        inst = s.instances[f"I{i}_{j}"]
                        inst.inputs[inst.TRIGGER] = False
            for s in (fast, ref):
                s.cycle()
                if k == 0:
                    # read in the scan that started the cams, before they step again
                    for n in read:
                        s.ctl.settle(s.ctl.axis(n))
            assert_same(fast, ref, f"scan {i} ({commands}), cycle {k}")
            most = max(most, laned(fast))
    assert laned(ref) == 0
    assert most >= SLAVES - 2  # the cams of one scan ran in the lanes


def test_a_profile_pickled_without_its_derived_values_derives_them() -> None:
    prof = profiles()[0]
    derived = ("_start", "_end", "_length", "_rise", "_inner")
    state = {k: v for k, v in prof.__dict__.items() if k not in derived}
    old = CamProfile.__new__(CamProfile)
    old.__setstate__(state)
    again = pickle.loads(pickle.dumps(old))
    for p in (old, again):
        assert (p.start, p.end, p.length) == (0.0, 360.0, 360.0)
        assert p.rise == 360.0  # f(end) - f(start) of the table's points
        assert p.evaluate_many(np.array([45.0]))[0][0] == p.value(45.0)
