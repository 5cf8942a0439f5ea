"""MC_GearInPos: the seed's two examples, sync arrival, status sequences, input rules.

The slave follows the master's actual position (the seed's formula). A virtual master's
actual position is its command after the previous cycle, so each check compares the
slave with the master value the block saw: the master's actual before the cycle.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import AxisConfig, AxisType, MotionStatusBit, ProcessKind

from ..support import make_system, trigger

DT = 0.002
COUNT = 1e-3  # one encoder count of the slave (1000 counts per unit)


def system(rotary: bool = False) -> MotionSystem:
    rollover = 360.0 if rotary else 0.0
    s = make_system(
        AxisConfig(
            1,
            "Master",
            AxisType.VIRTUAL,
            rollover=rollover,
            max_velocity=5000.0,
            max_acceleration=1e5,
            max_deceleration=1e5,
        ),
        AxisConfig(
            2,
            "Slave",
            AxisType.SERVO,
            rollover=rollover,
            max_velocity=5000.0,
            max_acceleration=36000.0,
            max_deceleration=36000.0,
        ),
    )
    for n in (1, 2):
        s.ctl.servo_on(s.ctl.axis(n))
    return s


def move_to(s: MotionSystem, axis: int, position: float) -> None:
    m = s.add("MC_MoveAbsolute", f"Move{axis}_{len(s.instances)}", {})
    trigger(
        s,
        m,
        Axis=axis,
        Position=position,
        Velocity=1000.0,
        Acceleration=1e4,
        Deceleration=1e4,
        Direction=2,
    )
    m.inputs["Execute"] = False
    for _ in range(500):
        s.cycle()
        if not s.ctl.axis(axis).active():
            break
    s.cycle(100)  # let the servo's actual settle
    assert s.ctl.axis(axis).command_position == pytest.approx(position, abs=1e-9)


def jog(s: MotionSystem, speed: float, accel: float = 1e5, name: str = "Jog") -> Instruction:
    j = s.instances.get(name) or s.add("MAJ", name, {})
    trigger(
        s,
        j,
        Axis=1,
        Speed=abs(speed),
        Direction=1 if speed < 0 else 0,
        AccelRate=accel,
        DecelRate=accel,
    )
    j.inputs["Execute"] = False
    return j


def gear_in_pos(s: MotionSystem, name: str = "GIP", **operands: object) -> Instruction:
    ops: dict[str, object] = {"Master": 1, "Slave": 2}
    ops.update(operands)
    g = s.add("MC_GearInPos", name, {})
    trigger(s, g, **ops)
    return g


def master(s: MotionSystem) -> float:
    return s.ctl.axis(1).actual_position_unwound


def slave(s: MotionSystem) -> float:
    return s.ctl.axis(2).command_position_unwound


class Run:
    """Cycle the system and record what the block saw and did."""

    def __init__(self, s: MotionSystem, g: Instruction) -> None:
        self.s, self.g = s, g
        self.seen: list[float] = []  # master actual the block read in the cycle
        self.seen_v: list[float] = []
        self.slave: list[float] = []
        self.slave_v: list[float] = []
        self.status: list[tuple[bool, bool, int]] = []
        self.remaining: list[float] = []

    def cycle(self, n: int = 1) -> None:
        ax = self.s.ctl.axis(1)
        for _ in range(n):
            self.seen.append(ax.actual_position_unwound)
            self.seen_v.append(ax.actual_velocity)
            self.s.cycle()
            out = self.g.outputs
            self.slave.append(slave(self.s))
            self.slave_v.append(self.s.ctl.axis(2).command_velocity)
            self.status.append((out["StartSync"], out["InSync"], out["SyncState"]))
            self.remaining.append(out["RemainingMasterDistance"])

    def until_in_sync(self, limit: int = 5000) -> int:
        for _ in range(limit):
            self.cycle()
            if self.g.outputs["InSync"]:
                return len(self.seen) - 1
        raise AssertionError("never in sync")

    def check_arrival(self, k: int, master_sync: float, slave_sync: float, ratio: float) -> None:
        """At the master sync position the slave is at its sync position (within one
        count) with the geared velocity, and its slope over the master is the ratio."""
        m0, m1 = self.seen[k - 1], self.seen[k]
        s0, s1 = self.slave[k - 1], self.slave[k]
        assert (m0 - master_sync) * (m1 - master_sync) <= 0.0  # crossed in this cycle
        assert m1 != m0
        at_sync = s0 + (master_sync - m0) * (s1 - s0) / (m1 - m0)
        assert abs(at_sync - slave_sync) <= COUNT
        assert abs(s1 - (slave_sync + ratio * (m1 - master_sync))) <= COUNT
        assert self.slave_v[k] == pytest.approx(ratio * self.seen_v[k], rel=1e-12)
        assert (s1 - s0) / (m1 - m0) == pytest.approx(ratio, rel=1e-3)


def assert_sequence(status: list[tuple[bool, bool, int]]) -> tuple[int, int]:
    """Waiting, then synchronizing (StartSync), then in sync (InSync), never backwards."""
    start = next(i for i, st in enumerate(status) if st[0])
    sync = next(i for i, st in enumerate(status) if st[1])
    assert start <= sync
    assert all(st == (False, False, 0) for st in status[:start])
    assert all(st == (True, False, 1) for st in status[start:sync])
    assert all(st == (True, True, 2) for st in status[sync:])
    return start, sync


# -- the seed's examples ------------------------------------------------------------------


def test_rotary_example_master_0_slave_45_ratio_1_start_distance_90() -> None:
    """Rotary master and slave (360 rollover), master at 0, slave at 45, ratio 1:1,
    MasterStartDistance 90; sync positions master 0, slave 90. The master's next sync
    occurrence beyond 0 + 90 is 360: the lock-on begins at 270, the slave travels 45 to
    90 while the master covers the last 90."""
    s = system(rotary=True)
    move_to(s, 2, 45.0)
    assert master(s) == 0.0
    g = gear_in_pos(
        s,
        RatioNumerator=1,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=90.0,
        SyncMode=0,
        MasterStartDistance=90.0,
        BufferMode=1,
    )
    assert g.outputs["Busy"] and g.outputs["Active"] and not g.outputs["Error"]
    assert g.outputs["RemainingMasterDistance"] == 360.0
    jog(s, 180.0)
    r = Run(s, g)
    k = r.until_in_sync()
    r.cycle(400)
    start, sync = assert_sequence(r.status)
    assert sync == k
    assert r.seen[start - 1] < 270.0 <= r.seen[start]
    assert all(p == 45.0 for p in r.slave[: start - 1])  # the slave waits at rest
    r.check_arrival(k, 360.0, 90.0, 1.0)
    for i in range(sync):
        assert r.remaining[i] == pytest.approx(360.0 - r.seen[i])
    assert all(d == 0.0 for d in r.remaining[sync:])
    # once in sync, the wrapped positions keep the 90 degree phase
    ax = s.ctl.axis(2)
    assert ax.command_position == pytest.approx((r.seen[-1] + 90.0) % 360.0, abs=1e-9)
    assert not g.outputs["Warning"]
    assert s.ctl.axis(2).motion_status & (1 << 12)  # GearingLockStatus


def st_example(s: MotionSystem, master_at: float = -150.0, slave_at: float = -100.0) -> Instruction:
    """The seed's ST call: Inst_MC_GearInPos(Req, Axis1, Axis2, 2, 1, 0, 0, 0, 100.0, 1)."""
    move_to(s, 1, master_at)
    move_to(s, 2, slave_at)
    return gear_in_pos(
        s,
        RatioNumerator=2,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=0.0,
        SyncMode=0,
        MasterStartDistance=100.0,
        BufferMode=1,
    )


