"""Cam tables as tags over real sockets (127.0.0.1, ephemeral ports, manual clock): points
written over Modbus (FC16) and over OPC UA (the array views) land in the kernel's table;
the CAM_PROFILE Status reads 0 until a profile is calculated, then 2, then 2 + n while n
cams run on it.

Addresses from the documented layout (tagmap/layout.py, docs/modbus.md): the first table
at the cam base 30000; a block is 8 + 6·capacity registers rounded up to a multiple of
100, so Cam1 (capacity 4: 32 registers) spans 30000-30099 and Cam2 starts at 30100; in a
table at base B, Length is at B+6 and element k's Master at B+8+6k, Slave at B+10+6k,
SegmentType at B+12+6k.
"""

from __future__ import annotations

import asyncio
import struct
from collections.abc import AsyncIterator
from typing import Any

import pytest
import pytest_asyncio
from asyncua import Client, ua
from pymodbus.client import AsyncModbusTcpClient

from motion_server import config
from motion_server.runtime import Runtime
from tests.opcua_support import USERS, running, secure_client, user_hashes

pytestmark = pytest.mark.asyncio(loop_scope="module")

SITE = """
[site]
name = "cam_test"
namespace_uri = "urn:motion-server:cam-test"

[controller]
clock = "manual"
status_log_interval = 0.0

[modbus]
port = 0

# the test steps the clock over plain Modbus: a map with users makes plain clients
# operators unless the map grants more
[modbus.access]
role = "admin"

[opcua]
port = 0
data_dir = "{data_dir}"
{users}

[[groups]]
name = "Group1"
axes = ["Axis1"]

[[axes]]
name = "Axis1"
type = "virtual"

[[cams]]
name = "Cam1"
capacity = 4
points = [[0, 0, 0], [10, 5, 0]]

[[cams]]
name = "Cam2"
capacity = 8
points = [[0, 0, 1], [90, 45, 1], [180, 180, 1]]
"""

CAM2 = 30100  # Cam2's block (see the module docstring)


def regs(fmt: str, *values: float) -> list[int]:
    """Big-endian registers (the default word order) of REAL ('f') and DINT ('i') values."""
    data = struct.pack(">" + fmt, *values)
    return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    hashes = user_hashes()
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in hashes.items()
    )
    data_dir = tmp_path_factory.mktemp("opcua-data")
    site = config.parse(SITE.format(data_dir=data_dir, users=users), "cam-test.toml")
    async with running(site) as runtime:
        yield runtime


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def modbus(rt: Runtime) -> AsyncIterator[AsyncModbusTcpClient]:
    assert rt.modbus is not None
    client = AsyncModbusTcpClient("127.0.0.1", port=rt.modbus.port, timeout=5)
    assert await client.connect()
    yield client
    client.close()


async def step(rt: Runtime, client: AsyncModbusTcpClient, cycles: int) -> None:
    """Run cycles through the Clock tags (answered once they ran)."""
    count, bit = rt.tagmap.tag("Clock.StepCycles"), rt.tagmap.tag("Clock.Step")
    assert not (await client.write_registers(count.address, regs("I", cycles))).isError()
    for value in (0, 1):
        mask = await client.mask_write_register(
            address=bit.address, and_mask=~(1 << (bit.bit or 0)) & 0xFFFF, or_mask=value
        )
        assert not mask.isError()


async def test_the_layout_is_at_the_documented_registers(rt: Runtime) -> None:
    tm = rt.tagmap
    assert tm.tag("Cam1.ProfileStatus").address == 30000
    assert tm.tag("Cam2.Length").address == CAM2 + 6
    assert tm.tag("Cam2.Master[5]").address == CAM2 + 8 + 30
    assert tm.tag("Cam2.SegmentType[7]").address == CAM2 + 12 + 42


