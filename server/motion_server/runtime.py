"""The cycle loop: clock modes, lifecycle and diagnostics around a :class:`MotionSystem`.

Simulated time advances exactly one base period per cycle, always. The runtime owns the
clock:

- ``realtime``: cycles run on an absolute deadline schedule; a late loop runs the missed
  cycles back to back (at most ``max_catch_up`` of them, the rest are dropped and logged)
  and counts every late cycle as an overrun. The period never stretches.
- ``scaled``: the same schedule at ``scale`` simulated seconds per real second.
- ``manual``: time stands still until :meth:`Runtime.request_cycles` asks for N cycles.

Stopping (SIGINT/SIGTERM or :meth:`request_stop`) runs the programmed stop of every group,
as a controller does when it leaves run mode, and returns once all axes are at rest.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import time
from collections.abc import Callable
from enum import IntEnum

from . import __version__
from .config import SiteMap
from .instructions import MotionSystem
from .kernel import GroupStop
from .kernel.group import OperatingMode

log = logging.getLogger("motion_server.runtime")

#: simulated seconds the shutdown stop may take before the runtime gives up waiting
SHUTDOWN_STOP_LIMIT = 30.0


class ClockMode(IntEnum):
    REALTIME = 0
    MANUAL = 1
    SCALED = 2


class Runtime:
    def __init__(self, site: SiteMap, system: MotionSystem | None = None) -> None:
        self.site = site
        self.system = system or site.build()
        self.ctl = self.system.ctl
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
        #: called after every cycle (front-ends refresh their images here)
        self.after_cycle: list[Callable[[], None]] = []
        self._pending_cycles = 0
        self._wake = asyncio.Event()
        self._stop_requested = False
        self._stopped = asyncio.Event()
        self._reschedule = True

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
            self._wake.set()

    def request_cycles(self, count: int) -> None:
        """Manual clock: run ``count`` more cycles (ignored in the other modes)."""
        if count > 0:
            self._pending_cycles += count
            self._wake.set()

    def request_stop(self) -> None:
        if not self._stop_requested:
            log.info("stop requested: programmed stop of every group")
            self._stop_requested = True
            self._wake.set()

    # -- the loop ---------------------------------------------------------------------------
    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        next_log = loop.time() + self.status_log_interval
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
                    n, self._pending_cycles = self._pending_cycles, 0
                    self.cycle(n)
                    await asyncio.sleep(0)
                    continue
                self._wake.clear()
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._wake.wait(), timeout=0.5)
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
                self._wake.clear()
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(
                        self._wake.wait(), timeout=max(0.0, deadline - loop.time())
                    )
            if self.status_log_interval and loop.time() >= next_log:
                next_log = loop.time() + self.status_log_interval
                log.info("%s", self.status_line())
        await self._programmed_stop()
        self._stopped.set()

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
