"""``motion-server run`` as a user starts it (through the pytest plugin's
:class:`~motion_server.testing.MotionServer`), for tests of the processes themselves:
the supervisor's children by role, killing one, waiting for a restarted front-end."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from pathlib import Path
from types import TracebackType

from motion_server.testing import MotionServer

MODBUS = re.compile(r"Modbus TCP on [\d.]+:(\d+)")
OPCUA = re.compile(r"OPC UA on (opc\.tcp://[^ ]+:(\d+)/)")


class Served:
    """``with Served(cwd, site="site.toml") as srv:`` — the server runs (realtime clock
    unless ``clock`` says otherwise) until the block ends (SIGINT). ``srv.modbus_port``,
    ``srv.opcua_port``, ``srv.children()`` (role -> pid), ``srv.kill(role)``."""

    def __init__(
        self, cwd: Path, site: str | None = None, opcua: bool = True, clock: str = "realtime"
    ) -> None:
        self.cwd = cwd
        self.site = cwd / site if site else None
        self.want_opcua = opcua
        self.want_modbus = True
        self.clock = clock
        self.server: MotionServer | None = None

    def __enter__(self) -> Served:
        self.server = MotionServer.start(
            self.cwd, self.site, clock=self.clock, opcua=None if self.want_opcua else False
        )
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    @property
    def proc(self) -> subprocess.Popen[bytes]:
        assert self.server is not None
        return self.server.proc

    @property
    def modbus_port(self) -> int:
        assert self.server is not None
        return self.server.modbus_port

    @property
    def endpoint(self) -> str:
        assert self.server is not None
        return self.server.opcua_endpoint

    @property
    def opcua_port(self) -> int:
        assert self.server is not None
        return self.server.opcua_port

    def log(self) -> str:
        assert self.server is not None
        return self.server.log()

    def wait_serving(self, after: int, timeout: float = 120.0) -> None:
        """Until the front-ends wanted again (``want_modbus``, ``want_opcua``) logged
        where they listen after log offset ``after`` (a restart)."""
        give_up = time.monotonic() + timeout
        while time.monotonic() < give_up:
            text = self.log()[after:]
            if (MODBUS.search(text) or not self.want_modbus) and (
                OPCUA.search(text) or not self.want_opcua
            ):
                return
            time.sleep(0.1)
        raise RuntimeError(f"no front-end came back:\n{self.log()[-3000:]}")

    def children(self) -> dict[str, int]:
        """role ("scan", "modbus", "opcua") -> pid of the supervisor's live children."""
        assert self.server is not None
        pid = self.server.pid
        out: dict[str, int] = {}
        for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split():
            try:
                cmd = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"motion_server.scan" in cmd:
                out["scan"] = int(child)
            elif b"motion_server.frontends" in cmd:
                out[cmd[cmd.index(b"motion_server.frontends") + 1].decode()] = int(child)
        return out

    def kill(self, role: str) -> int:
        pid = self.children()[role]
        os.kill(pid, signal.SIGKILL)
        return pid

    def stop(self, sig: signal.Signals = signal.SIGINT, timeout: float = 30.0) -> int:
        """Signal the supervisor and wait for it; returns its exit code."""
        assert self.server is not None
        return self.server.stop(timeout, sig)
