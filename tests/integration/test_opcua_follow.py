"""A client's trigger write is answered within cycles, not publishing passes: with the
clock running, the written instance's status is published right after the next cycle.

The publishing rate is set to 0.1 Hz here, so the periodic pass (one at start, the next
10 s later) cannot be what shows DN: the test waits at most 5 s and checks that no pass
ran meanwhile.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

from asyncua import ua

from motion_server import config
from tests.opcua_support import opcua_site, running, secure_client, user_hashes


def realtime_site(tmp: Path) -> config.SiteMap:
    site = opcua_site(tmp / "data", user_hashes())
    return site.model_copy(
        update={
            "controller": site.controller.model_copy(update={"clock": "realtime"}),
            "opcua": site.opcua.model_copy(update={"publish_rate_hz": 0.1}),
        }
    )


async def test_dn_is_published_after_the_next_cycle(tmp_path: Path) -> None:
    async with running(realtime_site(tmp_path)) as rt:
        fe = rt.opcua
        assert fe is not None
        client = await secure_client(rt, tmp_path, "operator")
        await client.connect()
        try:
            ns = fe.namespace_index

            def node(name: str) -> ua.NodeId:
                return client.get_node(ua.NodeId(f"Instructions.MSO_1.{name}", ns))

            await node("Axis").write_value(ua.DataValue(ua.Variant(2, ua.VariantType.Int32)))
            passes = fe.passes
            assert await node("DN").read_value() is False
            tick = rt.ctl.tick
            await node("Execute").write_value(
                ua.DataValue(ua.Variant(True, ua.VariantType.Boolean))
            )

            async def until_done() -> None:
                while not await node("DN").read_value():
                    await asyncio.sleep(0.001)

            await asyncio.wait_for(until_done(), 5.0)
            assert rt.ctl.tick > tick  # a cycle ran and scanned MSO_1
            assert await node("EN").read_value() is True
            assert fe.passes == passes  # no periodic pass published it
            assert rt.ctl.axes[1].state.name == "SERVO_CONTROL"
        finally:
            await client.disconnect()
