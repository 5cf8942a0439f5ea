"""A small site for the Modbus tests (manual clock, ephemeral port) and a server thread
for clients that block (pyModbusTCP, mbpoll)."""

from __future__ import annotations

import asyncio
import threading
from types import TracebackType

from motion_server import config
from motion_server.runtime import Runtime

SITE = """
[site]
name = "modbus_test"

[controller]
clock = "manual"
status_log_interval = 0.0

[opcua]
enabled = false

[modbus]
port = 0
word_order = "{word_order}"
unit_id = {unit_id}

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Axis1", "Axis2", "Axis3"]

# the master: a virtual axis (actual = command, no drive lag)
[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[[axes]]
name = "Axis2"
type = "servo"

[[axes]]
name = "Axis3"
type = "feedback_only"
conversion_constant = 100.0

[instructions]
every_type = true

# an instance declared by hand beside the every_type ones (MC_Power_1 on Axis2)
[[instructions.instances]]
name = "MC_Power_1"
type = "MC_Power"
operands = {{ Axis = 2 }}
"""


def modbus_site(word_order: str = "big", unit_id: int = 1) -> config.SiteMap:
    return config.parse(SITE.format(word_order=word_order, unit_id=unit_id), "modbus-test.toml")


class ServerThread:
    """``with ServerThread(site) as srv:`` runs the runtime and its Modbus front-end in a
    thread with its own event loop; ``srv.port`` is the bound port."""

    def __init__(self, site: config.SiteMap) -> None:
        self.site = site
        self.port = 0
        self.runtime: Runtime | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:  # surfaced to the test in __enter__
            self._error = exc
            self._ready.set()

    async def _main(self) -> None:
        rt = Runtime(self.site)
        self.runtime = rt
        self._loop = asyncio.get_running_loop()
        task = asyncio.create_task(rt.serve())
        await rt.ready.wait()
        assert rt.modbus is not None
        self.port = rt.modbus.port
        self._ready.set()
        await task

    def __enter__(self) -> ServerThread:
        self._thread.start()
        if not self._ready.wait(10.0) or self._error is not None:
            raise RuntimeError(f"server did not start: {self._error!r}")
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._loop is not None and self.runtime is not None:
            self._loop.call_soon_threadsafe(self.runtime.request_stop)
        self._thread.join(10.0)
        assert not self._thread.is_alive(), "server thread did not stop"
