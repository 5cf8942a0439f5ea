"""Communication watchdogs: stop a group when a client's heartbeat stops.

A site map names a watchdog (``[[watchdogs]]``) with a timeout T, a group and a stop mode.
Its tags (``<name>.Heartbeat``, ``.Reset``, ``.Fault``, ``.State``, ``.Trips``, ``.Age``)
live in the Safety folder. Rules:

- **Arming.** The watchdog is idle until the heartbeat first changes; from then on it must
  change at least every T. ``per_connection``: every client connection that changed it is
  supervised on its own (a second HMI cannot keep a dead one alive), and a connection that
  closes stays supervised, so it trips T after its last beat. Otherwise any change by
  anyone counts.
- **Time.** T is measured in simulated time, counted in whole cycles:
  ``ceil(T / period)``. A beat written between cycles k-1 and k is stamped with cycle k;
  before every cycle the watchdog checks, and the cycle that starts T after the last beat
  runs the stop. So the stop starts within T plus one cycle, deterministically with the
  manual clock. With the realtime clock a beat also keeps the wall-clock time the scan
  received it (:func:`arriving_at`), and the scan trips the watchdog T after that,
  between cycles if that moment falls between them (:meth:`Watchdog.due`): the stop is
  commanded T after the beat arrived, whatever the cycle's phase, and late or dropped
  cycles do not delay it; the next cycle steps it. The count of cycles stays as the
  bound (and is the only one with the other clocks).
- **Reaction.** An MGS of the group: programmed (each axis's own stop mode), fast stop or
  fast disable. When the group has stopped, the latch: every non-feedback axis of the
  group is faulted with :data:`WATCHDOG_FAULT` (AxisFault bit 2, drive off), and the
  watchdog's ``Fault`` stays set.
- **No restart by itself.** A heartbeat that comes back changes nothing. Only an explicit
  reset clears the fault: a rising edge of ``<name>.Reset`` (fault-resets the axes), or
  MAFR / MC_Reset on every faulted axis. Then the axes are in Axis Ready: MSO / MC_Power
  enables them again, and the watchdog re-arms on the next beat. A reset while the group
  is still stopping is ignored.
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Iterator
from contextvars import ContextVar
from enum import IntEnum

from ..config import WatchdogSection
from ..instructions.logix.mgs import FORCED, MGSStopMode
from ..kernel import (
    AxisType,
    Controller,
    GroupStop,
    MotionError,
    ProgrammedStopMode,
    TransitionError,
)
from ..tagmap.codec import Value
from ..tagmap.image import Getter, Setter
from .client import current_client

log = logging.getLogger("motion_server.watchdog")

#: AxisFault bit of a watchdog trip (communication loss)
WATCHDOG_FAULT = 1 << 2

_ARRIVED: ContextVar[float | None] = ContextVar("motion_server_beat_arrived", default=None)


@contextlib.contextmanager
def arriving_at(when: float) -> Iterator[None]:
    """The heartbeats written in this block arrived at ``when`` (seconds of the clock
    the scan is served with, ``time.monotonic`` in its process): the scan says so while
    its clock is the wall clock."""
    token = _ARRIVED.set(when)
    try:
        yield
    finally:
        _ARRIVED.reset(token)


class WatchdogState(IntEnum):
    """``<name>.State``."""

    IDLE = 0
    ARMED = 1
    STOPPING = 2
    FAULTED = 3


class WatchdogEvent(IntEnum):
    BEAT = 0
    EXPIRE = 1
    STOPPED = 2
    RESET = 3
    CLEARED = 4


S, E = WatchdogState, WatchdogEvent
#: (state, event) -> next state; a pair missing here is a bug (TransitionError)
TRANSITIONS: dict[tuple[WatchdogState, WatchdogEvent], WatchdogState] = {
    (S.IDLE, E.BEAT): S.ARMED,
    (S.IDLE, E.RESET): S.IDLE,
    (S.ARMED, E.BEAT): S.ARMED,
    (S.ARMED, E.EXPIRE): S.STOPPING,
    (S.ARMED, E.RESET): S.ARMED,
    (S.STOPPING, E.BEAT): S.STOPPING,
    (S.STOPPING, E.RESET): S.STOPPING,  # ignored: the stop must finish first
    (S.STOPPING, E.STOPPED): S.FAULTED,
    (S.FAULTED, E.BEAT): S.FAULTED,  # the client came back: still latched
    (S.FAULTED, E.RESET): S.IDLE,
    (S.FAULTED, E.CLEARED): S.IDLE,
}
del S, E

STOP_MODES = {
    "programmed": MGSStopMode.PROGRAMMED,
    "fast_stop": MGSStopMode.FAST_STOP,
    "fast_disable": MGSStopMode.FAST_DISABLE,
}


class Watchdog:
    """One configured watchdog on a controller. The runtime calls :meth:`check` before
    every cycle; the tag image binds :meth:`bindings`."""

    def __init__(self, config: WatchdogSection, ctl: Controller) -> None:
        self.config = config
        self.name = config.name
        self.ctl = ctl
        self.group = ctl.group(config.group)
        self.stop_mode = STOP_MODES[config.stop_mode]
        self.timeout_cycles = max(1, math.ceil(config.timeout / ctl.period - 1e-9))
        self.state = WatchdogState.IDLE
        self.trips = 0
        self.heartbeat = 0
        self.reset_input = False
        #: supervised sources: key -> (cycle of the last change, last value)
        self.beats: dict[str, tuple[int, int]] = {}
        #: key -> when the scan received its last change (its clock's seconds), for the
        #: sources whose last change came with the wall clock (:func:`arriving_at`)
        self.arrivals: dict[str, float] = {}
        self.stop: GroupStop | None = None

    # -- snapshots ------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, object]:
        """Its state without its configuration (the site map's: a restore attaches it
        again with :meth:`configure`) nor the wall-clock times of the beats (another
        process's clock: the count of cycles goes on alone)."""
        return {k: v for k, v in self.__dict__.items() if k not in ("config", "arrivals")}

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self.arrivals = {}

    def configure(self, config: WatchdogSection) -> None:
        """Attach the configuration of a watchdog loaded from a snapshot."""
        if config.name != self.name:
            raise ValueError(f"watchdog {self.name} is not {config.name}")
        self.config = config

    # -- events ---------------------------------------------------------------------------
    def fire(self, event: WatchdogEvent) -> WatchdogState:
        nxt = TRANSITIONS.get((self.state, event))
        if nxt is None:
            raise TransitionError(f"watchdog {self.name}", self.state, event)
        self.state = nxt
        return nxt

    @property
    def fault(self) -> bool:
        return self.state in (WatchdogState.STOPPING, WatchdogState.FAULTED)

    def age(self) -> int:
        """Cycles since the oldest supervised beat (0 when nothing is supervised)."""
        if not self.beats:
            return 0
        return max(0, self.ctl.tick - min(t for t, _ in self.beats.values()))

    def beat(self, value: int) -> None:
        """A write of the heartbeat tag (by :func:`current_client`)."""
        if self.config.per_connection:
            key = current_client().key
            previous = self.beats.get(key)
            changed = previous is None or previous[1] != value
        else:
            key, changed = "*", value != self.heartbeat
        self.heartbeat = value
        if not changed:
            return
        # stamped with the cycle that runs next (the write lands between cycles)
        self.beats[key] = (self.ctl.tick, value)
        arrived = _ARRIVED.get()
        if arrived is None:
            self.arrivals.pop(key, None)
        else:
            self.arrivals[key] = arrived
        self.fire(WatchdogEvent.BEAT)

    def expiry(self) -> float | None:
        """When (the scan's clock) the armed watchdog runs out T after the oldest
        supervised beat, if every one came with the wall clock; else None (the count of
        cycles alone decides)."""
        if self.state != WatchdogState.ARMED or len(self.arrivals) != len(self.beats):
            return None
        return min(self.arrivals.values()) + self.config.timeout

    def due(self, now: float) -> bool:
        """Trip if the wall clock says the timeout has run out at ``now``; True if it
        tripped."""
        expiry = self.expiry()
        if expiry is None or now < expiry:
            return False
        self.trip()
        return True

    def _forget_beats(self) -> None:
        """No supervised source has beaten yet (a reset, the latch cleared)."""
        self.beats.clear()
        self.arrivals.clear()

    def forget_arrivals(self) -> None:
        """The clock stopped following the wall clock (or starts again): the beats'
        arrival times no longer count, the count of cycles does."""
        self.arrivals.clear()

    def set_reset(self, value: bool) -> None:
        rising = value and not self.reset_input
        self.reset_input = value
        if rising:
            self.reset()

    def reset(self) -> None:
        """The explicit reset: clear the latch and the axes' watchdog faults."""
        if self.state == WatchdogState.FAULTED:
            self.ctl.fault_reset_axes([ax for ax in self.group.axes if ax.fault & WATCHDOG_FAULT])
            self._forget_beats()
        self.fire(WatchdogEvent.RESET)

    # -- the cycle ------------------------------------------------------------------------
    def check(self) -> None:
        """Before a cycle: trip on an expired beat, latch once stopped, notice a reset
        done by MAFR / MC_Reset."""
        if self.state == WatchdogState.ARMED:
            if self.age() >= self.timeout_cycles:
                self.trip()
        elif self.state == WatchdogState.STOPPING:
            assert self.stop is not None
            if self.stop.complete:
                # the whole group faulted in one batch (feedback-only axes have no drive)
                fb = AxisType.FEEDBACK_ONLY
                self.ctl.fault_axes([ax for ax in self.group.axes if ax.type != fb], WATCHDOG_FAULT)
                self.stop = None
                self.fire(WatchdogEvent.STOPPED)
        elif (
            self.state == WatchdogState.FAULTED
            and not (self.ctl.arrays.fault[self.group.idx] & WATCHDOG_FAULT).any()
        ):  # (the group's AxisFault words read as one array: every cycle while latched)
            self._forget_beats()
            self.fire(WatchdogEvent.CLEARED)

    def trip(self) -> None:
        self.trips += 1
        try:
            self.stop = self.ctl.group_stop(self.group.number, FORCED[self.stop_mode], owner=self)
        except MotionError as exc:
            # a ramp the kernel refuses (the limits forbid it; kept as a last guard): the
            # stop must still happen, so the drives go off at once and the axes coast
            log.error(
                "watchdog %s: the %s of %s was refused (%s); Hard Disable instead",
                self.name,
                self.stop_mode.name.lower(),
                self.group.name,
                exc,
            )
            self.stop = self.ctl.group_stop(
                self.group.number, ProgrammedStopMode.HARD_DISABLE, owner=self
            )
        self.fire(WatchdogEvent.EXPIRE)

    # -- tags -----------------------------------------------------------------------------
    def bindings(self) -> dict[str, tuple[Getter, Setter | None]]:
        """Getter and setter (None: read-only) of every tag of this watchdog."""
        n = self.name

        def set_heartbeat(value: Value) -> None:
            self.beat(int(value))

        def set_reset(value: Value) -> None:
            self.set_reset(bool(value))

        return {
            f"{n}.Fault": (lambda: self.fault, None),
            f"{n}.State": (lambda: int(self.state), None),
            f"{n}.Trips": (lambda: self.trips & 0xFFFFFFFF, None),
            f"{n}.Age": (lambda: min(self.age(), 0xFFFFFFFF), None),
            f"{n}.Reset": (lambda: self.reset_input, set_reset),
            f"{n}.Heartbeat": (lambda: self.heartbeat, set_heartbeat),
        }
