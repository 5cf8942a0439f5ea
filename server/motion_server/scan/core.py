"""The scan: the controller's cycle, its clock, its watchdogs and its image.

:class:`Scan` owns everything that moves: the :class:`MotionSystem` (kernel and
instruction instances), the communication watchdogs, the retained state, the clock and
the diagnostics counters. It talks to the rest of the server only through the shared
image (:mod:`motion_server.image.buffer`, written after every cycle) and through its
channels (:mod:`.channel`: judged write batches in, acknowledgements out).

It does no I/O of its own: :meth:`Scan.service` does one pass of work (read the packets
waiting, apply writes, run the cycles that are due, publish, acknowledge) and returns
when it wants to be called again; the caller sleeps until then or until a channel has a
packet. :mod:`.process` does that with ``select`` in a process of its own (how the server
runs); :class:`motion_server.runtime.Runtime` does it on an asyncio loop, in the test's
own process.

Clock modes (simulated time advances exactly one base period per cycle, always):

- ``realtime``: cycles on an absolute deadline schedule; a late pass runs the missed
  cycles back to back (at most ``max_catch_up``; the rest are dropped and logged) and
  counts every late cycle as an overrun. The period never stretches. Writes wait for the
  next cycle, which applies what its budget allows (:mod:`.writes`: watchdog writes
  first; the rest waits for the following cycles, in each client's order).
- ``scaled``: the same at ``scale`` simulated seconds per real second.
- ``manual``: time stands still; writes apply at once, whatever the budget; a rising edge
  of ``Clock.Step`` runs ``Clock.StepCycles`` cycles (in chunks, with packets read in
  between) and its write is acknowledged once they ran; the writes behind it go into
  those cycles, each taking its budget.
- ``fast``: cycles back to back as fast as the CPU allows; writes apply at the start of
  the next cycles within their budget, the image is published about every millisecond.

Stopping (:meth:`Scan.request_stop`: SIGINT/SIGTERM, or the supervisor): the programmed
stop of every group, as a controller does when it leaves run mode, commanded before any
write waiting and run back to back (each cycle applies its budget of writes); then the
writes still waiting are applied, the retained state is saved and :attr:`Scan.finished`
becomes true.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..config import SiteMap
from ..image import wire
from ..image.buffer import META_WORDS, ImageWriter, Meta, ScanState, image_bytes
from ..image.layout import ImageLayout
from ..image.trend import RingWriter
from ..instructions import MotionSystem
from ..kernel import GroupStop
from ..kernel.group import OperatingMode
from ..safety import retain
from ..safety.client import writing_as
from ..safety.watchdog import Watchdog, arriving_at
from ..scheduling import LOAD_WINDOW
from ..tagmap import ClockMode, CommFault, Folder, TagAccessError, TagImage, build_tagmap
from ..tagmap.image import CommSettings, Getter, Setter
from ..tagmap.judge import Judge
from . import snapshots
from .channel import CONTROL, Channel
from .filler import ImageFiller
from .writes import BatchCosts, Queued, WriteQueue, default_budget

log = logging.getLogger("motion_server.scan")

#: simulated seconds the programmed stop may take before the scan gives up waiting
SHUTDOWN_STOP_LIMIT = 30.0
#: manual clock: cycles run back to back before packets are read again
MANUAL_CHUNK = 200
#: fast clock: wall seconds of cycles between two publishes (and packet reads)
FAST_SLICE = 0.001
#: stop cycles run per pass
STOP_CHUNK = 50
#: seconds between two looks at a snapshot file being read or written
JOB_POLL = 0.002

RetainSink = Callable[[dict[str, Any]], None]


@dataclass
class _Served:
    """A system with everything the scan needs to serve it (see :meth:`Scan._serving`)."""

    system: MotionSystem
    watchdogs: dict[str, Watchdog]
    image: TagImage
    filler: ImageFiller


class Scan:
    """The motion cycle of one site (see the module docstring).

    ``buffer``: the shared memory of the image (the scan's side maps it writable); a
    private one when None. ``retain_sink``: where retained state goes (the supervisor
    writes the file); when None the scan writes the file itself. ``system``: a system
    built from ``site`` (tests pass one they prepared). ``background``: snapshot files are
    written and read in a thread of their own while the cycles go on (the scan's
    process); else at once, inside the write that asked (the in-process runtime).
    """

    def __init__(
        self,
        site: SiteMap,
        system: MotionSystem | None = None,
        *,
        buffer: Any = None,
        fresh: bool = False,
        retain_sink: RetainSink | None = None,
        background: bool = False,
    ) -> None:
        self.site = site
        self.system = system or site.build()
        self.ctl = self.system.ctl
        self.retain_file = retain.retain_path(site) if site.retain.enabled else None
        self._retain_sink = retain_sink
        if self.retain_file is not None and not fresh:
            payload = retain.load(self.retain_file, site.site.name)
            if payload is not None:
                for note in retain.restore(self.system, payload):
                    log.warning("retain: %s", note)
                log.info("retained state restored from %s", self.retain_file)
        self.background = background
        ctl_cfg = site.controller
        self.mode = ClockMode[ctl_cfg.clock.upper()]
        self.scale = ctl_cfg.scale
        self.max_catch_up = ctl_cfg.max_catch_up
        self.status_log_interval = ctl_cfg.status_log_interval
        self.version = __version__
        # diagnostics
        self.heartbeat = 0
        self.overruns = 0
        self.dropped = 0
        self.last_cycle_time = 0.0
        self.max_cycle_time = 0.0
        self.load = 0.0
        self.queued_writes = 0
        self.restarts = 0
        self.writes_applied = 0
        self.kernel_failures = 0
        # the Clock's own settings (not controller state: a restore keeps them)
        self.snapshot_number = 0
        self.snapshot_save = False
        self.snapshot_restore = False
        self.comm = CommSettings()
        #: monotonic time the communication fault ends (None: none, or until cleared)
        self.comm_until: float | None = None
        self._comm_written = False
        #: a snapshot command to carry out once its batch is applied: (kind, name)
        self._snapshot_op: tuple[str, str] | None = None
        #: the snapshot being written or read, and the write to answer once it is done
        self._job: snapshots.Job | None = None
        self._job_ack: tuple[Channel, int] | None = None
        # the image
        self.tagmap = build_tagmap(site)
        self.layout = ImageLayout(self.tagmap)
        self._install(self.system)
        size = self.layout.size
        buf = buffer if buffer is not None else bytearray(image_bytes(size))
        self.writer = ImageWriter(buf, size, self.layout.fingerprint)
        self.meta = np.zeros(META_WORDS, dtype=np.int64)
        #: the web view's trend ring (:mod:`motion_server.image.trend`), when it is served
        self.trend: RingWriter | None = None
        # channels and the write queue (and the budget of each cycle for it)
        self.channels: dict[int, Channel] = {}
        budget = ctl_cfg.write_budget or default_budget(self.period)
        self.writes = WriteQueue(budget, BatchCosts(self.layout, self.ctl))
        #: batches waiting for their cycles: (channel, sequence, tick to reach)
        self._waiting: list[tuple[Channel, int, int]] = []
        #: acknowledgements that go out with the next publish (an ACK means: the image
        #: shows the write, and the cycles it asked for)
        self._outgoing: list[tuple[Channel, bytes]] = []
        self._pending_cycles = 0
        # schedule
        self.state = ScanState.STARTING
        self._stop_requested = False
        self._stops: list[GroupStop] = []
        self._stop_cycles = 0
        self._reschedule = True
        self._deadline = 0.0
        #: what reads the time :meth:`service` is called with (see :meth:`rebase`)
        self.clock: Callable[[], float] = time.monotonic
        self._next_log = 0.0
        self._next_save = 0.0
        self._load_start = 0.0
        self._load_busy = 0.0
        self._dirty = False
        self._refill = False
        self._refill_clock = False
        #: the Clock tags the scan changes itself (command bits cleared, a fault over)
        self._clock_commands = [
            t
            for t in self.tagmap.owned_by("Clock")
            if t.field in ("SnapshotSave", "SnapshotRestore", "CommFault")
        ]
        #: the tags the scan (the host) answers, not the controller: a restore refreshes them
        self._host_tags = [
            t for t in self.layout.tags if t.folder in (Folder.CLOCK, Folder.DIAGNOSTICS)
        ]

    def _install(self, system: MotionSystem) -> None:
        """Serve ``system`` (at start)."""
        self._serve(self._serving(system, None, fill=False))

    def _serving(
        self, system: MotionSystem, watchdogs: dict[str, Watchdog] | None, fill: bool = True
    ) -> _Served:
        """What serving ``system`` takes: its watchdogs (new ones unless given), its tag
        image and the image filler, every slot filled. Touches nothing live: a restore
        builds it off the cycle, in the thread that read the file (it takes most of the
        time on a large map: thousands of bindings)."""
        if watchdogs is None:
            watchdogs = {w.name: Watchdog(w, system.ctl) for w in self.site.watchdogs}
        bindings: dict[str, tuple[Getter, Setter | None]] = {}
        for wd in watchdogs.values():
            bindings |= wd.bindings()
        image = TagImage(self.tagmap, system, self, bindings, Judge.for_system(self.tagmap, system))
        filler = ImageFiller(image, self.layout)
        if fill:
            filler.fill_all()
        return _Served(system, watchdogs, image, filler)

    def _serve(self, served: _Served) -> None:
        """Serve what :meth:`_serving` built (between two cycles)."""
        old = getattr(self, "image", None)
        self.system = served.system
        self.ctl = served.system.ctl
        self.watchdogs = served.watchdogs
        self.image = served.image
        if old is not None:  # the Clock's command state is the host's, not the controller's
            self.image.step = old.step
            self.image.step_cycles = old.step_cycles
            self.image.observers = old.observers
        self.filler = served.filler
        trend: RingWriter | None = getattr(self, "trend", None)
        if trend is not None:  # a restore: the getters read the new system
            trend.renew()

    # -- set-up ---------------------------------------------------------------------------
    def attach(self, channel: Channel) -> None:
        """Serve ``channel`` (a front-end's write queue, or the supervisor's control)."""
        self.channels[channel.number] = channel

    def attach_trend(self, buf: Any) -> None:
        """Write the web view's trend ring (``buf``: its shared memory) after every cycle."""
        tags = self.layout.tags
        self.trend = RingWriter(buf, lambda s: self.image.getter(tags[s].name), len(tags))

    def start(self, now: float) -> None:
        """Publish the first image and begin running (the controller is ready)."""
        self.state = ScanState.RUNNING  # before the fill: Diagnostics.Ready shows it
        self.filler.fill_all()
        self.rebase(now)
        self._publish()
        log.info(
            "motion-server %s: %d axes, %d groups, %d instructions, period %.1f ms, clock %s",
            self.version,
            len(self.ctl.axes),
            len(self.ctl.groups),
            len(self.system.instances),
            self.period * 1000,
            self.mode.name.lower(),
        )
        control = self.channels.get(CONTROL)
        if control is not None:
            control.send(wire.encode_simple(wire.Kind.READY))

    def rebase(self, now: float, clock: Callable[[], float] | None = None) -> None:
        """Restart the schedule and the timers from ``now`` (a new clock source);
        ``clock``: what reads that source, the time :meth:`service` is called with (by
        default ``time.monotonic``)."""
        if clock is not None:
            self.clock = clock
        for wd in self.watchdogs.values():
            wd.forget_arrivals()
        self._reschedule = True
        self._deadline = now
        self._next_log = now + self.status_log_interval
        self._next_save = now + self.site.retain.interval
        self._load_start = now
        self._load_busy = 0.0

    def deliver(self, channel: Channel, batch: wire.Batch) -> None:
        """Queue a batch that did not come through a socket (the in-process runtime)."""
        self._queue(channel, batch)

    def _queue(self, ch: Channel, batch: wire.Batch) -> None:
        q = self.writes.put(ch, batch)
        if q.watchdog:
            q.arrived = self.clock()  # a heartbeat: when it came (see _apply)
        self.queued_writes = len(self.writes)

    @property
    def period(self) -> float:
        return self.ctl.period

    @property
    def finished(self) -> bool:
        return self.state == ScanState.STOPPED

    @property
    def ready(self) -> bool:
        """``Diagnostics.Ready``: the controller runs (not starting, stopping or stopped)."""
        return self.state == ScanState.RUNNING

    # -- the host protocol of the tag image -------------------------------------------------
    def set_mode(self, mode: ClockMode) -> None:
        if mode != self.mode:
            log.info("clock mode %s -> %s", self.mode.name.lower(), mode.name.lower())
            self.mode = mode
            self._reschedule = True
            for wd in self.watchdogs.values():
                wd.forget_arrivals()  # the beats count in cycles until the next one
            if mode != ClockMode.MANUAL:
                self._pending_cycles = 0
                self._ack_waiting(wire.Result.NOT_RUN)

    def request_cycles(self, count: int) -> None:
        """Manual clock: run ``count`` more cycles (ignored in the other modes)."""
        if count > 0 and self.mode == ClockMode.MANUAL:
            self._pending_cycles += count

    async def settle(self) -> None:
        """(The tag image's host protocol; the scan acknowledges writes instead.)"""

    def snapshot(self, kind: str) -> None:
        """(Host protocol) a rising edge of ``Clock.SnapshotSave`` / ``SnapshotRestore``:
        checked now (a refusal refuses the write), done once the batch is applied."""
        if self._job is not None or self._snapshot_op is not None:
            raise TagAccessError(
                f"snapshot {self._job.name if self._job else self.snapshot_number} is "
                "being saved or restored: one at a time"
            )
        name = str(self.snapshot_number)
        try:
            path = snapshots.path_of(self.site, name)
            if kind == "restore" and not os.path.lexists(path):
                raise snapshots.SnapshotError(f"{path}: no such snapshot")
        except snapshots.SnapshotError as exc:
            raise TagAccessError(str(exc)) from None
        self._snapshot_op = (kind, name)

    def comm_changed(self) -> None:
        """(Host protocol) a ``Clock.Comm...`` tag was written."""
        self._comm_written = True

    # -- snapshots ------------------------------------------------------------------------
    def save_snapshot(self, name: str) -> Path:
        """Save the controller state as snapshot ``name`` now (SnapshotError); its file."""
        path = snapshots.path_of(self.site, name)
        tick, body = self._capture()
        snapshots.write(self.site, self.layout, name, tick, body)
        log.info("snapshot %s saved at cycle %d (%s)", name, tick, path)
        return path

    def restore_snapshot(self, name: str) -> None:
        """Restore snapshot ``name`` now (SnapshotError in one line: nothing changed)."""
        t0 = time.perf_counter()
        self._swap(self._prepare(snapshots.load(self.site, self.layout, name)), t0)
        self._publish()

    def _capture(self) -> tuple[int, bytes]:
        """The cycle and the bytes of the controller's state (pickled at once: the only
        part of a save done in the cycle; the file is written off it)."""
        state = snapshots.capture(self.system, self.watchdogs)
        return state.tick, snapshots.encode(state)

    def _prepare(self, loaded: snapshots.Loaded) -> tuple[snapshots.Loaded, _Served]:
        """A snapshot read and checked, made ready to serve (off the cycle)."""
        return loaded, self._serving(loaded.state.system, loaded.state.watchdogs)

    def _swap(self, ready: tuple[snapshots.Loaded, _Served], started: float) -> None:
        """Serve the state of a snapshot read, checked and prepared whole (between two
        cycles: an assignment, and the host's own tags refreshed)."""
        loaded, served = ready
        if self.state != ScanState.RUNNING:
            raise snapshots.SnapshotError(f"{loaded.path}: not restored: the server is stopping")
        t0 = time.perf_counter()
        state = loaded.state
        self._serve(served)
        self.heartbeat = state.tick & 0xFFFFFFFF
        self.filler.refresh(self._host_tags)
        self._refill = False
        self._dirty = True
        # a step asked of the timeline left behind is not run; the schedule starts again
        # from now (the restore is not a late cycle: no overrun, nothing dropped)
        self._pending_cycles = 0
        self._ack_waiting(wire.Result.NOT_RUN)
        self._reschedule = True
        log.info(
            "snapshot %s restored: cycle %d (read and checked in %.3f s, swapped in %.1f ms)",
            loaded.name,
            state.tick,
            t0 - started,
            (time.perf_counter() - t0) * 1000,
        )

    def _start_snapshot(self, ch: Channel, seq: int) -> None:
        """Begin the snapshot command of the batch just applied; it is answered once the
        file is written, or read, checked and swapped in (:meth:`_finish_snapshot`)."""
        op, self._snapshot_op = self._snapshot_op, None
        assert op is not None
        kind, name = op
        site, layout = self.site, self.layout
        work: Callable[[], Any]
        error: snapshots.SnapshotError | None = None
        if kind == "save":
            try:
                tick, body = self._capture()
            except snapshots.SnapshotError as exc:
                tick, body, error = 0, b"", exc

            def work() -> Any:
                if error is not None:
                    raise error
                snapshots.write(site, layout, name, tick, body)
                return tick

        else:

            def work() -> Any:
                return self._prepare(snapshots.load(site, layout, name))

        self._job_ack = (ch, seq)
        self._job = snapshots.Job(kind, name, work, self.background)
        if self._job.done:
            self._finish_snapshot()

    def _finish_snapshot(self) -> None:
        job, self._job = self._job, None
        assert job is not None and self._job_ack is not None
        ch, seq = self._job_ack
        self._job_ack = None
        error = job.error
        if error is None and job.kind == "restore":
            try:
                self._swap(job.result, job.started)
            except snapshots.SnapshotError as exc:
                error = exc
        elif error is None:
            log.info("snapshot %s saved at cycle %d", job.name, job.result)
        if error is not None:
            log.warning("%s channel: snapshot %s not %sd: %s", ch.name, job.name, job.kind, error)
        self.snapshot_save = self.snapshot_restore = False  # the command bits read 0 again
        self.filler.refresh(self._clock_commands)
        self._refill = True
        self._dirty = True
        self._ack(ch, seq, wire.Result.APPLIED if error is None else wire.Result.FAILED)

    def _comm_update(self, now: float) -> None:
        """A Comm tag was written: the fault (re)starts now, for its duration."""
        self._comm_written = False
        c = self.comm
        if c.mode and c.duration:
            self.comm_until = now + c.duration / 1000.0
        else:
            self.comm_until = None
        if c.mode:
            who = f"client port {c.client_port}" if c.client_port else "every client"
            what = f"delayed {c.delay} ms" if c.mode == CommFault.DELAY else "dropped"
            span = f"for {c.duration} ms" if c.duration else "until cleared"
            log.warning("communication fault: answers to %s %s, %s", who, what, span)
        else:
            log.info("communication fault cleared")

    def _comm_expired(self, now: float) -> None:
        if self.comm_until is not None and now >= self.comm_until:
            self.comm_until = None
            self.comm.mode = int(CommFault.NONE)
            self._refill_clock = True
            self._refill = True
            self._dirty = True
            log.info("communication fault over")

    def request_stop(self) -> None:
        if not self._stop_requested:
            self._stop_requested = True

    # -- one pass -------------------------------------------------------------------------
    def service(self, now: float) -> float | None:
        """Do what is due at ``now`` (monotonic seconds); return when to be called next
        (None: only when a packet arrives)."""
        self._receive()
        if self._job is not None and self._job.done:
            self._finish_snapshot()
        if self._stop_requested and self.state == ScanState.RUNNING:
            self._begin_stop()
        if self.state == ScanState.STOPPING:
            return self._stopping(now)
        if self.state != ScanState.RUNNING:
            return None
        timer = self._periodic(now)
        mode = self.mode
        if mode == ClockMode.MANUAL:
            wake = self._manual()
        elif mode == ClockMode.FAST:
            wake = self._fast(now)
        else:
            wake = self._realtime(now)
        self._flush()
        if self.mode != mode:
            # a write just switched the clock: the new mode's schedule starts now, not at
            # the old one's next wake-up (a manual clock's: a timer up to a second away)
            return now
        if self._job is not None:  # a snapshot file being read or written: look again soon
            timer = now + JOB_POLL if timer is None else min(timer, now + JOB_POLL)
        if wake is None:
            return timer
        return wake if timer is None else min(wake, timer)

    def cycle(self, count: int = 1) -> None:
        """Run ``count`` cycles now, whatever the clock mode (tests, tools); every write
        waiting is applied first, whatever the budget, and the image is published after
        each cycle."""
        self._receive()
        if self._job is not None and self._job.done:
            self._finish_snapshot()
        with self.ctl.batch():
            for _ in range(count):
                self._apply_all()
                self._run_cycle()
                self._ack_due()
                self._publish()
        if not count and self._dirty:
            self._apply_all()
            self._publish()
        self._flush()

    def _manual(self) -> float | None:
        if not self._pending_cycles:
            self._apply_at_once()
        if self._pending_cycles:
            n = min(self._pending_cycles, MANUAL_CHUNK)
            with self.ctl.batch():
                for _ in range(n):
                    # the writes behind the step go into its cycles, within the budget
                    self._apply_queued()
                    if not self._pending_cycles:  # a write left the manual clock
                        break
                    self._run_cycle()
                    self._pending_cycles -= 1
            self._ack_due()
            self._publish()
            return 0.0  # more to run, or to read: at once
        if self._dirty:
            self._publish()
        return None

    def _fast(self, now: float) -> float:
        end = time.perf_counter() + FAST_SLICE
        with self.ctl.batch():
            while True:
                self._apply_queued()
                self._run_cycle()
                if time.perf_counter() >= end:
                    break
        self._ack_due()
        self._publish()
        return now

    def _realtime(self, now: float) -> float:
        if self._reschedule:
            self._deadline = now
            self._reschedule = False
        timed = self.mode == ClockMode.REALTIME
        expiry = self._watchdogs_due(now) if timed else None
        step = self.period / (self.scale if self.mode == ClockMode.SCALED else 1.0)
        if now < self._deadline:
            # writes that arrived meanwhile wait for the cycle; a watchdog that runs out
            # before it trips then
            return self._deadline if expiry is None else min(self._deadline, expiry)
        due = int((now - self._deadline) / step) + 1
        if due > 1:
            self.overruns += due - 1
        if due > self.max_catch_up:
            self.dropped += due - self.max_catch_up
            log.warning(
                "scan %.1f ms late: dropped %d cycles",
                (now - self._deadline) * 1000,
                due - self.max_catch_up,
            )
            self._deadline += (due - self.max_catch_up) * step
            due = self.max_catch_up
        with self.ctl.batch():
            for _ in range(due):
                self._apply_queued()
                self._run_cycle()
                self._ack_due()
                self._publish()
        self._deadline += due * step
        if timed:  # (the cycles applied beats: when the next one runs out now)
            expiry = self._watchdogs_due(now)
            if expiry is not None:
                return min(self._deadline, expiry)
        return self._deadline

    def _watchdogs_due(self, now: float) -> float | None:
        """Trip the watchdogs whose heartbeat ran out at ``now`` by the wall clock (between
        cycles: the stop is commanded now, the next cycle steps it) and publish their
        state at once; when the next of the others runs out (None: none is timed so)."""
        nearest: float | None = None
        tripped = False
        for wd in self.watchdogs.values():
            if wd.due(now):
                tripped = True
                continue
            expiry = wd.expiry()
            if expiry is not None and (nearest is None or expiry < nearest):
                nearest = expiry
        if tripped:  # (once, however many tripped)
            self._refill = True
            self._dirty = True
            self._publish()
        return nearest

    # -- cycles -----------------------------------------------------------------------------
    def _run_cycle(self) -> None:
        t0 = time.perf_counter()
        for wd in self.watchdogs.values():
            wd.check()
        try:
            self.system.cycle()
        except Exception as exc:  # the kernel contains its own; never end the scan
            self.kernel_failures += 1
            if self.kernel_failures == 1 or self.kernel_failures % 1000 == 0:
                log.error(
                    "cycle %d failed (%d so far); the scan goes on",
                    self.ctl.tick,
                    self.kernel_failures,
                    exc_info=exc,
                )
        if self.system.internal_errors:
            self._log_internal_errors()
        if self.ctl.internal_errors:
            self._log_kernel_errors(self.ctl.take_internal_errors())
        self.heartbeat = (self.heartbeat + 1) & 0xFFFFFFFF
        if self.trend is not None:  # the web view's trend ring: one word read when idle
            self.trend.cycle(self.ctl.tick)
        # Diagnostics.CycleTime: the cycle's own work (watchdogs, instructions, kernel);
        # copying it into the image is counted in the scan load
        spent = time.perf_counter() - t0
        self.last_cycle_time = spent
        if spent > self.max_cycle_time:
            self.max_cycle_time = spent
        # the image is filled once, before it is published: the cycles run back to back
        # in a slice of the fast clock or a Clock.Step are not seen one by one, and the
        # filler's change sets (outputs, fault causes) accumulate until then
        self._refill = True
        self._dirty = True
        self._load_busy += spent

    def _log_internal_errors(self) -> None:
        errors = self.system.internal_errors
        for name, exc in errors:
            log.error(
                "instruction %s raised %s: it shows the internal error (1005), its axes stop",
                name,
                type(exc).__name__,
                exc_info=exc,
            )
        errors.clear()

    def _log_kernel_errors(self, errors: list[tuple[str, str, BaseException]]) -> None:
        for axis, where, exc in errors:
            log.error(
                "axis %s: %s raised %s: the axis stops (internal error 1005 or AxisFault bit 3)",
                axis,
                where,
                type(exc).__name__,
                exc_info=exc,
            )

    def _publish(self) -> None:
        t0 = time.perf_counter()
        if self._refill:  # cycles run, or writes applied, since the last publish
            self.filler.fill()
            self._refill = False
        meta = self.meta
        meta[Meta.TICK] = self.ctl.tick
        meta[Meta.STATE] = int(self.state)
        meta[Meta.CLOCK_MODE] = int(self.mode)
        self.writer.publish(self.filler.values, meta)
        self._dirty = False
        self._load_busy += time.perf_counter() - t0
        if self._outgoing:
            for ch, packet in self._outgoing:
                ch.send(packet)
            self._outgoing = []

    # -- writes -----------------------------------------------------------------------------
    def _receive(self) -> None:
        for ch in list(self.channels.values()):
            for data in ch.receive():
                self._packet(ch, data)
            if ch.closed:
                log.info("%s channel closed", ch.name)
                del self.channels[ch.number]
                if ch.number == CONTROL:
                    log.warning("the supervisor is gone: stopping")
                    self.request_stop()

    def _packet(self, ch: Channel, data: bytes) -> None:
        try:
            kind, _, _ = wire.header(data)
            if kind == wire.Kind.HELLO:
                self._hello(ch, data)
            elif not ch.welcomed:
                return  # left over from a front-end that died: wait for the new HELLO
            elif kind == wire.Kind.WRITE:
                batch = ch.assembler.feed(data)
                if batch is not None:
                    self._queue(ch, batch)
            elif kind == wire.Kind.STOP and ch.number == CONTROL:
                log.info("stop requested: programmed stop of every group")
                self.request_stop()
            elif kind == wire.Kind.RESTARTS and ch.number == CONTROL:
                self.restarts = wire.decode_count(data)
            else:
                raise wire.WireError(f"unexpected {kind.name} packet")
        except (wire.WireError, ValueError) as exc:
            log.warning("%s channel: %s; ignored until the next HELLO", ch.name, exc)
            ch.reset()

    def _hello(self, ch: Channel, data: bytes) -> None:
        number, pid, fingerprint = wire.decode_hello(data)
        ch.reset()
        if number != ch.number or fingerprint != self.layout.fingerprint:
            why = "another site map" if fingerprint != self.layout.fingerprint else "channel"
            log.warning("%s channel: HELLO from pid %d refused (%s)", ch.name, pid, why)
            ch.send(wire.encode_simple(wire.Kind.REFUSED, why))
            return
        ch.welcomed = True
        ch.peer_pid = pid
        # the new front-end numbers its batches after the last one received: batches of
        # the one before it may still wait for their cycle
        last = self.writes.last_received(ch.number)
        applied = int(self.meta[Meta.APPLIED + ch.number]) if last is None else last
        ch.send(wire.encode_simple(wire.Kind.WELCOME, str(applied)))
        log.debug("%s front-end (pid %d) connected", ch.name, pid)

    def _apply_queued(self) -> None:
        """Before a cycle: the watchdog writes waiting, then the batches this cycle's
        budget allows (:mod:`.writes`); the others wait for the next cycle."""
        writes = self.writes
        self.queued_writes = len(writes)
        if writes:
            for q in writes.take_cycle():
                self._apply(q)

    def _apply_at_once(self) -> None:
        """Time stands still (the manual clock between steps): every batch waiting, in
        arrival order, whatever the budget, until one asks for cycles (a ``Clock.Step``):
        the batches behind it go into those cycles, each taking its budget."""
        writes = self.writes
        self.queued_writes = len(writes)
        while not self._pending_cycles:
            q = writes.take_first()
            if q is None:
                return
            self._apply(q)

    def _apply_all(self) -> None:
        """Every batch waiting, in arrival order, whatever the budget."""
        writes = self.writes
        self.queued_writes = len(writes)
        for q in writes.take_all():
            self._apply(q)

    def _settle(self, q: Queued) -> None:
        """Done with ``q``: the channel's APPLIED word moves past every batch done with."""
        seq = self.writes.settle(q)
        if seq is not None:
            self.meta[Meta.APPLIED + q.channel.number] = seq

    def _apply(self, q: Queued) -> None:
        ch, batch = q.channel, q.batch
        tags = self.layout.tags
        updates = []
        for slot, value in batch.items:
            if not 0 <= slot < len(tags):
                log.warning("%s channel: write to slot %d outside the image", ch.name, slot)
                self._settle(q)
                self._ack(ch, batch.seq, wire.Result.REFUSED)
                return
            updates.append((tags[slot], value))
        before = self._pending_cycles
        # a heartbeat applied with the realtime clock counts from when it came, not from
        # the cycle that applies it (see safety.watchdog)
        arrived = (
            arriving_at(q.arrived)
            if q.arrived is not None and self.mode == ClockMode.REALTIME
            else contextlib.nullcontext()
        )
        try:
            with writing_as(batch.client), arrived:
                self.image.write_many(updates)
        except TagAccessError as exc:
            self._snapshot_op = None
            log.warning("%s channel: a write refused by the scan: %s", ch.name, exc)
            # done with: the front-end drops the values it laid over the image for it
            self._settle(q)
            self._ack(ch, batch.seq, wire.Result.REFUSED)
            return
        snapshot = self._snapshot_op is not None
        if self._comm_written:
            self._comm_update(time.monotonic())
        if self._refill_clock:
            self._refill_clock = False
            self.filler.refresh(self._clock_commands)
        self.filler.refresh(t for t, _ in updates)
        self._refill = True
        self._settle(q)
        self.writes_applied += 1
        self._dirty = True
        if snapshot:
            self._start_snapshot(ch, batch.seq)  # answered once done
        elif self._pending_cycles > before and self.state == ScanState.STOPPING:
            # a Clock.Step while the programmed stop runs: no cycles for clients any more
            self._pending_cycles = 0
            self._ack(ch, batch.seq, wire.Result.NOT_RUN)
        elif self._pending_cycles > before:
            self._waiting.append((ch, batch.seq, self.ctl.tick + self._pending_cycles))
        else:
            self._ack(ch, batch.seq, wire.Result.APPLIED)

    def _ack(self, ch: Channel, seq: int, result: wire.Result, cycles: int = 0) -> None:
        packet = wire.encode_ack(wire.Ack(seq, self.ctl.tick, cycles, result))
        self._outgoing.append((ch, packet))
        self._dirty = True

    def _ack_due(self) -> None:
        if not self._waiting:
            return
        tick = self.ctl.tick
        keep = []
        for ch, seq, target in self._waiting:
            if tick >= target:
                self._ack(ch, seq, wire.Result.APPLIED)
            else:
                keep.append((ch, seq, target))
        self._waiting = keep

    def _ack_waiting(self, result: wire.Result) -> None:
        for ch, seq, _ in self._waiting:
            self._ack(ch, seq, result)
        self._waiting = []

    def _flush(self) -> None:
        for ch in self.channels.values():
            if ch.outbox:
                ch.flush()

    # -- stopping ---------------------------------------------------------------------------
    def _begin_stop(self) -> None:
        self.state = ScanState.STOPPING
        self._pending_cycles = 0
        self._ack_waiting(wire.Result.NOT_RUN)
        self._stops = self.ctl.set_mode(OperatingMode.PROGRAM)
        self._stop_cycles = 0
        self._refill = True  # Diagnostics.Ready falls with this publish
        self._publish()

    def _stopping(self, now: float) -> float | None:
        limit = int(SHUTDOWN_STOP_LIMIT / self.period)
        done = all(s.complete for s in self._stops)
        n = 0
        with self.ctl.batch():
            while not done and self._stop_cycles < limit and n < STOP_CHUNK:
                self._apply_queued()  # the stop was commanded first: writes never delay it
                self._run_cycle()
                self._stop_cycles += 1
                n += 1
                done = all(s.complete for s in self._stops)
        self._publish()
        if not done and self._stop_cycles < limit:
            self._flush()
            return now
        if done:
            log.info(
                "programmed stop complete after %d cycles (%.3f s simulated)",
                self._stop_cycles,
                self._stop_cycles * self.period,
            )
        else:
            log.warning("programmed stop not complete after %.0f s simulated", SHUTDOWN_STOP_LIMIT)
        self._apply_all()  # what clients wrote before the end is in the retained state
        self.save_retained()
        self.state = ScanState.STOPPED
        self._refill = True
        self._publish()
        control = self.channels.get(CONTROL)
        if control is not None:
            control.send(wire.encode_simple(wire.Kind.STOPPED))
        self._flush()
        return None

    # -- housekeeping -----------------------------------------------------------------------
    def _periodic(self, now: float) -> float | None:
        timers: list[float] = []
        if self.comm_until is not None:
            self._comm_expired(now)
            if self.comm_until is not None:
                timers.append(self.comm_until)
            elif self._refill_clock:
                self._refill_clock = False
                self.filler.refresh(self._clock_commands)
        if now - self._load_start >= LOAD_WINDOW:
            self.load = 100.0 * self._load_busy / (now - self._load_start)
            self._load_busy = 0.0
            self._load_start = now
            self._refill = True  # Diagnostics.ScanLoad changed
        timers.append(self._load_start + LOAD_WINDOW)
        every = self.site.retain.interval
        if self.retain_file is not None and every:
            if now >= self._next_save:
                self._next_save = now + every
                self.save_retained()
            timers.append(self._next_save)
        if self.status_log_interval:
            if now >= self._next_log:
                self._next_log = now + self.status_log_interval
                log.info("%s", self.status_line())
            timers.append(self._next_log)
        return min(timers)

    def save_retained(self) -> None:
        """Hand the retained state to its sink (the supervisor writes it), or write it."""
        if self.retain_file is None:
            return
        payload = retain.snapshot(self.site, self.system)
        if self._retain_sink is not None:
            self._retain_sink(payload)
            return
        try:
            retain.save(self.retain_file, payload)
        except OSError as exc:
            log.error("retain: cannot write %s: %s", self.retain_file, exc)

    def status_line(self) -> str:
        axes = " ".join(
            f"{a.name}={a.actual_position:.3f}{a.config.units}/{a.state.name.lower()}"
            for a in self.ctl.axes[:16]
        )
        more = f" (+{len(self.ctl.axes) - 16} axes)" if len(self.ctl.axes) > 16 else ""
        return (
            f"cycle {self.ctl.tick} t={self.ctl.time:.3f}s overruns={self.overruns} "
            f"dropped={self.dropped} max_cycle={self.max_cycle_time * 1e6:.0f}us "
            f"load={self.load:.1f}% {axes}{more}"
        )