def test_structured_text_example_ratio_2_to_1_start_distance_100() -> None:
    s = system()
    g = st_example(s)
    assert g.outputs["Busy"] and not g.outputs["Error"]
    jog(s, 50.0)
    r = Run(s, g)
    k = r.until_in_sync()
    r.cycle(100)
    start, _ = assert_sequence(r.status)
    assert r.seen[start - 1] < -100.0 <= r.seen[start]
    r.check_arrival(k, 0.0, 0.0, 2.0)
    assert s.ctl.axis(2).command_velocity == pytest.approx(100.0)
    assert slave(s) == pytest.approx(2.0 * r.seen[-1], abs=1e-9)
    assert not g.outputs["Warning"]


def test_master_changing_speed_during_lock_on() -> None:
    s = system()
    g = st_example(s)
    jog(s, 50.0)
    r = Run(s, g)
    while not g.outputs["StartSync"]:
        r.cycle()
    while r.seen[-1] < -60.0:
        r.cycle()
    jog(s, 120.0, accel=500.0)  # 0.14 s of acceleration, during the lock-on
    k = r.until_in_sync()
    assert 50.0 < r.seen_v[k] <= 120.0  # still accelerating when it locks on
    r.check_arrival(k, 0.0, 0.0, 2.0)


def test_master_moving_negative_follows_the_denominator_sign() -> None:
    s = system()
    move_to(s, 1, 150.0)
    move_to(s, 2, -100.0)
    g = gear_in_pos(
        s,
        RatioNumerator=2,
        RatioDenominator=-1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=0.0,
        MasterStartDistance=100.0,
    )
    assert g.outputs["Busy"] and not g.outputs["Error"]
    jog(s, -50.0)
    r = Run(s, g)
    k = r.until_in_sync()
    start, _ = assert_sequence(r.status)
    assert r.seen[start - 1] > 100.0 >= r.seen[start]
    r.check_arrival(k, 0.0, 0.0, -2.0)
    assert r.slave_v[k] == pytest.approx(100.0)  # -2 x -50: the slave moves positive


