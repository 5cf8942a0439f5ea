"""Gears started on many slaves in one call (``Controller.start_gears``): the same state as
``Controller.start`` with MAG's factory on each slave in order, attribute by attribute,
and the same motion after every step, lanes on and off (the reference composes every
axis in Python); a refusal stops at the same slave; the lanes' first rebuild after a
batch whose levels are known does not level the followers again, and levels them when a
follower reads a slave of the batch."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    JogProcess,
    Limits,
    ProcessKind,
)
from motion_server.kernel.axis import Axis
from motion_server.kernel.errors import MotionError
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterReference, RateRamp
from motion_server.kernel.lanes.gears import CatchUpLane, GearLane
from motion_server.scan import statecodec

from .test_jog_batch import count_built

#: group 1: axes 1-4 virtual, 5-10 servo; group 2: axes 11 (virtual) and 12 (servo)
N = 12
PERIOD = 0.002
GEAR = (ProcessKind.GEAR,)


def controller(lanes: bool) -> Controller:
    cfg = [
        AxisConfig(n, f"A{n}", AxisType.VIRTUAL if n <= 4 or n == 11 else AxisType.SERVO,
                   max_acceleration=5000.0, max_deceleration=5000.0,
                   following_error_limit=1e9, conversion_constant=1000.0 + 10 * n)
        for n in range(1, N + 1)
    ]  # fmt: skip
    groups = [
        GroupConfig(1, "G1", tuple(range(1, 11)), PERIOD),
        GroupConfig(2, "G2", (11, 12), PERIOD),
    ]
    ctl = Controller(cfg, groups, lanes=lanes)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    return ctl


def mag(ctl: Controller, slave: Axis, term: GearTerm, rate: Any, owner: object,
        direction: int) -> Any:  # fmt: skip
    """MAG's factory (``instructions/logix/mag.py``): the ramp, then the gear; with a
    pair for the rate, MC_GearIn's (``RateRamp(acceleration, deceleration)``)."""

    def make(v: float, a: float) -> GearProcess:
        if rate is None:
            ramp = None
        elif isinstance(rate, tuple):
            ramp = RateRamp(*rate)
        else:
            ramp = RateRamp(rate)
        return GearProcess(ctl, slave, (term,), ramp, v, a, owner=owner, direction=direction)

    return make


def jog(ctl: Controller, n: int, speed: float) -> None:
    ctl.start(
        ctl.axis(n),
        lambda v, a: JogProcess(PERIOD, speed, Limits(200.0, 800.0, 800.0), v, a),
        replace=(ProcessKind.JOG,),
    )


def coupling_state(ctl: Controller, c: Any) -> dict[str, object]:
    out: dict[str, object] = {}
    arrays = {id(getattr(ctl.arrays, name)): name for name in ("cmd_pos", "cmd_vel", "cmd_acc",
                                                              "act_pos", "act_vel")}  # fmt: skip
    for name in type(c).__slots__:
        x = getattr(c, name)
        out[name] = arrays.get(id(x), "?") if isinstance(x, np.ndarray) else x
    return out


def state(ctl: Controller, p: object, laned: bool = True) -> str:
    """A process's attributes (its coupling's and ramp's expanded, its lane by kind, its
    owner left out), as text: floats by their bits (-0.0 and NaN alike). ``laned``
    False: without what only the lanes set (the lane, whether it was offered)."""
    out = dict(vars(p))
    out.pop("owner", None)
    out["lane"] = type(out.pop("lane", None)).__name__
    if not laned:
        out.pop("lane")
        out.pop("offer_pending", None)
        out.pop("status_changed", None)
    if isinstance(p, GearProcess):
        out["_c"] = [coupling_state(ctl, c) for c in p._c]
        out["single"] = None if p.single is None else "c0"
        out["_ramp"] = None if p.ramp is None else sorted(vars(p.ramp).items())
    if "profile" in out:
        out["profile"] = sorted(vars(out["profile"]).items())
    return repr(sorted(out.items(), key=lambda kv: kv[0]))


