"""A trigger left high by a client that disconnected never re-fires on reconnect, and a
watchdog stop is not undone by the client coming back (real sockets, manual clock).

MAM incremental move of 5 mm at 10 mm/s, 100 mm/s² (the defaults): 0.1 s to speed
(0.5 mm), 0.4 s at speed (4 mm), 0.1 s to rest (0.5 mm): 0.6 s = 300 cycles of 2 ms.
"""

from __future__ import annotations

import asyncio

import pytest
from pymodbus.client import AsyncModbusTcpClient

from motion_server import config
from motion_server.tagmap import encode
from tests.integration.test_modbus import Tags, start
from tests.modbus_support import SITE

WATCHDOG = """
[[watchdogs]]
name = "HMI1"
timeout = 0.1
group = "Group1"
stop_mode = "fast_stop"
"""


async def connect(port: int, rt_map: object) -> tuple[AsyncModbusTcpClient, Tags]:
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=5)
    assert await client.connect()
    return client, Tags(client, rt_map, 1)  # type: ignore[arg-type]


async def test_a_stale_execute_rewritten_after_reconnect_fires_nothing() -> None:
    site = config.parse(SITE.format(word_order="big", unit_id=1), "reconnect.toml")
    rt, task, port = await start(site)
    try:
        a, tags = await connect(port, rt.tagmap)
        await tags.trigger("MSO_1", Axis=1)
        await tags.step(1)
        await tags.trigger("MAM_1", Axis=1, MoveType=1, Position=5.0)
        await tags.step(400)
        assert await tags.read("Axis1.CommandPosition") == pytest.approx(5.0)
        a.close()  # gone with MAM_1.Execute still high
        await asyncio.sleep(0)
        assert rt.image.read("MAM_1.Execute") is True

        b, tags = await connect(port, rt.tagmap)
        # a cyclic master re-sends its whole output block: trigger register + operands
        trig = rt.tagmap.tag("MAM_1.Execute")
        pos = rt.tagmap.tag("MAM_1.Position")
        regs = [0] * (pos.address + pos.count - trig.address)
        regs[0] = 1 << (trig.bit or 0)
        for name in ("Axis", "MoveType", "Position", "Speed", "AccelRate", "DecelRate"):
            t = rt.tagmap.tag(f"MAM_1.{name}")
            if trig.address <= t.address and t.address + t.count <= pos.address + pos.count:
                value = rt.image.read(t)
                words = encode(t.type, value, rt.tagmap.word_order)
                regs[t.address - trig.address : t.address - trig.address + t.count] = words
        rr = await b.write_registers(trig.address, regs, device_id=1)
        assert not rr.isError()
        await tags.step(400)
        assert await tags.read("Axis1.CommandPosition") == pytest.approx(5.0)  # no 2nd move
        # an explicit 0 -> 1 is a new command: the second 5 mm
        await tags.write("MAM_1.Execute", False)
        await tags.step(1)
        await tags.write("MAM_1.Execute", True)
        await tags.step(400)
        assert await tags.read("Axis1.CommandPosition") == pytest.approx(10.0)
        b.close()
    finally:
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)


async def test_watchdog_stop_then_reconnect_does_not_restart_motion() -> None:
    text = SITE.format(word_order="big", unit_id=1) + WATCHDOG
    rt, task, port = await start(config.parse(text, "reconnect-watchdog.toml"))
    try:
        a, tags = await connect(port, rt.tagmap)
        await tags.trigger("MSO_1", Axis=1)
        await tags.step(1)
        await tags.trigger("MAJ_1", Axis=1, Speed=10.0, AccelRate=100.0, DecelRate=100.0)
        await tags.write("HMI1.Heartbeat", 1)
        await tags.step(40)
        assert await tags.read("Axis1.CommandVelocity") == pytest.approx(8.0)  # 100·0.08
        a.close()  # the HMI dies: no more beats
        await asyncio.sleep(0)

        b, tags = await connect(port, rt.tagmap)
        await tags.step(100)  # past T = 50 cycles: tripped, stopped, latched
        assert await tags.read("HMI1.Fault") is True
        assert await tags.read("Axis1.CommandVelocity") == 0.0
        for k in range(2, 5):  # the HMI is back: beats, re-sends its jog trigger
            await tags.write("HMI1.Heartbeat", k)
            await tags.write("MAJ_1.Execute", True)
            await tags.step(20)
        assert await tags.read("Axis1.CommandVelocity") == 0.0
        assert await tags.read("HMI1.Fault") is True
        assert await tags.read("Axis1.AxisState") == 3  # faulted until reset
        b.close()
    finally:
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)
