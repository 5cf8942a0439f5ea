"""Interop: a Modbus client that is not pymodbus (pyModbusTCP) drives the server.

Jog kinematics as in tests/integration/test_modbus.py: from rest to 10 mm/s at
100 mm/s², 0.5 mm after the 50-cycle ramp, then 10 mm/s: 1.5 mm after 100 cycles.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from pyModbusTCP.client import ModbusClient

from motion_server.tagmap import TagMap, TagType, decode, encode
from tests.modbus_support import ServerThread, modbus_site


class Tags:
    def __init__(self, client: ModbusClient, tagmap: TagMap) -> None:
        self.c = client
        self.map = tagmap

    def read(self, name: str) -> float | int | bool:
        tag = self.map.tag(name)
        regs = self.c.read_holding_registers(tag.address, tag.count)
        assert regs is not None, f"{name}: {self.c.last_error_as_txt} {self.c.last_except_as_txt}"
        if tag.type == TagType.BOOL:
            return bool(regs[0] >> (tag.bit or 0) & 1)
        return decode(tag.type, regs, self.map.word_order)

    def write(self, name: str, value: float) -> None:
        tag = self.map.tag(name)
        if tag.type == TagType.BOOL:  # read-modify-write of the command bits register
            reg = self.c.read_holding_registers(tag.address, 1)
            assert reg is not None
            bit = 1 << (tag.bit or 0)
            ok = self.c.write_single_register(
                tag.address, (reg[0] | bit) if value else (reg[0] & ~bit)
            )
        else:
            ok = self.c.write_multiple_registers(
                tag.address, encode(tag.type, value, self.map.word_order)
            )
        assert ok, f"{name}: {self.c.last_except_as_txt}"

    def step(self, cycles: int) -> None:
        self.write("Clock.StepCycles", cycles)
        self.write("Clock.Step", False)
        self.write("Clock.Step", True)

    def trigger(self, instance: str, **operands: float) -> None:
        for name, value in operands.items():
            self.write(f"{instance}.{name}", value)
        self.write(f"{instance}.Execute", False)
        self.write(f"{instance}.Execute", True)


@pytest.fixture(params=["big", "little"])
def tags(request: pytest.FixtureRequest) -> Iterator[Tags]:
    with ServerThread(modbus_site(word_order=request.param)) as srv:
        assert srv.runtime is not None
        client = ModbusClient(host="127.0.0.1", port=srv.port, unit_id=1, timeout=5.0)
        yield Tags(client, srv.runtime.tagmap)
        client.close()


def test_jog_the_master_with_pymodbustcp(tags: Tags) -> None:
    tags.trigger("MSO_1", Axis=1)
    tags.step(1)
    assert tags.read("MSO_1.DN") is True
    tags.trigger("MAJ_1", Axis=1, Speed=10.0, AccelRate=100.0, DecelRate=100.0)
    tags.step(1)
    assert (tags.read("MAJ_1.DN"), tags.read("MAJ_1.IP"), tags.read("MAJ_1.ER")) == (
        True,
        True,
        False,
    )
    assert tags.read("Axis1.CommandPosition") == pytest.approx(100.0 * 0.002**2 / 2, abs=1e-12)
    tags.step(99)
    assert tags.read("Axis1.CommandPosition") == pytest.approx(1.5, abs=1e-9)
    assert tags.read("Axis1.CommandVelocity") == pytest.approx(10.0, abs=1e-9)


def test_out_of_range_and_exceptions_with_pymodbustcp(tags: Tags) -> None:
    tags.trigger("MSO_1", Axis=1)
    tags.step(1)
    # MAJ(Axis, MotionControl, Direction, Speed, ...): Direction is operand 2 from 0
    tags.trigger("MAJ_1", Axis=1, Direction=5)
    tags.step(1)
    assert tags.read("MAJ_1.ER") is True
    assert (tags.read("MAJ_1.ERR"), tags.read("MAJ_1.EXERR")) == (13, 2)
    assert tags.read("Axis1.CommandVelocity") == 0.0
    c = tags.c
    assert c.read_holding_registers(4995, 10) is None
    assert c.last_except == 2
    assert not c.write_single_register(tags.map.tag("MAJ_1.ERR").address, 0)
    assert c.last_except == 2
