"""The cycle loop: clock modes, lifecycle and diagnostics around a :class:`MotionSystem`.

Simulated time advances exactly one base period per cycle, always. The runtime owns the
clock:

- ``realtime``: cycles run on an absolute deadline schedule; a late loop runs the missed
  cycles back to back (at most ``max_catch_up`` of them, the rest are dropped and logged)
  and counts every late cycle as an overrun. The period never stretches.
- ``scaled``: the same schedule at ``scale`` simulated seconds per real second.
- ``manual``: time stands still until :meth:`Runtime.request_cycles` asks for N cycles
  (a client's ``Clock.Step``); they run in chunks that yield to the loop, and
  :meth:`Runtime.settle` returns once they all ran.

:meth:`Runtime.serve` runs the loop with the front-ends of the site map (Modbus TCP,
OPC UA) around it; ``runtime.modbus`` / ``runtime.opcua`` are the running front-ends.
The runtime is the tag image's host: it owns the clock tags and the diagnostics counters.

Stopping (SIGINT/SIGTERM or :meth:`request_stop`) runs the programmed stop of every group,
as a controller does when it leaves run mode, and returns once all axes are at rest.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import signal
import time
from collections.abc import Callable, Iterator

from . import __version__
from .config import SiteMap, opcua_users
from .frontends.modbus import ModbusFrontend
from .frontends.opcua import OpcUaFrontend
from .instructions import MotionSystem
from .kernel import GroupStop
from .kernel.group import OperatingMode
from .safety import retain
from .safety.access import AccessPolicy
from .safety.audit import AuditLog
from .safety.watchdog import Watchdog
from .tagmap import ClockMode, TagImage, TagMap, build_tagmap
from .tagmap.image import Getter, Setter

log = logging.getLogger("motion_server.runtime")

#: simulated seconds the shutdown stop may take before the runtime gives up waiting
SHUTDOWN_STOP_LIMIT = 30.0
#: manual clock: cycles run back to back before the loop yields to the front-ends
MANUAL_CHUNK = 200

__all__ = ["ClockMode", "Runtime"]


class Runtime:
    def __init__(
        self, site: SiteMap, system: MotionSystem | None = None, fresh: bool = False
    ) -> None:
        self.site = site
        self.system = system or site.build()
        self.ctl = self.system.ctl
        #: the retain file (``[retain]``), None when off; a bad file raises RetainError
        self.retain_file = retain.retain_path(site) if site.retain.enabled else None
        if self.retain_file is not None and not fresh:
            payload = retain.load(self.retain_file, site.site.name)
            if payload is not None:
                for note in retain.restore(self.system, payload):
                    log.warning("retain: %s", note)
                log.info("retained state restored from %s", self.retain_file)
        ctl_cfg = site.controller
        self.mode = {
            "realtime": ClockMode.REALTIME,
            "scaled": ClockMode.SCALED,
            "manual": ClockMode.MANUAL,
        }[ctl_cfg.clock]
        self.scale = ctl_cfg.scale
        self.max_catch_up = ctl_cfg.max_catch_up
        self.status_log_interval = ctl_cfg.status_log_interval
        self.version = __version__
        self.heartbeat = 0
        self.overruns = 0
        self.dropped = 0
        self.last_cycle_time = 0.0  # seconds of CPU the last cycle took
        self.max_cycle_time = 0.0
        #: called before every cycle (the watchdogs) and after it (front-ends)
        self.before_cycle: list[Callable[[], None]] = []
        self.after_cycle: list[Callable[[], None]] = []
        self._pending_cycles = 0
        self._settled = asyncio.Event()
        #: the loop sleeps on this future until its deadline or a wake-up
        self._waiter: asyncio.Future[None] | None = None
        self._stop_requested = False
        self._stopped = asyncio.Event()
        self._reschedule = True
        self.tagmap: TagMap = build_tagmap(site)
        self.watchdogs = {w.name: Watchdog(w, self.ctl) for w in site.watchdogs}
        bindings: dict[str, tuple[Getter, Setter | None]] = {}
        for wd in self.watchdogs.values():
            bindings |= wd.bindings()
            self.before_cycle.append(wd.check)
        self.image = TagImage(self.tagmap, self.system, self, bindings)
        #: the audit log of client writes (``[audit]``), None when off
        self.audit = AuditLog.from_config(site.audit, site.data_dir, lambda: self.ctl.tick)
        if self.audit is not None:
            self.image.observers.append(self.audit.accepted)
        self.modbus: ModbusFrontend | None = None
        self.opcua: OpcUaFrontend | None = None
        #: set once the front-ends listen (``serve``)
        self.ready = asyncio.Event()

    # -- cycles -----------------------------------------------------------------------------
    @property
    def period(self) -> float:
        return self.ctl.period

    @property
    def cycle_count(self) -> int:
        return self.ctl.tick

    @property
    def sim_time(self) -> float:
        return self.ctl.time

    def cycle(self, count: int = 1) -> None:
        """Run ``count`` cycles now, whatever the clock mode (tests, manual steps)."""
        for _ in range(count):
            t0 = time.perf_counter()
            for before in self.before_cycle:
                before()
            self.system.cycle()
            self.heartbeat = (self.heartbeat + 1) & 0xFFFFFFFF
            for hook in self.after_cycle:
                hook()
            self.last_cycle_time = time.perf_counter() - t0
            self.max_cycle_time = max(self.max_cycle_time, self.last_cycle_time)

    def set_mode(self, mode: ClockMode) -> None:
        if mode != self.mode:
            log.info("clock mode %s -> %s", self.mode.name.lower(), mode.name.lower())
            self.mode = mode
            self._reschedule = True
            if mode != ClockMode.MANUAL:
                self._pending_cycles = 0
                self._settled.set()
            self._wake()

    def request_cycles(self, count: int) -> None:
        """Manual clock: run ``count`` more cycles (ignored in the other modes)."""
        if count > 0 and self.mode == ClockMode.MANUAL:
            self._pending_cycles += count
            self._settled.clear()
            self._wake()

    async def settle(self) -> None:
        """Return once the cycles requested so far have run (or can no longer run)."""
        while self._pending_cycles and not self._stop_requested:
            self._settled.clear()
            await self._settled.wait()

    def request_stop(self) -> None:
        if not self._stop_requested:
            log.info("stop requested: programmed stop of every group")
            self._stop_requested = True
            self._wake()

    def save_retained(self) -> None:
        """Write the retain file now (atomically); errors are logged, never raised."""
        if self.retain_file is None:
            return
        try:
            retain.save(self.retain_file, retain.snapshot(self.site, self.system))
        except OSError as exc:
            log.error("retain: cannot write %s: %s", self.retain_file, exc)

    # -- the loop ---------------------------------------------------------------------------
    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        next_log = loop.time() + self.status_log_interval
        every = self.site.retain.interval
        next_save = loop.time() + every
        deadline = loop.time()
        log.info(
            "motion-server %s: %d axes, %d groups, %d instructions, period %.1f ms, clock %s",
            self.version,
            len(self.ctl.axes),
            len(self.ctl.groups),
            len(self.system.instances),
            self.period * 1000,
            self.mode.name.lower(),
        )
        while not self._stop_requested:
            now = loop.time()
            if self.mode == ClockMode.MANUAL:
                if self._pending_cycles:
                    n = min(self._pending_cycles, MANUAL_CHUNK)
                    self.cycle(n)
                    self._pending_cycles -= n
                    if not self._pending_cycles:
                        self._settled.set()
                    await asyncio.sleep(0)
                    continue
                await self._sleep_until(loop.time() + 0.5)
                self._reschedule = True
            else:
                if self._reschedule:
                    deadline = now
                    self._reschedule = False
                step = self.period / (self.scale if self.mode == ClockMode.SCALED else 1.0)
                due = int((now - deadline) / step) + 1 if now >= deadline else 0
                if due > 1:
                    self.overruns += due - 1
                if due > self.max_catch_up:
                    self.dropped += due - self.max_catch_up
                    log.warning(
                        "loop %.1f ms late: dropped %d cycles",
                        (now - deadline) * 1000,
                        due - self.max_catch_up,
                    )
                    deadline += (due - self.max_catch_up) * step
                    due = self.max_catch_up
                if due:
                    self.cycle(due)
                    deadline += due * step
                await self._sleep_until(deadline)
            if self.retain_file is not None and every and loop.time() >= next_save:
                next_save = loop.time() + every
                self.save_retained()
            if self.status_log_interval and loop.time() >= next_log:
                next_log = loop.time() + self.status_log_interval
                log.info("%s", self.status_line())
        self._pending_cycles = 0
        self._settled.set()
        await self._programmed_stop()
        self.save_retained()
        self._stopped.set()

    async def serve(self, modbus: bool | None = None, opcua: bool | None = None) -> None:
        """Run the loop with the front-ends around it; they close after the stop.

        ``modbus`` and ``opcua`` override the site map's ``enabled`` of each front-end.
        """
        cfg = self.site.modbus
        try:
            if cfg.enabled if modbus is None else modbus:
                policy = AccessPolicy(cfg.access, self.tagmap)
                self.modbus = ModbusFrontend(
                    self.image, cfg.host, cfg.port, cfg.unit_id, policy, self.audit, cfg.tls
                )
                await self.modbus.start()
            ucfg = self.site.opcua
            if ucfg.enabled if opcua is None else opcua:
                self.opcua = OpcUaFrontend(
                    self.image, ucfg, opcua_users(self.site), audit=self.audit
                )
                await self.opcua.start()
            self.ready.set()
            with frozen_heap():
                await self.run()
        finally:
            if self.opcua is not None:
                await self.opcua.stop()
            if self.modbus is not None:
                await self.modbus.stop()
            if self.audit is not None:
                self.audit.close()

    def _wake(self) -> None:
        """End the loop's sleep now (a request, a mode change, a stop)."""
        if self._waiter is not None and not self._waiter.done():
            self._waiter.set_result(None)

    async def _sleep_until(self, deadline: float) -> None:
        """Sleep until ``deadline`` (loop time) or :meth:`_wake`: one future and one timer,
        far cheaper per cycle than ``wait_for`` on an event."""
        loop = asyncio.get_running_loop()
        if self._stop_requested or (self._pending_cycles and self.mode == ClockMode.MANUAL):
            return
        fut: asyncio.Future[None] = loop.create_future()
        self._waiter = fut
        timer = loop.call_at(deadline, _resolve, fut)
        try:
            await fut
        finally:
            timer.cancel()
            self._waiter = None

    async def _programmed_stop(self) -> None:
        # leaving run mode: the programmed stop of every group, no more instruction scans
        stops: list[GroupStop] = self.ctl.set_mode(OperatingMode.PROGRAM)
        limit = int(SHUTDOWN_STOP_LIMIT / self.period)
        n = 0
        while not all(s.complete for s in stops) and n < limit:
            self.cycle(1)
            n += 1
            if n % 50 == 0:
                await asyncio.sleep(0)
        if all(s.complete for s in stops):
            log.info(
                "programmed stop complete after %d cycles (%.3f s simulated)", n, n * self.period
            )
        else:
            log.warning("programmed stop not complete after %.0f s simulated", SHUTDOWN_STOP_LIMIT)

    def status_line(self) -> str:
        axes = " ".join(
            f"{a.name}={a.actual_position:.3f}{a.config.units}/{a.state.name.lower()}"
            for a in self.ctl.axes
        )
        return (
            f"cycle {self.cycle_count} t={self.sim_time:.3f}s overruns={self.overruns} "
            f"max_cycle={self.max_cycle_time * 1e6:.0f}us {axes}"
        )

    def install_signal_handlers(self) -> None:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, self.request_stop)


_frozen_by = 0


@contextlib.contextmanager
def frozen_heap() -> Iterator[None]:
    """Keep the start-up heap out of the garbage collector while the loop runs.

    A served site holds several hundred thousand tracked objects (asyncua's address space
    alone is most of them); a full collection scans them all and stops the loop for
    hundreds of milliseconds, far past the catch-up bound, so cycles would be dropped
    whenever one ran. Frozen objects are never scanned; what the server allocates later is
    still collected. Nested uses (several runtimes in one process) unfreeze with the last.
    """
    global _frozen_by
    _frozen_by += 1
    gc.freeze()
    try:
        yield
    finally:
        _frozen_by -= 1
        if not _frozen_by:
            gc.unfreeze()


def _resolve(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)
