"""Modbus access control over real sockets on 127.0.0.1: allowlist, read-only mode,
per-network write ranges, connection limit and idle timeout."""

from __future__ import annotations

import asyncio
import struct
from collections.abc import AsyncIterator, Callable

import pytest
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.pdu import ExceptionResponse

from motion_server import config
from motion_server.runtime import Runtime
from tests.integration.test_modbus import Tags, start
from tests.modbus_support import SITE


def site_with(extra: str) -> config.SiteMap:
    text = SITE.format(word_order="big", unit_id=1) + extra
    return config.parse(text, "access-test.toml")


Started = tuple[Runtime, AsyncModbusTcpClient, Tags]


@pytest.fixture
async def serve() -> AsyncIterator[Callable[[str], object]]:
    """``rt, client, tags = await serve(extra_toml)``; everything closed afterwards."""
    opened: list[tuple[Runtime, asyncio.Task[None], AsyncModbusTcpClient]] = []

    async def open_(extra: str) -> Started:
        rt, task, port = await start(site_with(extra))
        client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
        await client.connect()
        opened.append((rt, task, client))
        return rt, client, Tags(client, rt.tagmap, 1)

    yield open_
    for rt, task, client in opened:
        client.close()
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)


def read_frame(tid: int, address: int, count: int, unit: int = 1) -> bytes:
    return struct.pack(">HHHBBHH", tid, 0, 6, unit, 3, address, count)


async def raw_read(port: int, address: int = 0, count: int = 1) -> bytes:
    """One FC3 request on a fresh connection; the answer, or b"" if the server closed."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(read_frame(1, address, count))
        await writer.drain()
        return await asyncio.wait_for(reader.read(256), 3.0)
    except ConnectionResetError:
        return b""
    finally:
        writer.close()


async def test_a_client_outside_the_allowed_networks_is_disconnected(serve) -> None:  # type: ignore[no-untyped-def]
    rt, _, _ = await serve('\n[modbus.access]\nallow = ["10.0.0.0/8"]\n')
    assert rt.modbus is not None
    assert await raw_read(rt.modbus.port) == b""
    assert rt.modbus.refused_connections == 2  # the fixture's client and this one
    assert not rt.modbus.connections


async def test_a_client_inside_the_allowed_networks_is_served(serve) -> None:  # type: ignore[no-untyped-def]
    _rt, _, tags = await serve('\n[modbus.access]\nallow = ["10.0.0.0/8", "127.0.0.0/8"]\n')
    assert await tags.read("Clock.Mode") == 1
    await tags.write("MAJ_1.Speed", 25.0)
    assert await tags.read("MAJ_1.Speed") == 25.0


async def test_read_only_mode_refuses_every_write_and_serves_reads(serve) -> None:  # type: ignore[no-untyped-def]
    rt, client, tags = await serve("\n[modbus.access]\nread_only = true\n")
    speed = rt.tagmap.tag("MAJ_1.Speed")
    before = rt.image.read(speed)
    rr = await client.write_registers(speed.address, [0x41C8, 0], device_id=1)  # 25.0
    assert isinstance(rr, ExceptionResponse) and rr.exception_code == 2
    assert rt.image.read(speed) == before
    assert await tags.read("MAJ_1.Speed") == before


async def test_a_write_rule_lets_operators_write_instructions_but_not_the_clock(serve) -> None:  # type: ignore[no-untyped-def]
    rt, client, tags = await serve(
        '\n[[modbus.access.rules]]\nnetworks = ["127.0.0.0/8"]\nwrite = ["Instructions"]\n'
    )
    await tags.write("MAJ_1.Speed", 25.0)
    assert rt.image.read("MAJ_1.Speed") == 25.0
    cycles = rt.tagmap.tag("Clock.StepCycles")
    rr = await client.write_registers(cycles.address, [0, 7], device_id=1)
    assert isinstance(rr, ExceptionResponse) and rr.exception_code == 2
    assert rt.image.read(cycles) == 1  # unchanged


async def test_register_ranges_in_a_write_rule(serve) -> None:  # type: ignore[no-untyped-def]
    speed_tag = "MAJ_1.Speed"
    rt0, _, _ = await serve("")
    speed = rt0.tagmap.tag(speed_tag)
    lo, hi = speed.address, speed.address + speed.count - 1
    rt, client, tags = await serve(
        f'\n[[modbus.access.rules]]\nnetworks = ["127.0.0.1/32"]\nwrite = ["{lo}-{hi}"]\n'
    )
    await tags.write(speed_tag, 30.0)
    assert rt.image.read(speed_tag) == 30.0
    rr = await client.write_registers(lo, [0, 0, 0], device_id=1)  # one past the range
    assert isinstance(rr, ExceptionResponse) and rr.exception_code == 2
    assert rt.image.read(speed_tag) == 30.0


async def test_connections_past_the_limit_are_closed_and_the_others_served(serve) -> None:  # type: ignore[no-untyped-def]
    rt, _, tags = await serve("\n[modbus.access]\nmax_connections = 3\n")
    assert rt.modbus is not None
    port = rt.modbus.port
    # the fixture's client holds one; two more fill the limit
    held = [await asyncio.open_connection("127.0.0.1", port) for _ in range(2)]
    for reader, writer in held:  # each of them is served
        writer.write(read_frame(7, 0, 1))
        answer = await asyncio.wait_for(reader.readexactly(11), 3.0)
        assert answer[:2] == b"\x00\x07" and answer[7] == 3
    assert await raw_read(port) == b""  # the fourth is closed at once
    assert rt.modbus.refused_connections == 1
    assert await tags.read("Clock.Mode") == 1
    for _, writer in held:
        writer.close()
    # a freed slot is usable again (the server noticed the closes)
    for _ in range(100):
        if len(rt.modbus.connections) <= 1:
            break
        await asyncio.sleep(0.01)
    assert (await raw_read(port))[7] == 3


async def test_an_idle_connection_is_closed_after_the_timeout(serve) -> None:  # type: ignore[no-untyped-def]
    rt, _, _ = await serve("\n[modbus.access]\nidle_timeout = 0.3\n")
    assert rt.modbus is not None
    loop = asyncio.get_running_loop()
    # the server starts the idle clock when it accepts, before open_connection returns
    t0 = loop.time()
    reader, writer = await asyncio.open_connection("127.0.0.1", rt.modbus.port)
    assert await asyncio.wait_for(reader.read(10), 5.0) == b""  # EOF: the server closed
    waited = loop.time() - t0
    assert 0.3 <= waited < 2.0
    assert rt.modbus.idle_closed >= 1
    writer.close()
