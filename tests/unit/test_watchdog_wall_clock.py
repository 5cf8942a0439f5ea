"""The communication watchdog with the realtime clock: it times out T after the scan
received the last heartbeat, by the wall clock, and trips between cycles if that moment
falls between them, its state published at once (``Scan._watchdogs_due``).

The scan is served with a clock of its own (``Scan.rebase(now, clock)``), advanced by
hand. First principles: period 1 ms, T = 10 ms. A beat received at 0.4 ms is applied by
the cycle due at 1 ms (tick k) and runs out at 0.4 + 10 = 10.4 ms, while the count of
cycles would trip in the cycle due at 1 + 10 = 11 ms. The group stop ramps Axis1 from 10
mm/s at its maximum deceleration, 5,000 mm/s², 5 mm/s a cycle: at rest after two
cycles.
"""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.image import wire
from motion_server.safety.client import ClientInfo
from motion_server.safety.watchdog import WatchdogState
from motion_server.scan import Scan
from motion_server.scan.channel import MODBUS
from motion_server.tagmap import ClockMode

from .test_write_budget import SITE as WRITE_BUDGET_SITE
from .test_write_budget import FakeChannel

#: write_budget's map (Axis1 and Axis2 at 1 ms, MAJ_1 on Axis1 at 10 mm/s, the watchdog
#: HMI1 with T = 10 ms) on the realtime clock, the watchdog's stop a Fast Stop
SITE = (
    WRITE_BUDGET_SITE.format(budget="")
    .replace('clock = "manual"', 'clock = "realtime"')
    .replace('group = "Group1"\n', 'group = "Group1"\nstop_mode = "fast_stop"\n')
)

HMI = ClientInfo("modbus", "10.0.0.1", 50001, 1)


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class Served:
    """A scan on the realtime clock, Axis1 jogging at 10 mm/s, a channel for the beats."""

    def __init__(self) -> None:
        self.scan = scan = Scan(config.parse(SITE, "watchdog-wall-clock.toml"))
        scan.start(0.0)
        scan.ctl.servo_on(scan.ctl.axis(1))
        maj = scan.system["MAJ_1"]
        maj.inputs[maj.TRIGGER] = True
        scan.cycle(20)  # (cycles run whatever the clock: 10 mm/s at 1,000 mm/s² after 10)
        assert scan.ctl.axis(1).command_velocity == 10.0
        self.clock = Clock()
        scan.rebase(0.0, self.clock)
        self.channel = FakeChannel(MODBUS)
        scan.attach(self.channel)
        self.slot = {t.name: i for i, t in enumerate(scan.layout.tags)}
        self.seq = 0
        self.wd = scan.watchdogs["HMI1"]
        scan.service(0.0)  # the first cycle of the schedule; the next is due at 1 ms

    def at(self, t: float) -> float | None:
        """Serve the scan at ``t`` seconds (a microsecond later: the deadlines are sums
        of periods, not exact); when it asks to be served next."""
        self.clock.t = t + 1e-6
        return self.scan.service(t + 1e-6)

    def beat(self, value: int) -> None:
        self.seq += 1
        batch = wire.Batch(self.seq, HMI, [(self.slot["HMI1.Heartbeat"], float(value))])
        self.scan.deliver(self.channel, batch)

    def published_state(self) -> int:
        return int(self.scan.filler.values[self.slot["HMI1.State"]])


def test_the_watchdog_trips_t_after_the_beat_arrived_between_cycles() -> None:
    s = Served()
    s.clock.t = 0.0004
    s.beat(1)  # received at 0.4 ms
    assert s.at(0.0004) == pytest.approx(0.001, abs=1e-5)  # a beat waits for the cycle
    s.at(0.001)
    tick = s.scan.ctl.tick
    assert s.wd.state == WatchdogState.ARMED and s.wd.beats["*"][0] == tick - 1
    for k in range(2, 11):  # the cycles due at 2 ... 10 ms
        wake = s.at(k / 1000)
    assert s.wd.trips == 0
    # after the cycle due at 10 ms, the scan asks to be served when the beat runs out
    assert wake == pytest.approx(0.0104)
    ticks = s.scan.ctl.tick
    s.at(0.0104)
    assert s.wd.trips == 1 and s.wd.state == WatchdogState.STOPPING
    assert s.scan.ctl.tick == ticks  # between cycles: no cycle ran
    assert s.published_state() == int(WatchdogState.STOPPING)  # published at once
    # the next cycle steps the stop: 10 mm/s, 5 mm/s less a cycle
    s.at(0.011)
    assert s.scan.ctl.axis(1).command_velocity == pytest.approx(5.0)
    s.at(0.012)
    assert s.scan.ctl.axis(1).command_velocity == 0.0


def test_late_cycles_do_not_delay_the_trip() -> None:
    """The scan is not served from 1 ms to 25 ms (a stall): served again, it trips the
    watchdog first, then runs the cycles due."""
    s = Served()
    s.clock.t = 0.0004
    s.beat(1)
    s.at(0.001)
    ticks = s.scan.ctl.tick
    before = s.scan.ctl.axis(1).command_velocity
    s.at(0.025)
    assert s.wd.trips == 1
    assert before == 10.0 and s.scan.ctl.tick > ticks
    assert s.scan.ctl.axis(1).command_velocity == 0.0  # the catch-up cycles stopped it


def test_beats_keep_it_armed_and_the_count_of_cycles_stays_the_bound() -> None:
    """A beat every 5 ms holds it armed; with the clock leaving the wall clock the beat's
    arrival is forgotten, and the count of cycles alone decides (no trip by the wall
    clock however long the scan is not served)."""
    s = Served()
    for k in range(1, 40):
        if k % 5 == 0:
            s.clock.t = k / 1000 - 0.0002
            s.beat(k)
        s.at(k / 1000)
    assert s.wd.trips == 0 and s.wd.state == WatchdogState.ARMED
    assert s.wd.expiry() == pytest.approx(0.0348 + 0.01)  # the beat received at 34.8 ms
    s.scan.set_mode(ClockMode.MANUAL)
    assert s.wd.expiry() is None
    s.at(1.0)
    assert s.wd.trips == 0  # the manual clock: no cycle, no trip