# -- warnings and immediate mode ----------------------------------------------------------


def test_short_start_distance_warns(caplog: pytest.LogCaptureFixture) -> None:
    s = system()
    with caplog.at_level(logging.WARNING):
        g = st_example(s, slave_at=-300.0)  # 300 to go, 100 x 2 = 200 of master range
    assert g.outputs["Warning"] and g.outputs["Busy"]
    assert any("excessive lock-on acceleration" in rec.message for rec in caplog.records)
    jog(s, 50.0)
    r = Run(s, g)
    k = r.until_in_sync()
    r.check_arrival(k, 0.0, 0.0, 2.0)  # it still arrives


def test_immediate_mode_inside_the_start_distance_is_in_sync_at_once() -> None:
    """The seed, SyncMode 1: "If either the master or slave axis are beyond their
    respective sync start positions, the slave axis will immediately synchronize". The
    master, about -50 and jogging at 50 mm/s, is inside its 100 mm start distance before
    0: in sync in the scan the block starts, the slave's command on 0 + 2 x (master - 0),
    every cycle from then on. The slave was at -30, ahead of about -100: it moves
    backwards."""
    s = system()
    move_to(s, 1, -50.0)
    move_to(s, 2, -30.0)
    jog(s, 50.0)
    s.cycle(5)
    m_seen = master(s)
    g = gear_in_pos(
        s,
        RatioNumerator=2,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=0.0,
        SyncMode=1,
        MasterStartDistance=100.0,
    )
    out = g.outputs
    assert (out["StartSync"], out["InSync"], out["SyncState"]) == (True, True, 2)
    assert out["RemainingMasterDistance"] == 0.0 and out["Warning"]
    assert slave(s) == pytest.approx(2.0 * m_seen, abs=1e-9)
    r = Run(s, g)
    r.cycle(50)
    for k in range(50):
        assert r.slave[k] == pytest.approx(2.0 * r.seen[k], abs=1e-9)
        assert r.slave_v[k] == pytest.approx(2.0 * r.seen_v[k], rel=1e-12)
    assert all(st == (True, True, 2) for st in r.status)


def test_immediate_mode_beyond_the_sync_position_locks_at_once_with_a_warning() -> None:
    s = system()
    move_to(s, 1, 20.0)
    g = gear_in_pos(
        s,
        RatioNumerator=2,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=0.0,
        SyncMode=1,
        MasterStartDistance=0.0,
    )
    assert g.outputs["InSync"] and g.outputs["StartSync"] and g.outputs["Warning"]
    assert slave(s) == pytest.approx(2.0 * (master(s) - 0.0))


def test_immediate_mode_with_the_slave_beyond_its_sync_position_is_in_sync_at_once() -> None:
    """The seed, SyncMode 1: "If either the master or slave axis are beyond their
    respective sync start positions, the slave axis will immediately synchronize [...] If
    the slave axis is ahead of the master axis at the time of synchronization, the slave
    axis will move backwards." The master is 100 mm before its start point (-10), jogging
    at 50 mm/s; the slave, at 0, is 30 mm beyond its sync position -30: in sync in the scan
    the block starts, its command on -30 + (master - 0), about -150, and the servo moves
    backwards to it, then follows at the master's 50 mm/s."""
    s = system()
    move_to(s, 1, -120.0)
    jog(s, 50.0)
    s.cycle(5)
    m_seen = master(s)
    assert m_seen < -110.0  # far before the start point, -10
    g = gear_in_pos(
        s,
        RatioNumerator=1,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=-30.0,
        SyncMode=1,
        MasterStartDistance=10.0,
    )
    out = g.outputs
    assert (out["StartSync"], out["InSync"], out["SyncState"]) == (True, True, 2)
    assert out["RemainingMasterDistance"] == 0.0 and out["Warning"]
    assert slave(s) == pytest.approx(-30.0 + m_seen, abs=1e-9)
    ax = s.ctl.axis(2)
    assert ax.actual_velocity < 0.0  # the drive moves the slave backwards
    r = Run(s, g)
    backwards = []
    for _ in range(250):
        r.cycle()
        backwards.append(ax.actual_velocity)
    for k in range(250):
        assert r.slave[k] == pytest.approx(-30.0 + r.seen[k], abs=1e-9)
    assert min(backwards) < -50.0  # it ran back, faster than the master runs forward
    # after 0.5 s the drive (bandwidth 40 Hz) follows at 50 mm/s, lagging by 2v/w
    assert ax.actual_velocity == pytest.approx(50.0, rel=1e-3)
    lag = 2.0 * 50.0 / (2.0 * np.pi * 40.0)
    assert ax.actual_position == pytest.approx(ax.command_position - lag, abs=2 * COUNT)
    # SyncMode 0 refuses the same inputs (the slave must be before its sync position)
    s2 = system()
    move_to(s2, 1, -120.0)
    g2 = gear_in_pos(
        s2,
        RatioNumerator=1,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=-30.0,
        SyncMode=0,
        MasterStartDistance=10.0,
    )
    assert g2.outputs["Error"] and g2.outputs["ErrorID"] == 13