def kinematics(p: Any) -> tuple[object, ...]:
    return p.position, p.velocity, p.acceleration, p.state, type(p)


def assert_same_processes(a: Controller, b: Controller, laned: bool = True) -> None:
    for x, y in zip(a.axes, b.axes, strict=True):
        assert x.gear_direction == y.gear_direction, x.name
        assert len(x.processes) == len(y.processes), x.name
        for p, q in zip(x.processes, y.processes, strict=True):
            assert p.owner is q.owner or (type(p.owner) is type(q.owner) is int), x.name
            if laned or isinstance(p, GearProcess):
                assert state(a, p, laned) == state(b, q, laned), x.name
            else:  # (a jog's profile holds its plan as the lanes or Python built it)
                assert repr(kinematics(p)) == repr(kinematics(q)), x.name


def assert_same_motion(ctls: dict[str, Controller], where: object) -> None:
    first = ctls["batch"]
    for name, ctl in ctls.items():
        for arr in ("cmd_pos", "cmd_vel", "cmd_acc"):
            assert getattr(first, arr).tobytes() == getattr(ctl, arr).tobytes(), (name, arr, where)


# one gear of the batch: (slave, master, ratio, clutch rate, reference, direction); the
# parameters drawn from few values, so that gears alike (copied from the first) are
# common, and refusals rare enough that most batches go on after them
VALID_RATIOS = [(50_000, 100_000, False), (-3, 2, False), (1, 3, False), (7, 5, True),
                (-4, 3, True), (0.5, 1, False), (1.0, 3.0, False)]  # fmt: skip
REFUSED_RATIOS = [(0, 1, False), (1, 0, False), (float("nan"), 1, False), (1.5, 2, True),
                  (3, -1, True), (5e6, 1, False)]  # fmt: skip
ratios = st.sampled_from([*VALID_RATIOS * 6, *REFUSED_RATIOS])
rates = st.sampled_from(
    [None] * 6
    + [1000.0] * 6
    + [250.0, 3000, 0.0, float("inf")]
    # MC_GearIn's catch-up: (acceleration, deceleration)
    + [(1000.0, 250.0)] * 4
    + [(800.0, 800.0), (0.0, 100.0), (100.0, float("nan"))]
)
gears = st.tuples(
    st.integers(5, 12),
    st.sampled_from([1, 2, 3, 4, 5, 6, 11, 12] * 4 + [99]),
    ratios,
    rates,
    st.sampled_from([MasterReference.COMMAND, MasterReference.COMMAND, MasterReference.ACTUAL]),
    st.sampled_from([1, -1]),
)