async def test_fc16_writes_points_into_the_kernel_table(
    rt: Runtime, modbus: AsyncModbusTcpClient
) -> None:
    table = rt.ctl.cams.tables[2]
    # element 3 and 4 of Cam2 and Length in one FC16 each: (270, 315, cubic), (360, 360, cubic)
    points = regs("ffiffi", 270.0, 315.0, 1, 360.0, 360.0, 1)
    assert not (await modbus.write_registers(CAM2 + 8 + 18, points)).isError()
    assert not (await modbus.write_registers(CAM2 + 6, regs("i", 5))).isError()
    await step(rt, modbus, 1)
    assert table.master[:5] == [0.0, 90.0, 180.0, 270.0, 360.0]
    assert table.slave[:5] == [0.0, 45.0, 180.0, 315.0, 360.0]
    assert table.segment[:5] == [1, 1, 1, 1, 1]
    assert table.length == 5
    rr = await modbus.read_holding_registers(CAM2 + 8 + 18, count=12)
    assert rr.registers == points


async def test_the_header_is_read_only(rt: Runtime, modbus: AsyncModbusTcpClient) -> None:
    for address in (30000, 30002, 30004):  # ProfileStatus, Capacity, Number of Cam1
        rr = await modbus.write_registers(address, [0, 9])
        assert rr.isError() and rr.exception_code == 2
    rr = await modbus.read_holding_registers(30000, count=8)
    # ProfileStatus 0, Capacity 4, Number 1, Length 2 (the initial points)
    assert rr.registers == regs("iiii", 0, 4, 1, 2)


async def test_profile_status_counts_the_cams_that_use_the_profile(
    rt: Runtime, modbus: AsyncModbusTcpClient
) -> None:
    status = 30000  # Cam1.ProfileStatus
    await step(rt, modbus, 1)
    assert (await modbus.read_holding_registers(status, count=2)).registers == regs("i", 0)
    # no cam instruction is needed to compute a profile: the kernel's MCCP entry point
    profile = rt.ctl.cams.calculate(1, 0, 2, 0.0, 0.0, 1)
    await step(rt, modbus, 1)
    assert (await modbus.read_holding_registers(status, count=2)).registers == regs("i", 2)

    class Cam:  # what a running cam shows its profile slot (cam_tables.ProfileUser)
        def __init__(self) -> None:
            self.profile = profile
            self.active = True

    users = [Cam(), Cam()]
    for user in users:
        rt.ctl.cams.register(1, user)
    await step(rt, modbus, 1)
    assert (await modbus.read_holding_registers(status, count=2)).registers == regs("i", 4)
    users[0].active = False
    await step(rt, modbus, 1)
    assert (await modbus.read_holding_registers(status, count=2)).registers == regs("i", 3)
    users[1].active = False


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def operator(rt: Runtime, tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Client]:
    client = await secure_client(rt, tmp_path_factory.mktemp("c1"), "operator", "run-the-line")
    async with client:
        yield client


def write_value(rt: Runtime, client: Client, node: str, value: Any, vt: Any, rng: str = "") -> Any:
    assert rt.opcua is not None
    ns = rt.opcua.namespace_index
    wv = ua.WriteValue(
        NodeId=ua.NodeId(node, ns),
        AttributeId=ua.AttributeIds.Value,
        IndexRange=rng or None,
        Value=ua.DataValue(ua.Variant(value, vt)),
    )
    return client.uaclient.write(ua.WriteParameters(NodesToWrite=[wv]))


async def test_the_array_views_write_the_kernel_table(rt: Runtime, operator: Client) -> None:
    assert rt.opcua is not None
    ns = rt.opcua.namespace_index
    f, i = ua.VariantType.Float, ua.VariantType.Int32
    masters = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0]
    [code] = await write_value(rt, operator, "Cams.Cam2.MasterValues", masters, f)
    assert code.is_good(), code
    [code] = await write_value(rt, operator, "Cams.Cam2.SegmentTypes", [0, 0], i, "2:3")
    assert code.is_good(), code
    [code] = await write_value(rt, operator, "Cams.Cam2.SlaveValues", [2.5], f, "6")
    assert code.is_good(), code
    table = rt.ctl.cams.tables[2]
    # the manual clock answers a write once the scan applied it
    assert table.master == masters
    assert table.segment[1:5] == [1, 0, 0, 1]
    assert table.slave[6] == 2.5
    node = operator.get_node(ua.NodeId("Cams.Cam2.MasterValues", ns))
    assert await node.read_value() == masters
    element = operator.get_node(ua.NodeId("Cams.Cam2.Master[3]", ns))
    assert await element.read_value() == 30.0
    [dv] = await operator.uaclient.read(
        ua.ReadParameters(
            NodesToRead=[
                ua.ReadValueId(
                    NodeId=ua.NodeId("Cams.Cam2.SegmentTypes", ns),
                    AttributeId=ua.AttributeIds.Value,
                    IndexRange="1:4",
                )
            ]
        )
    )
    assert dv.Value.Value == [1, 0, 0, 1]


