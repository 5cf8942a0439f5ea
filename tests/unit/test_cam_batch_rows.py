"""A batch of cams on slaves at rest joins the cam lane as rows (``start_position_cams``:
the lane takes the batch's columns, the group is neither sorted nor levelled again when
the new links keep the order and the levels) and changes nothing but speed.

- Random scans on 20 axes: jogs (time lanes) and gears (command followers, in levels,
  some reading others) running; in one scan other commands before the batch, the batch
  or two (cams on distinct slaves at rest, masters anywhere, slaves of the same batch
  among them, both references, several parameter sets), other commands after it (a gear on a
  new slave, a jog on a master, a slave stopped); the processes read through
  ``Controller.settle`` at random moments, the controller copied through the snapshot
  codec at a random cycle. Compared after every cycle: the batch with lanes against the
  same cams started one by one with lanes (every cam's attributes, in a lane or not) and
  without lanes (every kinematic array, axis state, status and base).
- The usual batch (the ``cam`` bench case: every master jogging, every slave at rest)
  takes the short way: nothing to sort, nothing to level, the lane's columns taken as
  they are.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig
from motion_server.kernel.cam_batch import CamStart, start_position_cams
from motion_server.kernel.cams import CamMode, CamProcess
from motion_server.kernel.enums import AbortReason, MasterReference
from motion_server.kernel.gearing import GearProcess, GearTerm
from motion_server.kernel.lanes.cams import CamLane
from motion_server.kernel.processes import Process
from motion_server.scan import statecodec

from .test_cam_batch_start import jog, profiles

AXES = 20
ARRAYS = ("cmd_pos", "cmd_vel", "cmd_acc", "act_pos", "act_vel")


def controller(lanes: bool) -> Controller:
    axes = [
        AxisConfig(n, f"A{n}", AxisType.VIRTUAL if n <= 2 else AxisType.SERVO,
                   rollover=360.0 if n % 5 == 0 else 0.0, following_error_limit=1e9,
                   max_acceleration=5000.0, max_deceleration=5000.0)
        for n in range(1, AXES + 1)
    ]  # fmt: skip
    ctl = Controller(axes, [GroupConfig(1, "G", tuple(range(1, AXES + 1)), 0.002)], lanes=lanes)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    return ctl


def gear(ctl: Controller, slave: int, master: int, source: MasterReference) -> None:
    ax = ctl.axis(slave)
    term = GearTerm(master, source, 1, 2)
    ctl.start(ax, lambda v, a: GearProcess(ctl, ax, (term,), None, v, a), replace=None)


#: (profile, mode, scale, master scaling, cam lock, reference)
Params = tuple[int, CamMode, float, float, float, MasterReference]
params = st.tuples(
    st.integers(0, 1),
    st.sampled_from(list(CamMode)),
    st.sampled_from([1.0, -0.5]),
    st.sampled_from([0.1, 1.0, -0.3]),
    st.sampled_from([0.0, 15.0]),
    st.sampled_from(list(MasterReference)),
)

#: a command in the batch's scan: ("jog", axis), ("gear", slave, master), ("stop", axis),
#: ("settle", axis); axes as picks among 1..AXES
other = st.one_of(
    st.tuples(st.just("jog"), st.integers(1, AXES)),
    st.tuples(st.just("gear"), st.integers(3, AXES), st.integers(1, AXES)),
    st.tuples(st.just("stop"), st.integers(3, AXES)),
    st.tuples(st.just("settle"), st.integers(1, AXES)),
)


def command(ctl: Controller, cmd: tuple[object, ...]) -> None:
    """``cmd`` on ``ctl`` where it makes sense (the same on every controller)."""
    what = cmd[0]
    ax = ctl.axis(int(cmd[1]))  # type: ignore[call-overload]
    if what == "jog":
        jog(ctl, ax.number, 35.0)
    elif what == "gear":
        master = int(cmd[2])  # type: ignore[call-overload]
        if master != ax.number and not ctl.motion.would_cycle(ax.number, (master,)):
            gear(ctl, ax.number, master, MasterReference.COMMAND)
    elif what == "stop":
        ctl.motion.release(ax, list(ax.processes), AbortReason.STOPPED)
    else:
        ctl.settle(ax)


def cam_starts(
    ctl: Controller, picks: list[tuple[int, int, int]], sets: list[Params]
) -> list[CamStart]:
    """Cams on distinct slaves at rest (``picks``: slave, master, parameter set; a master
    beyond the axes: the slave of the cam before, a chain within the batch). A pick that
    would close a loop of master/slave links, with the processes running or the cams
    before it in the batch, is left out, as the gears of the set-up are: the instructions
    refuse such a link (ERR 10), and in a loop the motion depends on which axis of it
    composes first, an order neither way of starting defines."""
    profs = profiles()
    out: list[CamStart] = []
    taken: set[int] = set()
    for i, (s, m, j) in enumerate(picks):
        if m > AXES:
            m = out[-1].slave.number if out else 1
        slave = ctl.axis(s)
        if s == m or s in taken or slave.processes or slave.buffered is not None:
            continue
        batch_masters = {c.slave.number: c.master.number for c in out}
        reach, seen = [m], set()
        while reach and s not in seen:
            x = reach.pop()
            if x not in seen:
                seen.add(x)
                reach += [q for p in ctl.axis(x).processes if p.active for q in p.masters]
                if x in batch_masters:
                    reach.append(batch_masters[x])
        if s in seen:
            continue
        taken.add(s)
        k, mode, scale, ms, lock, src = sets[j % len(sets)]
        out.append(CamStart(slave, ctl.axis(m), profs[k], mode, scale, ms, lock, src, 0.0, None, i))
    return out


def one_by_one(ctl: Controller, starts: list[CamStart]) -> list[Process]:
    out = []
    for c in starts:

        def make(v: float, a: float, c: CamStart = c) -> Process:
            return c.build(ctl)

        out.append(ctl.start(c.slave, make, replace=()))
    return out


def same_motion(a: Controller, b: Controller, where: str) -> None:
    for name in ARRAYS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), f"{where}: {name}"
    for x, y in zip(a.axes, b.axes, strict=True):
        assert (x.state, x.motion_status, x.base) == (y.state, y.motion_status, y.base), where


def same_cams(batch: list[Process], seq: list[Process], where: str) -> None:
    for p, q in zip(batch, seq, strict=True):
        assert (p.lane is None) == (q.lane is None), where
        for r in (p, q):
            if r.lane is not None:
                r.lane.sync(r)  # the lane's values into the object (it stays in the lane)
        skip = {"lane", "profile"}  # (each controller has its own profile objects)
        left = {k: v for k, v in vars(p).items() if k not in skip}
        right = {k: v for k, v in vars(q).items() if k not in skip}
        assert left == right, where


@settings(max_examples=40, deadline=None)
@given(
    jogs=st.lists(st.integers(3, AXES), max_size=4),
    gears=st.lists(st.tuples(st.integers(3, AXES), st.integers(1, AXES)), max_size=5),
    before=st.lists(other, max_size=3),
    picks=st.lists(
        st.tuples(st.integers(3, AXES), st.integers(1, AXES + 4), st.integers(0, 2)),
        min_size=1,
        max_size=14,
    ),
    sets=st.lists(params, min_size=1, max_size=3),
    after=st.lists(other, max_size=3),
    reads=st.lists(st.tuples(st.integers(0, 39), st.integers(1, AXES)), max_size=4),
    snapshot=st.integers(0, 40),
    split=st.integers(0, 14),
)
def test_a_batch_as_rows_moves_as_the_cams_one_by_one(
    jogs: list[int],
    gears: list[tuple[int, int]],
    before: list[tuple[object, ...]],
    picks: list[tuple[int, int, int]],
    sets: list[Params],
    after: list[tuple[object, ...]],
    reads: list[tuple[int, int]],
    snapshot: int,
    split: int,
) -> None:
    batch, seq, ref = controller(True), controller(True), controller(False)
    ctls = (batch, seq, ref)
    for ctl in ctls:
        jog(ctl, 1, 100.0)
        jog(ctl, 2, -70.0)
        for n in jogs:
            jog(ctl, n, 20.0)
        for s, m in gears:
            if s != m and not ctl.axis(s).processes and not ctl.motion.would_cycle(s, (m,)):
                gear(ctl, s, m, MasterReference.COMMAND)
        ctl.run(20)
        for cmd in before:
            command(ctl, cmd)
    started: tuple[list[Process], list[Process], list[Process]] = ([], [], [])
    for part in (picks[:split], picks[split:]):  # one batch or two in the scan
        if part:
            started[0].extend(start_position_cams(batch, cam_starts(batch, part, sets)))
            started[1].extend(one_by_one(seq, cam_starts(seq, part, sets)))
            started[2].extend(one_by_one(ref, cam_starts(ref, part, sets)))
    for ctl in ctls:
        for cmd in after:
            command(ctl, cmd)
    same_motion(batch, ref, "started")
    same_cams(started[0], started[1], "started")
    for k in range(40):
        if k == snapshot:
            # the batch's controller copied (its cams with it) and run on from the copy
            batch, cams = statecodec.loads(statecodec.dumps((batch, started[0])))
            started = (cams, started[1], started[2])
        for cycle, n in reads:
            if cycle == k:
                for ctl in (batch, seq, ref):
                    ctl.settle(ctl.axis(n))
        for ctl in (batch, seq, ref):
            ctl.step()
        same_motion(batch, ref, f"cycle {k}")
        same_motion(batch, seq, f"cycle {k}")
        same_cams(started[0], started[1], f"cycle {k}")
    assert all(type(p) is CamProcess for p in started[0])


def test_the_usual_batch_is_neither_sorted_nor_levelled_again() -> None:
    """Every master jogging, every slave at rest (the bench's ``cam`` case): the cams
    join the cam lane with their levels, the composition order stays, and after one
    step every cam is in the lane, commanding what the cams one by one command."""
    batch, ref = controller(True), controller(False)
    starts = {}
    for ctl in (batch, ref):
        for n in range(1, 11):
            jog(ctl, n, 10.0 * n)
        ctl.run(10)
        prof = profiles()[0]
        starts[id(ctl)] = [
            CamStart(ctl.axis(10 + n), ctl.axis(n), prof, CamMode.CONTINUOUS, 1.0, 1.0, 0.0)
            for n in range(1, 11)
        ]
    cams = start_position_cams(batch, starts[id(batch)])
    one_by_one(ref, starts[id(ref)])
    lanes = batch.motion.lanes[1]
    assert not batch.motion.order_dirty  # the masters already compose before the slaves
    assert not lanes.dirty  # the followers are not levelled again
    assert lanes.handed  # the cams come with their levels (0: their masters jog)
    batch.step()
    ref.step()
    same_motion(batch, ref, "first step")
    lane = next(f for f in lanes.followers[MasterReference.COMMAND] if isinstance(f, CamLane))
    assert lane.members == cams
    assert lane.member_levels == [0] * 10


def test_a_follower_of_a_new_slave_and_a_chain_in_the_batch_get_their_levels() -> None:
    """A gear already in the lanes on a slave of the batch (at rest until then: its
    level 0) steps after that slave's cam from now on (level 1): the followers are
    levelled again. A cam whose master is another cam of the batch steps after it."""
    for follower in (True, False):
        batch, ref = controller(True), controller(False)
        for ctl in (batch, ref):
            jog(ctl, 1, 50.0)
            if follower:
                gear(ctl, 6, 4, MasterReference.COMMAND)
            ctl.run(10)
        cams = []
        for ctl in (batch, ref):
            prof = profiles()[0]
            starts = [
                CamStart(ctl.axis(4), ctl.axis(1), prof, CamMode.CONTINUOUS, 1.0, 1.0, 0.0),
                CamStart(ctl.axis(5), ctl.axis(4), prof, CamMode.CONTINUOUS, -0.5, 0.1, 0.0),
            ]
            cams.append(
                start_position_cams(ctl, starts) if ctl is batch else one_by_one(ctl, starts)
            )
        lanes = batch.motion.lanes[1]
        assert lanes.dirty is follower  # (without the follower: handed with the levels)
        for k in range(20):
            batch.step()
            ref.step()
            same_motion(batch, ref, f"cycle {k}")
        assert all(p.lane is not None for p in cams[0])