def test_immediate_mode_with_zero_start_distance_syncs_when_the_master_crosses() -> None:
    s = system()
    move_to(s, 1, -20.0)
    g = gear_in_pos(
        s,
        RatioNumerator=1,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=5.0,
        SyncMode=1,
        MasterStartDistance=0.0,
    )
    jog(s, 50.0)
    r = Run(s, g)
    k = r.until_in_sync()
    start, sync = assert_sequence(r.status)
    assert start == sync == k and r.seen[k - 1] < 0.0 <= r.seen[k]
    assert all(p == 0.0 for p in r.slave[:k])
    assert r.slave[k] == pytest.approx(5.0 + r.seen[k])
    assert g.outputs["Warning"]


# -- inconsistent inputs ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("master_at", "slave_at", "operands"),
    [
        (-50.0, -100.0, {}),  # the master is already inside the start distance
        (-100.0, -100.0, {}),  # exactly at it: "greater than" fails
        (-150.0, 10.0, {}),  # the slave is beyond its sync position
        (-150.0, 0.0, {}),  # ... or at it
        (-150.0, -100.0, {"MasterStartDistance": 0.0}),
        (-150.0, -100.0, {"MasterStartDistance": -5.0}),
        (-150.0, -100.0, {"RatioNumerator": 0}),
        (-150.0, -100.0, {"RatioDenominator": 0}),
        (-150.0, -100.0, {"SyncMode": 2}),
        (-150.0, -100.0, {"MasterSyncPosition": float("nan")}),
        (150.0, -100.0, {"RatioDenominator": -1, "MasterStartDistance": 200.0}),
    ],
)
def test_inconsistent_inputs_error_13_and_no_motion(
    master_at: float, slave_at: float, operands: dict[str, object]
) -> None:
    s = system()
    move_to(s, 1, master_at)
    move_to(s, 2, slave_at)
    ops: dict[str, object] = {
        "RatioNumerator": 2,
        "RatioDenominator": 1,
        "MasterSyncPosition": 0.0,
        "SlaveSyncPosition": 0.0,
        "MasterStartDistance": 100.0,
    }
    ops.update(operands)
    g = gear_in_pos(s, **ops)
    assert g.outputs["Error"] and g.outputs["ErrorID"] == 13
    assert not g.outputs["Busy"] and not g.outputs["StartSync"]
    jog(s, 50.0)
    before = slave(s)
    s.cycle(200)
    assert slave(s) == before and s.ctl.axis(2).active() == []


def test_start_distance_must_exceed_the_masters_travel_per_update() -> None:
    s = system()
    move_to(s, 1, -150.0)
    move_to(s, 2, -100.0)
    jog(s, 50.0)  # 0.1 units per 2 ms update
    s.cycle(5)
    common = dict(RatioNumerator=2, RatioDenominator=1, SlaveSyncPosition=0.0)
    g = gear_in_pos(s, "short", MasterSyncPosition=0.0, MasterStartDistance=0.05, **common)
    assert g.outputs["Error"] and g.outputs["ErrorID"] == 13
    g = gear_in_pos(s, "ok", MasterSyncPosition=0.0, MasterStartDistance=0.5, **common)
    assert g.outputs["Busy"] and not g.outputs["Error"]


