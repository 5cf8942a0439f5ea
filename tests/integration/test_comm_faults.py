"""Communication faults over Modbus TCP: an HMI-like client's timeout fires while the
server delays or drops its answers, and it recovers once the fault is over
(``frontends/comm_faults.py``; tags ``Clock.CommFault``, ``CommDelay``, ``CommDuration``,
``CommClientPort``).

The HMI is a plain pymodbus client, as a panel's driver is: it polls ``Clock.Cycle`` with
a 0.5 s timeout and, after a timeout, reconnects and polls again. The fault windows are
seconds long so that a busy machine does not blur them; every check is on what the HMI
saw inside or after a window, never on how fast the server was.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ModbusException

from motion_clients import ClientMap, MotionClient
from motion_server import config
from tests.clients_support import serving
from tests.modbus_support import ServerThread

HMI_TIMEOUT = 0.5


@dataclass
class Poll:
    at: float  # monotonic seconds when the read was sent
    ok: bool
    latency: float


def local_port(client: AsyncModbusTcpClient) -> int:
    """The TCP port the client connects from (pymodbus keeps its transport in ``ctx``)."""
    transport = client.ctx.transport
    assert transport is not None
    return int(transport.get_extra_info("sockname")[1])


@dataclass
class Hmi:
    """Polls register 0 (Clock.Cycle) every 50 ms; reconnects after a timeout."""

    port: int
    polls: list[Poll] = field(default_factory=list)
    local_port: int = 0

    async def run(self, until: float) -> None:
        client = AsyncModbusTcpClient("127.0.0.1", port=self.port, timeout=HMI_TIMEOUT, retries=0)
        await client.connect()
        self.local_port = local_port(client)
        try:
            while time.monotonic() < until:
                t0 = time.monotonic()
                try:
                    rr = await client.read_holding_registers(0, count=2, device_id=1)
                    ok = not rr.isError()
                except (TimeoutError, ModbusException, ConnectionError):
                    ok = False
                self.polls.append(Poll(t0, ok, time.monotonic() - t0))
                if not ok:  # what a panel does: drop the connection, connect again
                    client.close()
                    await client.connect()
                    self.local_port = local_port(client)
                await asyncio.sleep(0.05)
        finally:
            client.close()

    def between(self, start: float, end: float) -> list[Poll]:
        return [p for p in self.polls if start <= p.at < end]


@pytest.fixture
def served() -> Iterator[tuple[ServerThread, ClientMap]]:
    with serving(config.load(None)) as s:
        yield s


async def set_fault(port: int, tagmap: ClientMap, **tags: int) -> None:
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", port) as admin:
        await admin.write_many({f"Clock.{k}": v for k, v in tags.items() if k != "CommFault"})
        await admin.write("Clock.CommFault", tags.get("CommFault", 0))


async def test_dropped_answers_make_the_hmi_time_out_until_the_fault_ends(
    served: tuple[ServerThread, ClientMap],
) -> None:
    srv, tagmap = served
    hmi = Hmi(srv.port)
    start = time.monotonic()
    task = asyncio.create_task(hmi.run(start + 6.0))
    await asyncio.sleep(1.0)
    t_on = time.monotonic()
    await set_fault(srv.port, tagmap, CommFault=2, CommDuration=2000, CommClientPort=0)
    t_off = t_on + 2.0
    await task
    before, during = hmi.between(start, t_on), hmi.between(t_on + 0.1, t_off - 0.1)
    after = hmi.between(t_off + 1.0, start + 6.0)
    assert before and all(p.ok for p in before)
    assert during and not any(p.ok for p in during)  # every poll in the window timed out
    assert all(p.latency >= HMI_TIMEOUT for p in during)
    assert after and all(p.ok for p in after)  # recovered
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", srv.port) as mc:
        assert await mc.read("Clock.CommFault") == 0  # over by itself
    assert srv.runtime is not None


async def test_a_delay_for_one_client_only(served: tuple[ServerThread, ClientMap]) -> None:
    srv, tagmap = served
    hmi = Hmi(srv.port)
    start = time.monotonic()
    task = asyncio.create_task(hmi.run(start + 7.0))
    await asyncio.sleep(1.0)
    # the HMI's connection: the port it polls from now
    await set_fault(
        srv.port, tagmap, CommFault=1, CommDelay=800, CommDuration=0, CommClientPort=hmi.local_port
    )
    t_set = time.monotonic()
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", srv.port, timeout=2.0) as other:
        t0 = time.monotonic()
        await other.read("Clock.Cycle")
        other_latency = time.monotonic() - t0
        await asyncio.sleep(3.0)
        await other.write("Clock.CommFault", 0)
    await task
    assert other_latency < 0.8  # another client is not delayed
    # the HMI times out (800 ms > 0.5 s) on its next poll; it reconnects from another
    # port, which the fault does not name, and recovers
    failed = [p for p in hmi.between(t_set, t_set + 1.0) if not p.ok]
    assert failed and failed[0].latency >= HMI_TIMEOUT
    later = hmi.between(failed[-1].at + 0.1, start + 7.0)
    assert later and all(p.ok for p in later)


async def test_a_short_delay_stays_below_the_timeout(
    served: tuple[ServerThread, ClientMap],
) -> None:
    srv, tagmap = served
    hmi = Hmi(srv.port)
    start = time.monotonic()
    task = asyncio.create_task(hmi.run(start + 4.0))
    await asyncio.sleep(0.5)
    t_on = time.monotonic()
    await set_fault(srv.port, tagmap, CommFault=1, CommDelay=200, CommDuration=2000)
    await task
    during = hmi.between(t_on + 0.3, t_on + 1.8)
    assert during and all(p.ok and p.latency >= 0.2 for p in during)


async def test_the_command_line_sets_and_clears_a_fault(
    served: tuple[ServerThread, ClientMap],
) -> None:
    srv, tagmap = served
    cli = [sys.executable, "-m", "motion_server.cli", "comm-fault"]
    port = ["--port", str(srv.port)]
    done = subprocess.run(
        [*cli, "drop", "--duration", "30", "--client-port", "1", *port],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", srv.port) as mc:
        seen = await mc.read_many(["Clock.CommFault", "Clock.CommDuration", "Clock.CommClientPort"])
        assert seen == {
            "Clock.CommFault": 2,
            "Clock.CommDuration": 30000,
            "Clock.CommClientPort": 1,
        }
    done = subprocess.run([*cli, "off", *port], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", srv.port) as mc:
        assert await mc.read("Clock.CommFault") == 0
    bad = subprocess.run([*cli, "delay", *port], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1
