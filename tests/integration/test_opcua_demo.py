"""The demo site map over OPC UA: its anonymous sessions on the None endpoint (loopback),
and the absolute deadband of analog values.

The demo map as shipped, with three changes for a test: an ephemeral port, a data
directory of the test's own, the manual clock (cycles run only when the test asks), no
Modbus, and a deadband of 0.5 mm. Its Axis4 is a hand wheel (feedback only, input
signal): its ActualPosition is the FeedbackInput written before the cycle, quantised to
its 100 counts/mm, so 0.3 and 0.6 are exact positions.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from typing import Any

import pytest
import pytest_asyncio
from asyncua import Client, Node, ua

from motion_server import config
from motion_server.runtime import Runtime
from tests.opcua_support import running

pytestmark = pytest.mark.asyncio(loop_scope="module")
DEADBAND = 0.5


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    demo = config.load()
    site = demo.model_copy(
        update={
            "controller": demo.controller.model_copy(update={"clock": "manual"}),
            "modbus": demo.modbus.model_copy(update={"enabled": False}),
            "opcua": demo.opcua.model_copy(
                update={
                    "port": 0,
                    "data_dir": str(tmp_path_factory.mktemp("opcua-demo")),
                    "deadband": DEADBAND,
                }
            ),
        }
    )
    async with running(site) as runtime:
        yield runtime


async def anonymous(rt: Runtime) -> Client:
    """An anonymous client on the None endpoint (asyncua's default without security)."""
    assert rt.opcua is not None
    client = Client(rt.opcua.endpoint, timeout=10)
    await client.connect()
    assert client.security_policy.Mode == ua.MessageSecurityMode.None_
    return client


def node(client: Client, rt: Runtime, node_id: str) -> Node:
    assert rt.opcua is not None
    return client.get_node(ua.NodeId(node_id, rt.opcua.namespace_index))


async def write(client: Client, rt: Runtime, node_id: str, value: Any, vt: ua.VariantType) -> None:
    await node(client, rt, node_id).write_value(ua.DataValue(ua.Variant(value, vt)))


async def test_the_demo_offers_anonymous_and_none_on_loopback(rt: Runtime) -> None:
    assert rt.opcua is not None
    assert rt.opcua.config.host == "127.0.0.1"
    probe = Client(rt.opcua.endpoint, timeout=10)
    endpoints = await probe.connect_and_get_server_endpoints()
    none = [e for e in endpoints if e.SecurityMode == ua.MessageSecurityMode.None_]
    assert none and none[0].SecurityPolicyUri.endswith("#None")
    tokens = {t.TokenType for t in none[0].UserIdentityTokens}
    assert ua.UserTokenType.Anonymous in tokens


async def test_anonymous_operator_writes_operands_but_not_the_clock(rt: Runtime) -> None:
    client = await anonymous(rt)
    try:
        cycle = await node(client, rt, "Clock.Cycle").read_value()
        assert cycle == rt.ctl.tick
        speed = rt.system["MAJ_1"].inputs["Speed"] + 12.5
        await write(client, rt, "Instructions.MAJ_1.Speed", speed, ua.VariantType.Float)
        assert rt.system["MAJ_1"].inputs["Speed"] == speed
        assert await node(client, rt, "Instructions.MAJ_1.Speed").read_value() == speed
        # the demo's anonymous role is operator: Execute too
        execute = rt.system["MAJ_1"].inputs["Execute"]
        await write(client, rt, "Instructions.MAJ_1.Execute", not execute, ua.VariantType.Boolean)
        assert rt.system["MAJ_1"].inputs["Execute"] == (not execute)
        await write(client, rt, "Instructions.MAJ_1.Execute", execute, ua.VariantType.Boolean)
        # the clock needs the admin role
        mode = await node(client, rt, "Clock.Mode").read_value()
        for node_id, value, vt in [
            ("Clock.StepCycles", 7, ua.VariantType.UInt32),
            ("Clock.Step", True, ua.VariantType.Boolean),
            ("Clock.Mode", 0, ua.VariantType.Int16),
        ]:
            with pytest.raises(ua.uaerrors.BadUserAccessDenied):
                await write(client, rt, node_id, value, vt)
        assert rt.ctl.tick == cycle  # no cycle ran
        assert await node(client, rt, "Clock.Mode").read_value() == mode
        with pytest.raises(ua.uaerrors.BadNotWritable):
            await write(client, rt, "Instructions.MAJ_1.DN", True, ua.VariantType.Boolean)
    finally:
        await client.disconnect()


class Seen:
    def __init__(self) -> None:
        self.values: list[float] = []
        self.event = asyncio.Event()

    def datachange_notification(self, node: Node, val: Any, data: Any) -> None:
        self.values.append(val)
        self.event.set()

    async def wait_for(self, count: int, timeout: float = 5.0) -> None:
        async def until() -> None:
            while len(self.values) < count:
                self.event.clear()
                await self.event.wait()

        await asyncio.wait_for(until(), timeout)


async def test_a_change_below_the_deadband_is_not_published(rt: Runtime) -> None:
    assert rt.opcua is not None
    fe = rt.opcua
    client = await anonymous(rt)
    try:
        actual = node(client, rt, "Axes.Axis4.ActualPosition")

        async def hand_wheel(position: float) -> None:
            await write(client, rt, "Axes.Axis4.FeedbackInput", position, ua.VariantType.Double)
            rt.request_cycles(1)
            await rt.settle()
            await fe.publish()
            assert rt.ctl.axes[3].actual_position == pytest.approx(position, abs=1e-12)

        await hand_wheel(0.0)
        seen = Seen()
        sub = await client.create_subscription(10, seen)
        await sub.subscribe_data_change(actual, queuesize=10)
        await hand_wheel(0.3)  # 0.3 from the published 0.0: below 0.5
        assert await actual.read_value() == 0.0
        await hand_wheel(0.6)  # 0.6 from the published 0.0: above
        assert await actual.read_value() == pytest.approx(0.6, abs=1e-12)
        await hand_wheel(0.9)  # 0.3 from the published 0.6: below again
        assert await actual.read_value() == pytest.approx(0.6, abs=1e-12)
        await hand_wheel(0.0)  # 0.6 back: above
        assert await actual.read_value() == 0.0
        # the subscriber saw the published values only (the initial one first)
        await seen.wait_for(3)
        assert seen.values == [0.0, pytest.approx(0.6, abs=1e-12), 0.0]
        await sub.delete()
        # non-analog values ignore the deadband: the cycle count moves by 1
        before = await node(client, rt, "Clock.Cycle").read_value()
        rt.request_cycles(1)
        await rt.settle()
        await fe.publish()
        assert await node(client, rt, "Clock.Cycle").read_value() == before + 1
    finally:
        await client.disconnect()