def acyclic(pairs: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """The (slave, master) links of ``pairs`` that close no loop with those kept before
    (the instructions refuse the others: ERR 10)."""
    kept: list[tuple[int, int]] = []

    def reaches(a: int, b: int) -> bool:
        frontier, seen = [a], set()
        while frontier:
            x = frontier.pop()
            if x == b:
                return True
            if x not in seen:
                seen.add(x)
                frontier += [m for s, m in kept if s == x]
        return False

    for s, m in pairs:
        if s != m and not reaches(m, s):
            kept.append((s, m))
    return kept


@settings(max_examples=150, deadline=None)
@given(
    jogging=st.lists(st.sampled_from([1, 2, 3, 4, 5, 6, 11]), max_size=5, unique=True),
    before=st.lists(st.tuples(st.integers(5, 12), st.sampled_from([1, 2, 3, 4, 5, 6, 7, 11])),
                    max_size=4),
    batch=st.lists(gears, min_size=1, max_size=10),
    settle=st.integers(0, 40),
    steps=st.integers(1, 120),
    reads=st.lists(st.tuples(st.integers(0, 120), st.integers(1, N)), max_size=4),
    snapshot=st.booleans(),
    alike=st.booleans(),
    aborting=st.booleans(),
)  # fmt: skip
def test_start_gears_is_start_on_each_slave_in_order(
    jogging: list[int],
    before: list[tuple[int, int]],
    batch: list[tuple[Any, ...]],
    settle: int,
    steps: int,
    reads: list[tuple[int, int]],
    snapshot: bool,
    alike: bool,
    aborting: bool,
) -> None:
    """MAG's gears (replacing a gear) and, ``aborting``, MC_GearIn's (replacing every
    process: a jogging slave's jog too)."""
    replace = None if aborting else GEAR
    if alike:  # every gear with the first one's parameters (its master and slave apart)
        batch = [(g[0], g[1], *batch[0][2:]) for g in batch]
    ctls = {"batch": controller(True), "loop": controller(True), "ref": controller(False)}
    before = acyclic(before)
    links = acyclic([*before, *((g[0], g[1]) for g in batch if g[1] != 99)])
    allowed = set(links[len(before) :]) if links[: len(before)] == before else set()
    batch = [g for g in batch if g[1] == 99 or (g[0], g[1]) in allowed]
    for ctl in ctls.values():
        for k, n in enumerate(jogging):
            jog(ctl, n, 30.0 + 20.0 * k)
        for s, m in before:
            term = GearTerm(m, MasterReference.COMMAND, 1, 2)
            ctl.start(ctl.axis(s), mag(ctl, ctl.axis(s), term, None, None, 1), GEAR)
        ctl.run(settle)
    owners = list(range(len(batch)))
    errors: dict[str, int | None] = {}
    for name, ctl in ctls.items():
        errors[name] = None
        slaves = [ctl.axis(g[0]) for g in batch]
        terms = [GearTerm(g[1], g[4], g[2][0], g[2][1], counts=g[2][2]) for g in batch]
        rates_ = [g[3] for g in batch]
        dirs = [g[5] for g in batch]
        if name == "batch":
            try:
                ctl.start_gears(slaves, terms, rates_, owners, dirs, replace)
            except MotionError as exc:
                errors[name] = int(exc.code)
        else:
            for ax, term, rate, owner, d in zip(slaves, terms, rates_, owners, dirs, strict=True):
                try:
                    ctl.start(ax, mag(ctl, ax, term, rate, owner, d), replace=replace)
                except MotionError as exc:
                    errors[name] = int(exc.code)
                    break
    assert errors["batch"] == errors["loop"] == errors["ref"]
    assert_same_processes(ctls["batch"], ctls["loop"])
    if snapshot:
        # a snapshot taken before the lanes took the batch (its levels kept by identity)
        ctls["copy"] = statecodec.loads(statecodec.dumps(ctls["batch"]))
    for c in range(steps):
        for ctl in ctls.values():
            ctl.step()
        assert_same_motion(ctls, c)
        for when, n in reads:
            if when == c:
                # an axis's processes read (and taken out of its lane) at any moment
                for ctl in ctls.values():
                    ctl.settle(ctl.axis(n))
                assert_same_processes(ctls["batch"], ctls["loop"], laned=False)
    # once stepped, the lanes' own flags (offer_pending, status_changed) depend on the
    # path their rebuilds took (a follower levelled alone or the whole group again),
    # not on how the gears were started: what must agree is every other attribute (above
    # and below) and the status the scan publishes, after the last step
    assert_same_processes(ctls["batch"], ctls["loop"], laned=False)
    status = [[a.tobytes() for a in ctl.status_arrays()] for ctl in ctls.values()]
    assert all(s == status[0] for s in status), "status arrays"
    for ctl in ctls.values():
        for ax in ctl.axes:
            ctl.settle(ax)  # the lanes' values written back
    assert_same_processes(ctls["batch"], ctls["ref"], laned=False)


def bench_like(lanes: bool) -> Controller:
    """Masters 1-4 jogging (in the cruise lane), servo slaves 5-10 without motion."""
    ctl = controller(lanes)
    for n in range(1, 5):
        jog(ctl, n, 100.0)
    ctl.run(100)
    return ctl


def test_a_batch_of_gears_on_jogging_masters_keeps_the_followers_levels() -> None:
    """Every gear reads a master in a time-driven lane and no follower reads a slave:
    they join at level 0 (handed over, not levelled again), their columns taken as a
    batch; the motion is the reference's."""
    for rate in (1000.0, None):
        ctl, ref = bench_like(True), bench_like(False)
        for c in (ctl, ref):
            slaves = [c.axis(n) for n in range(5, 11)]
            terms = [GearTerm((n - 5) % 4 + 1, MasterReference.COMMAND, 1, 2) for n in range(5, 11)]
            c.start_gears(slaves, terms, [rate] * 6)
        lanes = ctl.motion.lanes[1]
        lane = next(
            x
            for x in lanes.followers[MasterReference.COMMAND]
            if type(x) is (CatchUpLane if rate else GearLane)
        )
        assert lanes.handed and not lanes.dirty
        assert lane._batch is not None and lane._batch[1] == 6
        for k in range(400):
            ctl.step()
            ref.step()
            assert ctl.cmd_pos.tobytes() == ref.cmd_pos.tobytes(), k
            assert ctl.cmd_vel.tobytes() == ref.cmd_vel.tobytes(), k
        assert sum(len(x.members) for x in lanes.followers[MasterReference.COMMAND]) == 6


def test_a_follower_reading_a_slave_of_the_batch_is_levelled_again() -> None:
    """Axis 6 follows axis 5 (without motion: level 0); a batch gears 5 to a jogging
    master: 6 must now step after 5 (level 1), so the followers are levelled again."""
    ctls = (bench_like(True), bench_like(False))
    for c in ctls:
        c.start(c.axis(6), mag(c, c.axis(6), GearTerm(5, MasterReference.COMMAND, 2, 1), None,
                               None, 1), GEAR)  # fmt: skip
        c.run(3)
        c.start_gears([c.axis(5)], [GearTerm(1, MasterReference.COMMAND, 1, 2)], [500.0])
    lanes = ctls[0].motion.lanes[1]
    assert lanes.dirty
    for k in range(300):
        for c in ctls:
            c.step()
        assert ctls[0].cmd_pos.tobytes() == ctls[1].cmd_pos.tobytes(), k
    assert ctls[0].cmd_pos[5] != 0.0


def test_gears_at_a_new_ratio_on_geared_slaves_catch_up_and_lock(monkeypatch: Any) -> None:
    """Masters 1-4 jogging at 100 mm/s, slaves 5-10 geared at 1/2 (locked, 50 mm/s); a
    batch gears them again at 1/4 with the clutch at 500 mm/s²: each new gear is built
    from the slave's 50 mm/s (one built per set of parameters, the others copied), reads
    the same master, so the composition order stands; the motion is the loop's and the
    reference's step by step, and each slave ends locked at 25 mm/s, a quarter of its
    master's speed (50 to 25 mm/s at 500 mm/s² is 0.05 s: locked well within 0.4 s)."""
    ctls = {"batch": bench_like(True), "loop": bench_like(True), "ref": bench_like(False)}
    for c in ctls.values():
        for n in range(5, 11):
            term = GearTerm((n - 5) % 4 + 1, MasterReference.COMMAND, 1, 2)
            c.start(c.axis(n), mag(c, c.axis(n), term, None, None, 1), GEAR)
        c.run(50)
    for name, c in ctls.items():
        slaves = [c.axis(n) for n in range(5, 11)]
        terms = [GearTerm((n - 5) % 4 + 1, MasterReference.COMMAND, 1, 4) for n in range(5, 11)]
        if name == "batch":
            # (the velocity each gear starts from)
            built = count_built(monkeypatch, GearProcess, lambda args: args[4])
            c.start_gears(slaves, terms, [500.0] * 6)
            monkeypatch.undo()
            assert built == [50.0]
            assert not c.motion.order_dirty
        else:
            for ax, term in zip(slaves, terms, strict=True):
                c.start(ax, mag(c, ax, term, 500.0, None, 1), GEAR)
    assert_same_processes(ctls["batch"], ctls["loop"])
    for k in range(200):
        for c in ctls.values():
            c.step()
        assert_same_motion(ctls, k)
    for n in range(5, 11):
        ax = ctls["batch"].axis(n)
        assert ax.processes[0].locked
        assert ax.command_velocity == 25.0
