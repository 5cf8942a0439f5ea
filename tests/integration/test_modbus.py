"""Modbus TCP over a real socket (127.0.0.1, ephemeral port, manual clock), pymodbus client.

Kinematics used below (from first principles): a trapezoidal jog from rest to speed
v = 10 mm/s at a = 100 mm/s² reaches v after v/a = 0.1 s = 50 cycles of 2 ms, having
covered a·t²/2 = 0.5 mm; after k cycles (t = k·0.002 s) it is at 50·t² mm while
accelerating and 0.5 + 10·(t - 0.1) mm after.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from dataclasses import dataclass

import pytest
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.pdu import ExceptionResponse

from motion_server import config
from motion_server.runtime import Runtime
from motion_server.tagmap import TagMap, TagType, decode, encode
from tests.modbus_support import modbus_site

DT = 0.002


def jog_position(cycles: int, v: float = 10.0, a: float = 100.0) -> float:
    t = cycles * DT
    t_ramp = v / a
    if t <= t_ramp:
        return a * t * t / 2.0
    return a * t_ramp * t_ramp / 2.0 + v * (t - t_ramp)


@dataclass
class Tags:
    """Tag-name access over a pymodbus client (BOOLs through FC22 mask writes)."""

    client: AsyncModbusTcpClient
    map: TagMap
    unit: int

    async def read(self, name: str) -> float | int | bool:
        tag = self.map.tag(name)
        rr = await self.client.read_holding_registers(
            tag.address, count=tag.count, device_id=self.unit
        )
        assert not rr.isError(), f"{name}: {rr}"
        if tag.type == TagType.BOOL:
            return bool(rr.registers[0] >> (tag.bit or 0) & 1)
        return decode(tag.type, rr.registers, self.map.word_order)

    async def write(self, name: str, value: float) -> None:
        tag = self.map.tag(name)
        if tag.type == TagType.BOOL:
            bit = tag.bit or 0
            rr = await self.client.mask_write_register(
                address=tag.address,
                and_mask=~(1 << bit) & 0xFFFF,
                or_mask=int(bool(value)) << bit,
                device_id=self.unit,
            )
        else:
            rr = await self.client.write_registers(
                tag.address, encode(tag.type, value, self.map.word_order), device_id=self.unit
            )
        assert not rr.isError(), f"{name}: {rr}"

    async def step(self, cycles: int) -> None:
        """Run ``cycles`` cycles through the Clock tags (answered once they ran)."""
        await self.write("Clock.StepCycles", cycles)
        await self.write("Clock.Step", False)
        await self.write("Clock.Step", True)

    async def trigger(self, instance: str, trigger: str = "Execute", **operands: float) -> None:
        for name, value in operands.items():
            await self.write(f"{instance}.{name}", value)
        await self.write(f"{instance}.{trigger}", False)
        await self.write(f"{instance}.{trigger}", True)


@dataclass
class Server:
    runtime: Runtime
    client: AsyncModbusTcpClient
    tags: Tags
    port: int


async def start(site: config.SiteMap) -> tuple[Runtime, asyncio.Task[None], int]:
    rt = Runtime(site)
    task = asyncio.create_task(rt.serve())
    await asyncio.wait_for(rt.ready.wait(), 10.0)
    assert rt.modbus is not None
    return rt, task, rt.modbus.port


@pytest.fixture(params=["big", "little"])
async def server(request: pytest.FixtureRequest) -> AsyncIterator[Server]:
    site = modbus_site(word_order=request.param)
    rt, task, port = await start(site)
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=5)
    assert await client.connect()
    yield Server(rt, client, Tags(client, rt.tagmap, 1), port)
    client.close()
    rt.request_stop()
    await asyncio.wait_for(task, 10.0)


async def test_power_and_jog_the_master_by_register_writes(server: Server) -> None:
    tags = server.tags
    assert await tags.read("Clock.Mode") == 1  # manual: nothing moves until we step
    await tags.trigger("MSO_1", Axis=1)
    assert await tags.read("MSO_1.DN") is False  # not scanned yet
    await tags.step(1)
    assert await tags.read("Clock.Cycle") == 1
    assert await tags.read("MSO_1.DN") is True
    assert await tags.read("Axis1.AxisState") == 2  # Servo Control
    assert await tags.read("Axis1.PLCopenState") == 2  # StandStill

    await tags.trigger(
        "MAJ_1", Axis=1, Direction=0, Speed=10.0, SpeedUnits=0, AccelRate=100.0, DecelRate=100.0
    )
    await tags.step(1)
    # DN and IP in the same scan, read in one request of the status register
    status = server.runtime.tagmap.tag("MAJ_1.DN")
    rr = await server.client.read_holding_registers(status.address, count=1, device_id=1)
    bits = {
        t.field: bool(rr.registers[0] >> (t.bit or 0) & 1)
        for t in server.runtime.tagmap.at(status.address)
        if t.field in ("EN", "DN", "ER", "PC", "IP", "AC")
    }
    assert bits == {"EN": True, "DN": True, "ER": False, "PC": False, "IP": True, "AC": False}
    assert await tags.read("Axis1.CommandPosition") == pytest.approx(jog_position(1), abs=1e-12)

    await tags.step(24)  # 25 cycles: mid-ramp, v = a·t = 5 mm/s
    assert await tags.read("Axis1.CommandPosition") == pytest.approx(jog_position(25), abs=1e-9)
    assert jog_position(25) == pytest.approx(0.125)
    assert await tags.read("Axis1.CommandVelocity") == pytest.approx(5.0, abs=1e-9)
    await tags.step(75)  # 100 cycles: 0.5 mm of ramp + 10 mm/s for 0.1 s = 1.5 mm
    assert await tags.read("Axis1.CommandPosition") == pytest.approx(1.5, abs=1e-9)
    assert await tags.read("Axis1.ActualPosition") == pytest.approx(1.5, abs=1e-9)  # virtual
    assert await tags.read("Axis1.CommandVelocity") == pytest.approx(10.0, abs=1e-9)
    assert int(await tags.read("Axis1.MotionStatus")) & (1 << 3)  # Jog
    assert await tags.read("Axis1.PLCopenState") == 7  # ContinuousMotion
    assert await tags.read("MAJ_1.IP") is True
    assert await tags.read("Clock.Cycle") == 101
    assert await tags.read("Clock.SimTime") == pytest.approx(101 * DT, abs=1e-12)


async def test_out_of_range_operand_gives_er_err_13_and_no_motion(server: Server) -> None:
    tags = server.tags
    await tags.trigger("MSO_1", Axis=1)
    await tags.step(1)
    # MAM(Axis, MotionControl, MoveType, Position, Speed, SpeedUnits, AccelRate, ...):
    # AccelRate is operand 6 counting from 0
    await tags.trigger("MAM_1", Axis=1, MoveType=1, Position=5.0, Speed=10.0, AccelRate=-5.0)
    await tags.step(1)
    assert await tags.read("MAM_1.ER") is True
    assert await tags.read("MAM_1.DN") is False
    assert await tags.read("MAM_1.ERR") == 13
    assert await tags.read("MAM_1.EXERR") == 6
    assert int(await tags.read("MAM_1.FLAGS")) == (1 << 31) | (1 << 28)  # EN, ER
    await tags.step(10)
    assert await tags.read("Axis1.CommandPosition") == 0.0
    assert await tags.read("Axis1.PLCopenState") == 2  # StandStill


async def test_plcopen_move_absolute_over_lreal_operands(server: Server) -> None:
    # 1 mm at 10 mm/s, 100 mm/s²: 0.1 s up to speed (0.5 mm), 0.1 s down (0.5 mm)
    tags = server.tags
    await tags.trigger("MC_Power_1", trigger="Enable", Axis=2)
    await tags.step(1)
    assert await tags.read("MC_Power_1.Status") is True
    await tags.trigger(
        "MC_MoveAbsolute_1",
        Axis=2,
        Position=1.0,
        Velocity=10.0,
        Acceleration=100.0,
        Deceleration=100.0,
        Jerk=0.0,
    )
    await tags.step(50)
    assert await tags.read("Axis2.CommandPosition") == pytest.approx(0.5, abs=1e-9)
    assert await tags.read("MC_MoveAbsolute_1.Busy") is True
    await tags.step(60)
    assert await tags.read("MC_MoveAbsolute_1.Done") is True
    assert await tags.read("Axis2.CommandPosition") == 1.0  # lands exactly on target


async def test_fc23_writes_operands_and_trigger_and_reads_the_last_completed_cycle(
    server: Server,
) -> None:
    m = server.runtime.tagmap
    block = m.block("MSO_1")
    order = m.word_order
    # the command region: Execute bit register, a pad, then Axis (DINT)
    axis = m.tag("MSO_1.Axis")
    values = [1] + [0] * (axis.address - block.command_start - 1) + encode(TagType.DINT, 2, order)
    rr = await server.client.readwrite_registers(
        read_address=block.base,
        read_count=5,
        write_address=block.command_start,
        values=values,
        device_id=1,
    )
    assert not rr.isError(), rr
    assert rr.registers == [0, 0, 0, 0, 0]  # the write is not scanned yet
    assert server.runtime.system["MSO_1"].inputs["Axis"] == 2
    await server.tags.step(1)
    assert await server.tags.read("MSO_1.DN") is True
    assert await server.tags.read("Axis2.AxisState") == 2


async def test_a_write_that_splits_a_32_bit_value_is_accepted(server: Server) -> None:
    m = server.runtime.tagmap
    speed = m.tag("MAJ_1.Speed")
    words = encode(TagType.REAL, 42.5, m.word_order)
    for k, word in enumerate(words):
        rr = await server.client.write_register(speed.address + k, word, device_id=1)
        assert not rr.isError(), rr
    assert await server.tags.read("MAJ_1.Speed") == 42.5
    assert server.runtime.system["MAJ_1"].inputs["Speed"] == 42.5


async def test_bad_requests_get_exceptions(server: Server) -> None:
    c, m = server.client, server.runtime.tagmap

    async def exception(coro: object) -> int:
        rr = await coro  # type: ignore[misc]
        assert isinstance(rr, ExceptionResponse), rr
        return int(rr.exception_code)

    assert await exception(c.read_holding_registers(4990, count=20, device_id=1)) == 2
    assert await exception(c.read_holding_registers(65530, count=6, device_id=1)) == 2
    assert await exception(c.write_register(m.tag("MAJ_1.ERR").address, 1, device_id=1)) == 2
    # a write that runs from the command region into the read-only tail of the block
    block = m.block("MSO_1")
    span = block.command_end - block.command_start + 1
    assert await exception(c.write_registers(block.command_start, [0] * span, device_id=1)) == 2
    assert await exception(c.write_register(m.tag("Clock.Mode").address, 9, device_id=1)) == 3
    assert await exception(c.read_coils(0, count=8, device_id=1)) == 1
    assert await exception(c.read_input_registers(0, count=2, device_id=1)) == 1
    assert await exception(c.read_holding_registers(0, count=2, device_id=7)) == 11
    # none of it moved anything, and the server still answers
    assert await server.tags.read("Clock.Cycle") == 0
    assert await server.tags.read("Clock.Mode") == 1


async def test_unparseable_requests_never_take_the_server_down(server: Server) -> None:
    garbage = [
        b"\x00\x01\x00\x00\x00\x02\x01",  # truncated
        b"\x00\x02\x00\x00\x00\x03\x01\x63\x00",  # function code 0x63
        b"\x00\x03\x00\x07\x00\x06\x01\x03\x00\x00\x00\x02",  # protocol id 7
        b"\x00\x04\x00\x00\x00\x06\x01\x03\x00\x00\x07\xd0",  # count 2000
        bytes(range(256)),
    ]
    for junk in garbage:
        reader, writer = await asyncio.open_connection("127.0.0.1", server.port)
        writer.write(junk)
        await writer.drain()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(reader.read(256), 0.3)
        writer.close()
    assert await server.tags.read("Clock.Mode") == 1
    await server.tags.step(3)
    assert await server.tags.read("Clock.Cycle") == 3


async def test_remote_clock_disabled_refuses_clock_writes() -> None:
    site = modbus_site()
    site = site.model_copy(
        update={"controller": site.controller.model_copy(update={"remote_clock": False})}
    )
    rt, task, port = await start(site)
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=5)
    try:
        assert await client.connect()
        step = rt.tagmap.tag("Clock.Step")
        rr = await client.write_register(step.address, 1, device_id=1)
        assert isinstance(rr, ExceptionResponse) and rr.exception_code == 2
    finally:
        client.close()
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)


async def test_a_long_step_is_answered_once_every_cycle_ran(server: Server) -> None:
    # 1000 cycles run in chunks that yield to the loop; the write's answer waits for all
    await server.tags.step(1000)
    assert await server.tags.read("Clock.Cycle") == 1000
    assert await server.tags.read("Diagnostics.Heartbeat") == 1000
    assert await server.tags.read("Clock.SimTime") == pytest.approx(2.0, abs=1e-12)


async def test_unit_id_0_answers_every_unit_id() -> None:
    rt, task, port = await start(modbus_site(unit_id=0))
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=5)
    try:
        assert await client.connect()
        mode = rt.tagmap.tag("Clock.Mode")
        for unit in (0, 1, 7, 255):
            rr = await client.read_holding_registers(mode.address, count=1, device_id=unit)
            assert not rr.isError() and rr.registers == [1], (unit, rr)
    finally:
        client.close()
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)


async def test_gear_a_slave_with_mag_over_modbus(server: Server) -> None:
    """MAG 1:3 as a fraction of counts (both axes 1000 counts/mm), command reference, no
    clutch. An incremental MAM of 3 mm on the master (v = 10 mm/s, a = 100 mm/s²: lasts
    d/v + v/a = 0.4 s = 200 cycles) moves the slave floor(3000 / 3) = 1000 counts = 1 mm,
    exactly."""
    tags = server.tags
    for axis in (1, 2):
        await tags.trigger("MSO_1", Axis=axis)
        await tags.step(1)
        assert await tags.read(f"Axis{axis}.AxisState") == 2
        await tags.write("MSO_1.Execute", False)  # the rung goes false for a scan
        await tags.step(1)
    await tags.trigger(
        "MAG_1", SlaveAxis=2, MasterAxis=1, RatioFormat=1, SlaveCounts=1, MasterCounts=3,
        MasterReference=1, Clutch=1,
    )  # fmt: skip
    await tags.step(1)
    status = server.runtime.tagmap.tag("MAG_1.DN")
    rr = await server.client.read_holding_registers(status.address, count=1, device_id=1)
    bits = {t.field: bool(rr.registers[0] >> (t.bit or 0) & 1)
            for t in server.runtime.tagmap.at(status.address)}  # fmt: skip
    assert bits["DN"] and bits["IP"] and not bits["ER"]  # DN and IP in the same scan
    assert int(await tags.read("Axis2.MotionStatus")) & (1 << 4)  # GearingStatus

    await tags.trigger(
        "MAM_1", Axis=1, MoveType=1, Position=3.0, Speed=10.0, AccelRate=100.0, DecelRate=100.0
    )
    await tags.step(100)  # half way: the slave follows at a third, to within one count
    master = float(await tags.read("Axis1.CommandPosition"))
    slave = float(await tags.read("Axis2.CommandPosition"))
    assert 0.5 < master < 2.5
    assert abs(slave - master / 3.0) <= 0.001
    await tags.step(150)  # past the 200 cycles of the move
    assert await tags.read("MAM_1.PC") is True
    assert await tags.read("Axis1.CommandPosition") == 3.0
    assert await tags.read("Axis2.CommandPosition") == 1.0
    await tags.step(500)  # the slave's drive settles on its command
    assert await tags.read("Axis2.ActualPosition") == pytest.approx(1.0, abs=0.001)
    assert await tags.read("MAG_1.IP") is True  # gearing stays in process
