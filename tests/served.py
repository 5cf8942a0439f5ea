"""``motion-server run`` as a user starts it, for tests of the processes themselves:
the supervisor, the scan and the front-ends (each a process of its own)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import TracebackType

MODBUS = re.compile(r"Modbus TCP on [\d.]+:(\d+)")
OPCUA = re.compile(r"OPC UA on (opc\.tcp://[^ ]+:(\d+)/)")


class Served:
    """``with Served(args, cwd) as srv:`` — the server runs until the block ends (SIGINT,
    then a kill if it does not stop). ``srv.modbus_port``, ``srv.endpoint``,
    ``srv.children()`` (role -> pid), ``srv.log()``."""

    def __init__(self, args: list[str], cwd: Path, modbus: bool = True, opcua: bool = True):
        self.args = args
        self.cwd = cwd
        self.want_modbus = modbus
        self.want_opcua = opcua
        self.log_file = cwd / "server.log"
        self.proc: subprocess.Popen[bytes] | None = None
        self.modbus_port = 0
        self.endpoint = ""

    def __enter__(self) -> Served:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "motion_server.cli", "run", *self.args],
            cwd=self.cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=self.log_file.open("wb"),
        )
        self.wait_serving()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    @property
    def opcua_port(self) -> int:
        return int(self.endpoint.rsplit(":", 1)[1].strip("/")) if self.endpoint else 0

    def log(self) -> str:
        return self.log_file.read_text(errors="replace")

    def wait_serving(self, timeout: float = 120.0, after: int = 0) -> None:
        """Until the wanted front-ends logged where they listen (after log offset ``after``)."""
        assert self.proc is not None
        give_up = time.monotonic() + timeout
        while time.monotonic() < give_up:
            text = self.log()[after:]
            m = MODBUS.findall(text)
            u = OPCUA.findall(text)
            # the supervisor says "serving" once it heard every front-end (at start)
            started = after or "motion_server.supervisor: serving:" in text
            if started and (m or not self.want_modbus) and (u or not self.want_opcua):
                if m:
                    self.modbus_port = int(m[-1])
                if u:
                    self.endpoint = u[-1][0]
                return
            if self.proc.poll() is not None:
                raise RuntimeError(f"the server ended:\n{self.log()[-3000:]}")
            time.sleep(0.1)
        raise RuntimeError(f"the server did not serve:\n{self.log()[-3000:]}")

    def children(self) -> dict[str, int]:
        """role ("scan", "modbus", "opcua") -> pid of the supervisor's live children."""
        assert self.proc is not None
        path = Path(f"/proc/{self.proc.pid}/task/{self.proc.pid}/children")
        out: dict[str, int] = {}
        for pid in path.read_text().split():
            try:
                cmd = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"motion_server.scan" in cmd:
                out["scan"] = int(pid)
            elif b"motion_server.frontends" in cmd:
                out[cmd[cmd.index(b"motion_server.frontends") + 1].decode()] = int(pid)
        return out

    def kill(self, role: str) -> int:
        pid = self.children()[role]
        os.kill(pid, signal.SIGKILL)
        return pid

    def stop(self, sig: signal.Signals = signal.SIGINT, timeout: float = 30.0) -> int:
        """Signal the supervisor and wait for it; returns its exit code."""
        assert self.proc is not None
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode
