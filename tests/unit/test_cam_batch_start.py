"""Cams started as one batch (``start_position_cams``) are the cams started one after
the other (``Controller.start`` per slave, each built by its constructor): random batches
on many slaves (several on one slave, slaves already moving, masters that are slaves of
the same batch, command and actual references, several profiles and parameters), run on
and compared after every cycle: every kinematic array, every axis's state, status and
base, every cam's attributes and whether it is in a lane; with and without lanes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig
from motion_server.kernel.cam_batch import CamStart, start_position_cams
from motion_server.kernel.cam_profile import CamProfile, compute_profile
from motion_server.kernel.cams import CamMode, CamProcess
from motion_server.kernel.enums import MasterReference, ProcessKind
from motion_server.kernel.errors import ErrorCode, MotionError
from motion_server.kernel.processes import JogProcess, Process
from motion_server.kernel.profiles import Limits

AXES = 14  # 1 and 2 jog; 3..14 may be slaves, and masters of one another
ARRAYS = ("cmd_pos", "cmd_vel", "cmd_acc", "act_pos", "act_vel")


def profiles() -> list[CamProfile]:
    return [
        compute_profile((0.0, 90.0, 180.0, 360.0), (0.0, 20.0, 180.0, 360.0), [1, 1, 1, 1]),
        compute_profile((0.0, 30.0, 60.0), (0.0, 10.0, 10.0), [0, 1, 0]),
    ]


def controller(lanes: bool) -> Controller:
    axes = [
        AxisConfig(n, f"A{n}", AxisType.SERVO if n > 2 else AxisType.VIRTUAL,
                   rollover=360.0 if n % 4 == 0 else 0.0, following_error_limit=1e9,
                   max_acceleration=5000.0)
        for n in range(1, AXES + 1)
    ]  # fmt: skip
    ctl = Controller(axes, [GroupConfig(1, "G", tuple(range(1, AXES + 1)), 0.002)], lanes=lanes)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    return ctl


def jog(ctl: Controller, number: int, speed: float) -> None:
    ctl.start(
        ctl.axis(number),
        lambda v, a: JogProcess(0.002, speed, Limits(abs(speed), 5000.0, 5000.0), v, a),
        replace=(ProcessKind.JOG,),
    )


Params = tuple[int, CamMode, float, float, float, MasterReference, float]
#: (slave, master, which of the batch's parameter sets)
Spec = tuple[int, int, int]

params = st.tuples(
    st.integers(0, 1),  # profile
    st.sampled_from(list(CamMode)),
    st.sampled_from([1.0, -0.5]),  # scale
    st.sampled_from([0.1, 1.0, -0.3]),  # master scaling
    st.sampled_from([0.0, 15.0]),  # cam lock
    st.sampled_from(list(MasterReference)),
    st.sampled_from([0.0, 2.5]),  # origin
)
spec = st.tuples(st.integers(3, AXES), st.integers(1, AXES), st.integers(0, 2))


def cam_starts(ctl: Controller, specs: list[Spec], sets: list[Params]) -> list[CamStart]:
    """The starts of ``specs``; most share a parameter set, as many MAPC on one table do."""
    profs = profiles()
    out = []
    for i, (s, m, j) in enumerate(specs):
        if s != m:
            k, mode, scale, ms, lock, src, origin = sets[j % len(sets)]
            out.append(
                CamStart(ctl.axis(s), ctl.axis(m), profs[k], mode, scale, ms, lock, src, origin,
                         None, i)
            )  # fmt: skip
    return out


def one_by_one(ctl: Controller, starts: list[CamStart]) -> list[Process]:
    out = []
    for c in starts:

        def make(v: float, a: float, c: CamStart = c) -> Process:
            return c.build(ctl)

        out.append(ctl.start(c.slave, make, replace=()))
    return out


def same(
    a: Controller, b: Controller, cams: tuple[list[Process], list[Process]], where: str
) -> None:
    for name in ARRAYS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), f"{where}: {name}"
    for x, y in zip(a.axes, b.axes, strict=True):
        assert (x.state, x.motion_status, x.base) == (y.state, y.motion_status, y.base), where
    for p, q in zip(*cams, strict=True):
        assert (p.lane is None) == (q.lane is None), where
        for r in (p, q):
            if r.lane is not None:
                r.lane.sync(r)  # the lane's values into the object (it stays in the lane)
        skip = {"lane", "profile"}  # (each controller has its own profile objects)
        left = {k: v for k, v in vars(p).items() if k not in skip}
        right = {k: v for k, v in vars(q).items() if k not in skip}
        assert left == right, where
        assert p.profile.x == q.profile.x, where


@settings(max_examples=40, deadline=None)
@given(
    batches=st.lists(st.lists(spec, min_size=1, max_size=16), min_size=1, max_size=3),
    sets=st.lists(params, min_size=1, max_size=3),
    moving=st.lists(st.integers(3, AXES), max_size=3),
    lanes=st.booleans(),
)
def test_a_batch_starts_the_cams_one_after_the_other_would(
    batches: list[list[Spec]], sets: list[Params], moving: list[int], lanes: bool
) -> None:
    batch, seq = controller(lanes), controller(lanes)
    for ctl in (batch, seq):
        jog(ctl, 1, 100.0)
        jog(ctl, 2, -70.0)
        for n in moving:
            jog(ctl, n, 20.0)
        ctl.run(30)
    started: tuple[list[Process], list[Process]] = ([], [])
    for i, specs in enumerate(batches):
        started[0].extend(start_position_cams(batch, cam_starts(batch, specs, sets)))
        started[1].extend(one_by_one(seq, cam_starts(seq, specs, sets)))
        same(batch, seq, started, f"batch {i}, started")
        for k in range(40):
            batch.step()
            seq.step()
            same(batch, seq, started, f"batch {i}, cycle {k}")
    assert all(type(p) is CamProcess for p in started[0])


def test_a_cam_that_cannot_start_stops_the_batch_where_it_is() -> None:
    ctl = controller(True)
    prof = profiles()[1]  # master range 0..60
    ok = CamStart(ctl.axis(3), ctl.axis(1), prof, CamMode.ONCE, 1.0, 1.0, 0.0)
    bad = CamStart(ctl.axis(4), ctl.axis(1), prof, CamMode.ONCE, 1.0, 1.0, 61.0)
    after = CamStart(ctl.axis(5), ctl.axis(1), prof, CamMode.ONCE, 1.0, 1.0, 0.0)
    with pytest.raises(MotionError) as caught:
        start_position_cams(ctl, [ok, bad, after])
    assert caught.value.code == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert [len(ctl.axis(n).processes) for n in (3, 4, 5)] == [1, 0, 0]