def test_rotary_axes_reject_immediate_mode_and_out_of_range_sync_positions() -> None:
    s = system(rotary=True)
    common = dict(RatioNumerator=1, RatioDenominator=1, MasterStartDistance=90.0)
    g = gear_in_pos(s, "imm", MasterSyncPosition=0.0, SlaveSyncPosition=90.0, SyncMode=1, **common)
    assert g.outputs["ErrorID"] == 13
    g = gear_in_pos(s, "range", MasterSyncPosition=400.0, SlaveSyncPosition=90.0, **common)
    assert g.outputs["ErrorID"] == 13
    g = gear_in_pos(s, "slave", MasterSyncPosition=0.0, SlaveSyncPosition=-1.0, **common)
    assert g.outputs["ErrorID"] == 13
    assert s.ctl.axis(2).active() == []


def test_buffered_behind_a_move_is_judged_when_it_starts() -> None:
    s = system()
    move_to(s, 1, -150.0)
    move_to(s, 2, -100.0)
    m = s.add("MC_MoveAbsolute", "Move", {})
    trigger(s, m, Axis=2, Position=10.0, Velocity=200.0, Acceleration=1e4, Deceleration=1e4)
    g = gear_in_pos(
        s,
        RatioNumerator=2,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=0.0,
        MasterStartDistance=100.0,
        BufferMode=1,
    )
    assert g.outputs["Busy"] and not g.outputs["Active"]  # waiting for the move
    for _ in range(400):
        s.cycle()
        if g.outputs["Error"]:
            break
    # the move ended beyond the slave sync position: inconsistent when it starts
    assert g.outputs["Error"] and g.outputs["ErrorID"] == 13 and m.outputs["Done"]
    s.cycle(20)
    assert slave(s) == pytest.approx(10.0) and s.ctl.axis(2).active() == []


# -- being taken over ---------------------------------------------------------------------


def test_command_aborted_when_mc_stop_takes_over() -> None:
    s = system()
    g = st_example(s)
    jog(s, 50.0)
    Run(s, g).until_in_sync()
    stop = s.add("MC_Stop", "Stop", {})
    trigger(s, stop, Axis=2, Deceleration=5000.0)
    out = g.outputs
    assert out["CommandAborted"] and not out["Busy"] and not out["InSync"]
    assert (out["StartSync"], out["SyncState"], out["RemainingMasterDistance"]) == (False, 0, 0.0)
    assert s.ctl.axis(2).active(ProcessKind.GEAR) == []


def test_command_aborted_when_an_aborting_gear_in_takes_over_during_lock_on() -> None:
    s = system()
    g = st_example(s)
    jog(s, 50.0)
    r = Run(s, g)
    while not g.outputs["StartSync"]:
        r.cycle()
    r.cycle(10)
    v = s.ctl.axis(2).command_velocity
    gi = s.add("MC_GearIn", "GearIn", {})
    trigger(s, gi, Master=1, Slave=2, Acceleration=1000.0, Deceleration=1000.0, BufferMode=0)
    assert g.outputs["CommandAborted"] and gi.outputs["Busy"]
    # the new gear inherits the velocity: no step
    assert abs(s.ctl.axis(2).command_velocity - v) <= 1000.0 * DT + 1e-9


def test_slave_acceleration_during_lock_on_is_smooth() -> None:
    """The quintic has zero curvature at both ends: the slave's acceleration starts and
    ends at about zero (master at constant speed) instead of stepping."""
    s = system()
    g = st_example(s)
    jog(s, 50.0)
    r = Run(s, g)
    r.until_in_sync()
    r.cycle(10)
    start, sync = assert_sequence(r.status)
    a = np.diff(np.array(r.slave_v)) / DT
    peak = np.max(np.abs(a))
    assert abs(a[start]) < 0.05 * peak
    assert abs(a[sync - 1]) < 0.05 * peak and np.all(np.abs(a[sync + 1 :]) < 1e-6)


def test_the_status_arrays_show_the_lock_in_the_cycle_it_happens() -> None:
    """Composition in Python marks an axis's status stale only when a step changes it:
    the cycle the slave reaches sync, ``status_arrays()`` shows GearingLockStatus as the
    axis property does, and in steady gearing a cycle leaves no axis to re-derive."""
    s = system()
    st_example(s)
    jog(s, 50.0)
    ctl = s.ctl
    lock = 1 << MotionStatusBit.GEARING_LOCK
    s.cycle(20)
    for _ in range(5000):
        ctl.status_arrays()
        s.cycle()
        word = int(ctl.status_arrays().motion_status[1])
        assert word == ctl.axis(2).motion_status
        if word & lock:
            break
    else:
        pytest.fail("the slave never reached sync")
    for _ in range(10):
        s.cycle()
        assert ctl.arrays.dirty == set()
        assert int(ctl.status_arrays().motion_status[1]) == ctl.axis(2).motion_status
