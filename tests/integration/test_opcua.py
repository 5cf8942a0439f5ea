"""OPC UA over a real socket (127.0.0.1, ephemeral port, manual clock), asyncua client on
the Basic256Sha256 SignAndEncrypt endpoint with user names.

Numbers from first principles: MAG at ratio 0.5 on a master jogging at 10 mm/s gives the
slave 5 mm/s (clutch disabled: locked at once). MGS programmed stop from 10 mm/s at the
axes' 5000 mm/s² deceleration takes 10/5000 = 2 ms = one cycle, so after a few cycles all
axes are at rest and PC is set.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio
from asyncua import Client, Node, ua

from motion_server.runtime import Runtime
from tests.opcua_support import opcua_site, running, secure_client, user_hashes

pytestmark = pytest.mark.asyncio(loop_scope="module")
NS_URI = "urn:motion-server:opcua-test"


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    site = opcua_site(tmp_path_factory.mktemp("opcua-data"), user_hashes(), lockout=0.0)
    async with running(site) as runtime:
        yield runtime


@pytest.fixture(scope="module")
def client_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("opcua-client")


class Tags:
    """Tag-name access over an asyncua client."""

    def __init__(self, client: Client, ns: int) -> None:
        self.client = client
        self.ns = ns

    def node(self, node_id: str) -> Node:
        return self.client.get_node(ua.NodeId(node_id, self.ns))

    async def read(self, node_id: str) -> Any:
        return await self.node(node_id).read_value()

    async def write(self, node_id: str, value: Any, vt: ua.VariantType) -> None:
        await self.node(node_id).write_value(ua.DataValue(ua.Variant(value, vt)))

    async def step(self, cycles: int) -> None:
        await self.write("Clock.StepCycles", cycles, ua.VariantType.UInt32)
        await self.write("Clock.Step", False, ua.VariantType.Boolean)
        await self.write("Clock.Step", True, ua.VariantType.Boolean)

    async def jog(self, axis: int, speed: float, rate: float) -> None:
        """MAJ_1 forward on ``axis`` at ``speed`` (units/s), accelerating and decelerating
        at ``rate`` (units/s^2)."""
        await self.trigger(
            "MAJ_1",
            Axis=(axis, I32),
            Direction=(0, I32),
            SpeedUnits=(0, I32),
            Speed=(speed, F),
            AccelRate=(rate, F),
            DecelRate=(rate, F),
        )

    async def trigger(self, inst: str, **operands: tuple[Any, ua.VariantType]) -> None:
        for name, (value, vt) in operands.items():
            await self.write(f"Instructions.{inst}.{name}", value, vt)
        await self.write(f"Instructions.{inst}.Execute", False, ua.VariantType.Boolean)
        await self.step(1)  # one scan with the rung false, so that the next write is an edge
        await self.write(f"Instructions.{inst}.Execute", True, ua.VariantType.Boolean)


async def connect(rt: Runtime, client_dir: Path, user: str | None, **kw: Any) -> Client:
    client = await secure_client(rt, client_dir, user, **kw)
    await client.connect()
    return client


B, I32, F = ua.VariantType.Boolean, ua.VariantType.Int32, ua.VariantType.Float


async def test_browse_tree_types_and_access(rt: Runtime, client_dir: Path) -> None:
    client = await connect(rt, client_dir, "viewer")
    try:
        ns = await client.get_namespace_index(NS_URI)
        assert rt.opcua is not None and ns == rt.opcua.namespace_index
        names = {
            (await n.read_browse_name()).Name for n in await client.nodes.objects.get_children()
        }
        assert {"Axes", "Groups", "Instructions", "Diagnostics", "Clock"} <= names
        mag = await client.nodes.objects.get_child([f"{ns}:Instructions", f"{ns}:MAG_1"])
        assert mag.nodeid == ua.NodeId("Instructions.MAG_1", ns)
        kids = {(await n.read_browse_name()).Name for n in await mag.get_children()}
        assert {"Execute", "Ratio", "Clutch", "DN", "IP", "ER", "ERR", "EXERR"} <= kids
        inputs = await mag.get_child(f"{ns}:InputVariables")
        organized = {n.nodeid.Identifier for n in await inputs.get_children(refs=35)}
        assert "Instructions.MAG_1.Execute" in organized
        assert "Instructions.MAG_1.DN" not in organized
        expect = {
            "Instructions.MAG_1.Ratio": (ua.ObjectIds.Float, 3),
            "Instructions.MAG_1.Execute": (ua.ObjectIds.Boolean, 3),
            "Instructions.MAG_1.SlaveCounts": (ua.ObjectIds.UInt32, 3),
            "Instructions.MAG_1.DN": (ua.ObjectIds.Boolean, 1),
            "Instructions.MAG_1.ERR": (ua.ObjectIds.Int16, 1),
            "Instructions.MAG_1.EXERR": (ua.ObjectIds.SByte, 1),
            "Instructions.MAG_1.Direction": (ua.ObjectIds.Int32, 3),
            "Instructions.MC_MoveAbsolute_1.Position": (ua.ObjectIds.Double, 3),
            "Axes.Axis2.ActualPosition": (ua.ObjectIds.Double, 1),
            "Clock.Cycle": (ua.ObjectIds.UInt32, 1),
            "Clock.Mode": (ua.ObjectIds.Int16, 3),
        }
        for node_id, (dtype, level) in expect.items():
            node = client.get_node(ua.NodeId(node_id, ns))
            assert (await node.read_data_type()).Identifier == dtype, node_id
            assert await node.read_attribute(ua.AttributeIds.AccessLevel) is not None
            access = (await node.read_attribute(ua.AttributeIds.AccessLevel)).Value.Value
            assert access == level, node_id
        pos = client.get_node(ua.NodeId("Axes.Axis2.ActualPosition", ns))
        eu = await (await pos.get_child("0:EngineeringUnits")).read_value()
        assert eu.DisplayName.Text == "mm"
        assert eu.UnitId == (ord("M") << 16) | (ord("M") << 8) | ord("T")  # UNECE MMT
        rng = await (await pos.get_child("0:EURange")).read_value()
        assert rng.Low < 0 < rng.High
        direction = client.get_node(ua.NodeId("Instructions.MAG_1.Direction", ns))
        values = await (await direction.get_child("0:EnumValues")).read_value()
        # the seed's MAG Direction: same 0, opposite 1, reverse 2, unchanged 3
        assert [(v.Value, v.DisplayName.Text.lower()) for v in values] == [
            (0, "same"),
            (1, "opposite"),
            (2, "reverse"),
            (3, "unchanged"),
        ]
    finally:
        await client.disconnect()


class Changes:
    def __init__(self) -> None:
        self.seen: dict[str, list[Any]] = {}
        self.event = asyncio.Event()

    def datachange_notification(self, node: Node, val: Any, data: Any) -> None:
        self.seen.setdefault(node.nodeid.Identifier, []).append(val)
        self.event.set()

    async def wait_for(self, node_id: str, value: Any, timeout: float = 5.0) -> None:
        async def until() -> None:
            while value not in self.seen.get(node_id, []):
                self.event.clear()
                await self.event.wait()

        await asyncio.wait_for(until(), timeout)


async def test_mag_and_mgs_triggered_by_writes_seen_by_read_and_subscription(
    rt: Runtime, client_dir: Path
) -> None:
    client = await connect(rt, client_dir, "admin")
    try:
        tags = Tags(client, await client.get_namespace_index(NS_URI))
        changes = Changes()
        sub = await client.create_subscription(20, changes)
        watched = [
            "Instructions.MAG_1.DN",
            "Instructions.MAG_1.IP",
            "Instructions.MGS_1.DN",
            "Instructions.MGS_1.PC",
        ]
        await sub.subscribe_data_change([tags.node(n) for n in watched])
        for axis in (1, 2):
            await tags.trigger("MSO_1", Axis=(axis, I32))
            await tags.step(1)
            assert await tags.read("Instructions.MSO_1.DN") is True
        await tags.jog(1, 10.0, 100.0)
        await tags.step(60)  # 0.1 s to reach 10 mm/s
        err = await tags.read("Instructions.MAJ_1.ERR")
        assert await tags.read("Instructions.MAJ_1.IP") is True, f"MAJ ERR {err}"
        assert await tags.read("Axes.Axis1.CommandVelocity") == pytest.approx(10.0, abs=1e-9)
        await tags.trigger(
            "MAG_1", SlaveAxis=(2, I32), MasterAxis=(1, I32), Ratio=(0.5, F), Clutch=(1, I32)
        )
        assert await tags.read("Instructions.MAG_1.DN") is False  # not scanned yet
        await tags.step(1)
        # MAG sets DN and IP in the same scan
        err = (
            await tags.read("Instructions.MAG_1.ERR"),
            await tags.read("Instructions.MAG_1.EXERR"),
        )
        assert await tags.read("Instructions.MAG_1.DN") is True, f"MAG ERR, EXERR {err}"
        assert await tags.read("Instructions.MAG_1.IP") is True
        await changes.wait_for("Instructions.MAG_1.DN", True)
        await changes.wait_for("Instructions.MAG_1.IP", True)
        await tags.step(5)
        assert await tags.read("Axes.Axis2.CommandVelocity") == pytest.approx(5.0, abs=1e-9)

        await tags.trigger("MGS_1", Group=(1, I32), StopMode=(0, ua.VariantType.UInt32))
        await tags.step(1)
        assert await tags.read("Instructions.MGS_1.DN") is True
        await tags.step(20)
        assert await tags.read("Instructions.MGS_1.PC") is True
        assert await tags.read("Instructions.MGS_1.IP") is False
        assert await tags.read("Instructions.MAG_1.IP") is False  # the stop ended the gearing
        assert await tags.read("Axes.Axis1.CommandVelocity") == 0.0
        assert await tags.read("Axes.Axis2.CommandVelocity") == 0.0
        await changes.wait_for("Instructions.MGS_1.DN", True)
        await changes.wait_for("Instructions.MGS_1.PC", True)
        await changes.wait_for("Instructions.MAG_1.IP", False)
        await sub.delete()
    finally:
        await client.disconnect()


async def test_multi_item_write_gets_a_status_per_item(rt: Runtime, client_dir: Path) -> None:
    client = await connect(rt, client_dir, "operator")
    try:
        ns = await client.get_namespace_index(NS_URI)
        before = rt.system["MAM_1"].inputs["Speed"]
        cycle = rt.ctl.tick

        def item(node_id: str, value: Any, vt: ua.VariantType) -> ua.WriteValue:
            return ua.WriteValue(
                NodeId=ua.NodeId(node_id, ns),
                AttributeId=ua.AttributeIds.Value,
                Value=ua.DataValue(ua.Variant(value, vt)),
            )

        params = ua.WriteParameters(
            NodesToWrite=[
                item("Instructions.MAJ_1.Speed", 42.5, F),  # good
                item("Instructions.MAJ_1.DN", True, B),  # an output
                item("Instructions.MAM_1.Speed", 7.0, ua.VariantType.Double),  # REAL wants Float
                item("Clock.Step", True, B),  # operators do not drive the clock
                item("Instructions.MAJ_1.Direction", 1, I32),  # good
            ]
        )
        codes = [c.value for c in await client.uaclient.write(params)]
        assert codes == [
            ua.StatusCodes.Good,
            ua.StatusCodes.BadNotWritable,
            ua.StatusCodes.BadTypeMismatch,
            ua.StatusCodes.BadUserAccessDenied,
            ua.StatusCodes.Good,
        ]
        assert rt.system["MAJ_1"].inputs["Speed"] == 42.5
        assert rt.system["MAJ_1"].inputs["Direction"] == 1
        assert rt.system["MAM_1"].inputs["Speed"] == before
        assert rt.ctl.tick == cycle  # the refused Clock.Step ran no cycle
    finally:
        await client.disconnect()


async def test_viewer_reads_but_cannot_write(rt: Runtime, client_dir: Path) -> None:
    client = await connect(rt, client_dir, "viewer")
    try:
        tags = Tags(client, await client.get_namespace_index(NS_URI))
        assert await tags.read("Clock.Cycle") == rt.ctl.tick
        maj = rt.system["MAJ_1"]
        speed, execute = maj.inputs["Speed"], maj.inputs["Execute"]
        assert await tags.read("Instructions.MAJ_1.Speed") == speed
        with pytest.raises(ua.uaerrors.BadUserAccessDenied):
            await tags.write("Instructions.MAJ_1.Execute", not execute, B)
        with pytest.raises(ua.uaerrors.BadUserAccessDenied):
            await tags.write("Instructions.MAJ_1.Speed", speed + 1.0, F)
        assert (maj.inputs["Speed"], maj.inputs["Execute"]) == (speed, execute)
        assert await tags.read("Instructions.MAJ_1.Speed") == speed
    finally:
        await client.disconnect()


async def test_wrong_password_is_refused(rt: Runtime, client_dir: Path) -> None:
    client = await secure_client(rt, client_dir, "operator", password="not-the-password")
    with pytest.raises(ua.UaError):
        await client.connect()
    unknown = await secure_client(rt, client_dir, "nobody", password="x")
    with pytest.raises(ua.UaError):
        await unknown.connect()


async def test_anonymous_is_refused_when_not_enabled(rt: Runtime, client_dir: Path) -> None:
    client = await secure_client(rt, client_dir, None)
    with pytest.raises(ua.UaError):
        await client.connect()


async def test_queue_size_zero_delivers_the_latest_value(rt: Runtime, client_dir: Path) -> None:
    client = await connect(rt, client_dir, "admin")
    try:
        tags = Tags(client, await client.get_namespace_index(NS_URI))
        changes = Changes()
        sub = await client.create_subscription(1000, changes)
        await sub.subscribe_data_change(tags.node("Clock.Cycle"), queuesize=0)
        start = await tags.read("Clock.Cycle")
        await changes.wait_for("Clock.Cycle", start)  # the initial value
        for _ in range(5):
            await tags.step(1)  # five changes well within one publishing interval
        await changes.wait_for("Clock.Cycle", start + 5)
        burst = [v for v in changes.seen["Clock.Cycle"] if v != start]
        assert burst[-1] == start + 5
        assert len(burst) < 5  # latest value, not a queue of every change
        await sub.delete()
    finally:
        await client.disconnect()


async def test_many_monitored_items_in_one_request_and_axis_values_by_subscription(
    rt: Runtime, client_dir: Path
) -> None:
    """One CreateMonitoredItems of more items than the server creates between two yields:
    every item gets its own result in request order (an unknown node its own Bad code),
    and the positions of a jogging axis arrive as the values a Read returns."""
    client = await connect(rt, client_dir, "admin")
    try:
        tags = Tags(client, await client.get_namespace_index(NS_URI))
        fields = ("ActualPosition", "CommandPosition", "CommandVelocity", "PositionError")
        names = [f"Axes.Axis{a}.{f}" for a in (1, 2, 3) for f in fields]
        names += [f"Instructions.MAJ_1.{f}" for f in ("DN", "IP", "ER", "ERR")]
        names += [f"Instructions.MSO_1.{f}" for f in ("DN", "ER", "ERR")]
        names.insert(9, "Axes.NoSuchAxis.ActualPosition")
        assert len(names) > 16  # more than one batch (CREATE_BATCH)
        changes = Changes()
        sub = await client.create_subscription(20, changes)
        results = await sub.subscribe_data_change([tags.node(n) for n in names])
        assert len(results) == len(names)
        for name, result in zip(names, results, strict=True):
            if name.startswith("Axes.NoSuchAxis"):
                assert isinstance(result, ua.StatusCode)
                assert result.value == ua.StatusCodes.BadNodeIdUnknown
            else:
                assert isinstance(result, int), (name, result)
        await tags.trigger("MSO_1", Axis=(1, I32))
        await tags.step(1)
        assert await tags.read("Axes.Axis1.CommandVelocity") == 0.0  # at rest: from here
        start = await tags.read("Axes.Axis1.CommandPosition")
        await tags.jog(1, 10.0, 1000.0)
        await tags.step(51)  # at speed after 10 ms; 100 ms at 10 mm/s from then on
        position = await tags.read("Axes.Axis1.CommandPosition")
        # from rest: 10 mm/s at 1000 mm/s^2 is reached in 10 ms (5 cycles) over 0.05 mm,
        # then 46 cycles (92 ms) at speed
        assert position - start == pytest.approx(0.05 + 10.0 * 0.092, abs=1e-9)
        await changes.wait_for("Axes.Axis1.CommandPosition", position)
        await changes.wait_for("Axes.Axis1.ActualPosition", position)  # virtual: actual = command
        await changes.wait_for("Axes.Axis1.CommandVelocity", 10.0)
        await sub.delete()
    finally:
        await client.disconnect()