@pytest.mark.parametrize(
    ("node", "value", "vt", "rng", "code"),
    [
        ("Cams.Cam2.MasterValues", [1.0] * 7, "Float", "", "BadTypeMismatch"),
        ("Cams.Cam2.MasterValues", [1.0] * 8, "Double", "", "BadTypeMismatch"),
        ("Cams.Cam2.MasterValues", 1.0, "Float", "", "BadTypeMismatch"),
        ("Cams.Cam2.SegmentTypes", [1.0] * 8, "Float", "", "BadTypeMismatch"),
        ("Cams.Cam2.MasterValues", [1.0, 2.0], "Float", "7:8", "BadIndexRangeDataMismatch"),
        ("Cams.Cam2.MasterValues", [1.0], "Float", "8", "BadIndexRangeNoData"),
        ("Cams.Cam2.MasterValues", [1.0], "Float", "3:1", "BadIndexRangeInvalid"),
        ("Cams.Cam2.MasterValues", [1.0, float("nan")], "Float", "0:1", "BadOutOfRange"),
    ],
)
async def test_a_bad_array_write_answers_its_status_and_changes_nothing(
    rt: Runtime, operator: Client, node: str, value: Any, vt: str, rng: str, code: str
) -> None:
    table = rt.ctl.cams.tables[2]
    before = (list(table.master), list(table.slave), list(table.segment))
    [got] = await write_value(rt, operator, node, value, getattr(ua.VariantType, vt), rng)
    assert got.name == code
    await asyncio.sleep(0)
    assert (table.master, table.slave, table.segment) == before


async def test_a_viewer_may_not_write_a_table(
    rt: Runtime, tmp_path_factory: pytest.TempPathFactory
) -> None:
    table = rt.ctl.cams.tables[1]
    before = list(table.master)
    client = await secure_client(rt, tmp_path_factory.mktemp("c2"), "viewer", "look-only")
    async with client:
        f = ua.VariantType.Float
        [code] = await write_value(rt, client, "Cams.Cam1.MasterValues", [9.0] * 4, f)
        assert code.name == "BadUserAccessDenied"
        [code] = await write_value(rt, client, "Cams.Cam1.Master[0]", 9.0, f)
        assert code.name == "BadUserAccessDenied"
    assert table.master == before


async def test_a_subscriber_of_an_array_view_sees_an_element_write(
    rt: Runtime, operator: Client, modbus: AsyncModbusTcpClient
) -> None:
    assert rt.opcua is not None
    ns = rt.opcua.namespace_index
    seen: asyncio.Queue[list[float]] = asyncio.Queue()

    class Handler:
        def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
            seen.put_nowait(val)

    sub = await operator.create_subscription(50, Handler())
    await sub.subscribe_data_change(operator.get_node(ua.NodeId("Cams.Cam1.SlaveValues", ns)))
    first = await asyncio.wait_for(seen.get(), 5.0)  # the initial value
    assert first == list(rt.ctl.cams.tables[1].slave)
    # Cam1.Slave[3] (B+10+6·3 = 30028) over Modbus: the view follows
    assert not (await modbus.write_registers(30028, regs("f", 7.5))).isError()
    await step(rt, modbus, 1)
    while True:
        value = await asyncio.wait_for(seen.get(), 5.0)
        if value[3] == 7.5:
            break
    assert value == [*first[:3], 7.5]
    await sub.delete()
