"""``motion-server run`` on a site map, as deployed (the scan and each front-end in a
process of their own), for campaigns that measure its deadlines.

The parent reads the OPC UA endpoint from the server's log, and its statistics over
OPC UA as any SCADA would: ``Diagnostics.Overruns`` and ``Diagnostics.DroppedCycles``
from the site's namespace, the current subscription count from the standard server
diagnostics (``Server.ServerDiagnostics.ServerDiagnosticsSummary``). ``stop()`` sends
SIGINT: the programmed stop, then exit 0.
"""

from __future__ import annotations

import asyncio
import re
import signal
import sys
from pathlib import Path

from asyncua import Client, ua

from motion_server import config

ROOT = Path(__file__).resolve().parents[2]
ENDPOINT = re.compile(r"OPC UA on (opc\.tcp://[^ ]+/)")
#: Server.ServerDiagnostics.ServerDiagnosticsSummary.CurrentSubscriptionCount
SUBSCRIPTIONS = 2285


class ServerProcess:
    """The parent's handle: start, ``stats()``, stop."""

    def __init__(self, site_text: str, directory: Path) -> None:
        self.site_file = directory / "site.toml"
        self.site_file.write_text(site_text)
        self.namespace_uri = config.parse(site_text).site.namespace_uri
        self.log_file = directory / "server.log"
        self.proc: asyncio.subprocess.Process | None = None
        self.endpoint = ""
        self.port = 0
        self.namespace_index = 0
        self._stats_client: Client | None = None

    async def start(self) -> ServerProcess:
        self.proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-m",
            "motion_server.cli",
            "run",
            str(self.site_file),
            cwd=self.site_file.parent,
            stdin=asyncio.subprocess.DEVNULL,
            stdout=asyncio.subprocess.DEVNULL,
            stderr=self.log_file.open("wb"),
        )
        loop = asyncio.get_running_loop()
        give_up = loop.time() + 120.0
        while loop.time() < give_up:
            found = ENDPOINT.search(self.log())
            if found:
                self.endpoint = found.group(1)
                break
            if self.proc.returncode is not None:
                raise RuntimeError(f"the server process ended:\n{self.log()[-3000:]}")
            await asyncio.sleep(0.1)
        else:
            raise RuntimeError(f"the server did not serve OPC UA:\n{self.log()[-3000:]}")
        self.port = int(self.endpoint.rsplit(":", 1)[1].strip("/"))
        return self

    async def stats(self, client: Client) -> dict[str, int]:
        """Overruns, dropped cycles and current subscriptions, read with ``client``."""
        if not self.namespace_index:
            self.namespace_index = await client.get_namespace_index(self.namespace_uri)
        ns = self.namespace_index
        overruns, dropped, subscriptions = await client.read_values(
            [
                client.get_node(ua.NodeId("Diagnostics.Overruns", ns)),
                client.get_node(ua.NodeId("Diagnostics.DroppedCycles", ns)),
                client.get_node(ua.NodeId(SUBSCRIPTIONS)),
            ]
        )
        return {"overruns": overruns, "dropped": dropped, "subscriptions": subscriptions}

    def child(self, role: str) -> int:
        """The pid of the child process serving ``role`` (``scan``, ``opcua``, ``modbus``)."""
        assert self.proc is not None
        wanted = ["motion_server.scan"] if role == "scan" else ["motion_server.frontends", role]
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
                argv = (entry / "cmdline").read_bytes().split(b"\0")
            except (OSError, ValueError, IndexError):
                continue  # gone meanwhile
            words = [a.decode(errors="replace") for a in argv]
            if ppid == self.proc.pid and all(w in words for w in wanted):
                return int(entry.name)
        raise RuntimeError(f"no {role} child of {self.proc.pid}")

    def log(self) -> str:
        return self.log_file.read_text(errors="replace")

    async def stop(self) -> None:
        if self.proc is None or self.proc.returncode is not None:
            return
        self.proc.send_signal(signal.SIGINT)
        try:
            await asyncio.wait_for(self.proc.wait(), 30.0)
        except TimeoutError:
            self.proc.kill()
            await self.proc.wait()
