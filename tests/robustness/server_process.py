"""A motion-server runtime in its own process, for campaigns that measure its deadlines.

In a thread of the test process the server would share the interpreter lock with the
test's own clients: on a loaded machine each handover can wait for an operating-system
time slice, and the server's loop then runs late for reasons a deployed server (a process
of its own) does not have. The parent talks to the child over stdin/stdout, one JSON
object per line:

- the child prints ``{"endpoint", "port", "ns"}`` once serving;
- ``stats`` -> ``{"overruns", "dropped", "subscriptions"}``;
- ``stop`` -> the runtime's programmed stop; the child exits.

Run as ``python -m tests.robustness.server_process SITE_FILE``.
"""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path
from typing import Any

from motion_server import config
from motion_server.runtime import Runtime

ROOT = Path(__file__).resolve().parents[2]


async def _child(site_file: str) -> None:
    rt = Runtime(config.load(site_file))
    task = asyncio.create_task(rt.serve())
    await asyncio.wait_for(rt.ready.wait(), 60.0)
    assert rt.opcua is not None and rt.opcua.server is not None
    service = rt.opcua.server.iserver.subscription_service

    def say(obj: dict[str, Any]) -> None:
        sys.stdout.write(json.dumps(obj) + "\n")
        sys.stdout.flush()

    say({"endpoint": rt.opcua.endpoint, "port": rt.opcua.port, "ns": rt.opcua.namespace_index})
    loop = asyncio.get_running_loop()
    reader = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
    while True:
        line = (await reader.readline()).decode().strip()
        if line == "stats":
            subs = len(service.subscriptions)
            say({"overruns": rt.overruns, "dropped": rt.dropped, "subscriptions": subs})
        elif line in ("stop", ""):  # "" : the parent went away
            break
    rt.request_stop()
    await asyncio.wait_for(task, 30.0)


class ServerProcess:
    """The parent's handle: start, ``stats()``, stop."""

    def __init__(self, site_text: str, directory: Path) -> None:
        self.site_file = directory / "site.toml"
        self.site_file.write_text(site_text)
        self.log_file = directory / "server.log"
        self.proc: asyncio.subprocess.Process | None = None
        self.endpoint = ""
        self.port = 0
        self.namespace_index = 0

    async def start(self) -> ServerProcess:
        self.proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-m",
            "tests.robustness.server_process",
            str(self.site_file),
            cwd=ROOT,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            stderr=self.log_file.open("wb"),
        )
        hello = await self._line(60.0)
        self.endpoint, self.port, self.namespace_index = (
            hello["endpoint"],
            hello["port"],
            hello["ns"],
        )
        return self

    async def _line(self, timeout: float) -> dict[str, Any]:
        assert self.proc is not None and self.proc.stdout is not None
        raw = await asyncio.wait_for(self.proc.stdout.readline(), timeout)
        if not raw:
            raise RuntimeError(f"the server process ended:\n{self.log_file.read_text()[-3000:]}")
        result: dict[str, Any] = json.loads(raw)
        return result

    async def stats(self) -> dict[str, int]:
        assert self.proc is not None and self.proc.stdin is not None
        self.proc.stdin.write(b"stats\n")
        await self.proc.stdin.drain()
        return await self._line(10.0)

    def log(self) -> str:
        return self.log_file.read_text(errors="replace")

    async def stop(self) -> None:
        if self.proc is None or self.proc.stdin is None:
            return
        if self.proc.returncode is None:
            self.proc.stdin.write(b"stop\n")
            await self.proc.stdin.drain()
            try:
                await asyncio.wait_for(self.proc.wait(), 30.0)
            except TimeoutError:
                self.proc.kill()
                await self.proc.wait()


if __name__ == "__main__":
    asyncio.run(_child(sys.argv[1]))
