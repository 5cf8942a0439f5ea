"""A SCADA over OPC UA: the same client calls, plus a subscription to changing values.

Connects to the secure endpoint (Basic256Sha256, SignAndEncrypt, the bench user) and
drives the same instructions as the Modbus examples: MSO, a master jog at 100 mm/s, MAG
at ratio 0.5 without clutch. A subscription (publishing interval 50 ms) on the master
and slave velocities and MAG_1.IP receives their changes as the server publishes them:
the last notified slave velocity is 0.5 · 100 = 50 mm/s and MAG_1.IP rose to true.
"""

from __future__ import annotations

import asyncio
import sys
from typing import Any

from motion_clients.scenario import Scenario, run_example

TAGS = ["Master.CommandVelocity", "Slave.CommandVelocity", "Slave.CommandPosition", "MAG_1.IP"]
WATCHED = ["Master.CommandVelocity", "Slave.CommandVelocity", "MAG_1.IP"]
TIME_UNITS = dict(SpeedUnits=0, AccelUnits=0, DecelUnits=0)


class Changes:
    """asyncua data-change handler: every notified value, by tag name."""

    def __init__(self, names: dict[str, str]) -> None:
        self.names = names  # node id string -> tag name
        self.seen: dict[str, list[Any]] = {n: [] for n in names.values()}

    def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
        self.seen[self.names[node.nodeid.Identifier]].append(val)


async def until(predicate: Any, seconds: float = 5.0) -> bool:
    """Wait (real time: notifications are pushed at the publishing rate) for predicate()."""
    loop = asyncio.get_running_loop()
    end = loop.time() + seconds
    while not predicate():
        if loop.time() > end:
            return False
        await asyncio.sleep(0.02)
    return True


async def body(sc: Scenario) -> None:
    backend: Any = sc.mc.backend
    if backend.protocol != "opcua":
        raise SystemExit("this example speaks OPC UA: --protocol opcua")
    await sc.clean_start()
    changes = Changes({sc.mc.map.tag(t).node_id: t for t in WATCHED})
    sub = await backend.client.create_subscription(50, changes)
    await sub.subscribe_data_change([backend._node(sc.mc.map.tag(t)) for t in WATCHED])
    for n in (1, 2):
        await sc.trigger("MSO_1", Axis=n)
    await sc.trigger("Jog_Master", Speed=100.0, AccelRate=10000.0, DecelRate=10000.0, **TIME_UNITS)
    await sc.trigger(
        "MAG_1",
        SlaveAxis=2,
        MasterAxis=1,
        Direction="SAME",
        Ratio=0.5,
        RatioFormat="REAL",
        MasterReference="COMMAND",
        Clutch="DISABLED",
    )
    await sc.run(0.2)
    got = await until(lambda: changes.seen["Slave.CommandVelocity"][-1:] == [50.0])
    sc.say(f"  notifications: { {k: len(v) for k, v in changes.seen.items()} }")
    sc.check("subscription delivered the slave at 50 mm/s", float(got), 1.0, 0)
    sc.check("last notified slave velocity [mm/s]", changes.seen["Slave.CommandVelocity"][-1], 50.0)
    sc.check("MAG_1.IP notified true", float(True in changes.seen["MAG_1.IP"]), 1.0, 0)
    sc.check("read agrees [mm/s]", float(await sc.read("Slave.CommandVelocity")), 50.0)
    await sub.delete()


def main(argv: list[str] | None = None) -> int:
    defaults = {"protocol": "opcua", "user": "bench", "password": "bench-only"}
    return run_example(__file__, __doc__ or "", TAGS, body, argv, defaults=defaults)


if __name__ == "__main__":
    sys.exit(main())
