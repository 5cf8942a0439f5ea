"""An FMU whose controller is also served: Modbus and OPC UA front-ends on the image
while a co-simulation master steps it, so an HMI can watch (and operate) a
co-simulation.

:class:`ServedRuntime` runs :meth:`Runtime.serve` (the front-ends of the site map, on its
ports) on an asyncio loop in a thread of its own. Everything that touches the scan then
runs on that loop: the master's ``doStep`` is handed over with
:func:`asyncio.run_coroutine_threadsafe` and waited for, so a client's write and the
master's step never interleave. Time stays the master's: a served FMU needs a site map
with ``remote_clock = false``, so that no client can step the clock or change its mode
(the registers are those ``motion-server map`` exports for that site map).
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import TypeVar

from ..runtime import Runtime

T = TypeVar("T")

SERVE_NEEDS = (
    "a served FMU needs [controller] remote_clock = false in its site map: the master "
    "owns time, no client may step the clock"
)
#: seconds the front-ends may take to listen, and the programmed stop to end
START_TIMEOUT = 60.0
STOP_TIMEOUT = 60.0


class ServeError(RuntimeError):
    """The front-ends did not start (a port in use, ...)."""


class ServedRuntime:
    """``runtime`` served from a thread of its own (see the module docstring)."""

    def __init__(self, runtime: Runtime) -> None:
        self.runtime = runtime
        self.loop = asyncio.new_event_loop()
        self._started = threading.Event()
        self._error: BaseException | None = None
        self.thread = threading.Thread(target=self._main, name="fmu-frontends", daemon=True)
        self.thread.start()
        if not self._started.wait(START_TIMEOUT):
            raise ServeError(f"the front-ends did not start within {START_TIMEOUT:.0f} s")
        if self._error is not None:
            raise ServeError(f"the front-ends did not start: {self._error}")

    def _main(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_until_complete(self._serve())
        finally:
            self._started.set()
            self.loop.close()

    async def _serve(self) -> None:
        task = asyncio.create_task(self.runtime.serve())
        ready = asyncio.create_task(self.runtime.ready.wait())
        await asyncio.wait({task, ready}, return_when=asyncio.FIRST_COMPLETED)
        if task.done():
            ready.cancel()
            self._error = task.exception() or RuntimeError("stopped at start")
            return
        self._started.set()
        await task

    def call(self, work: Callable[[], T]) -> T:
        """Run ``work`` on the loop (between two passes of the scan) and return its result."""

        async def run() -> T:
            return work()

        return asyncio.run_coroutine_threadsafe(run(), self.loop).result()

    @property
    def modbus_port(self) -> int | None:
        fe = self.runtime.modbus
        return fe.port if fe is not None else None

    def stop(self) -> None:
        """The programmed stop of every group, the front-ends closed, the thread ended."""
        if self.thread.is_alive():
            self.loop.call_soon_threadsafe(self.runtime.request_stop)
            self.thread.join(STOP_TIMEOUT)
