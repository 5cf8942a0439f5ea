"""OPC UA writes go through the safety layer: the audit log names the session's user
(never a password), and per-connection watchdogs supervise OPC UA sessions.

Real sockets, manual clock, Basic256Sha256 SignAndEncrypt with user names. Watchdog
numbers: T = 0.1 s at 2 ms cycles is ceil(0.1 / 0.002) = 50 cycles; the cycle that
starts 50 cycles after the last beat runs a fast stop. The jog: 10 mm/s at 100 mm/s²
reaches speed in 0.1 s = 50 cycles; Axis1's 5000 mm/s² fast stop from 10 mm/s takes
10 / 5000 = 2 ms, one cycle.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua

from motion_server import config
from motion_server.frontends.opcua_space import VARIANT_TYPES
from motion_server.runtime import Runtime
from tests.opcua_support import SITE, USERS, running, secure_client, user_hashes

B, U32, F = ua.VariantType.Boolean, ua.VariantType.UInt32, ua.VariantType.Float
I32 = ua.VariantType.Int32

WATCHDOG = """
[audit]
enabled = true

[[watchdogs]]
name = "HMI1"
timeout = 0.1
group = "Group1"
stop_mode = "fast_stop"
per_connection = true
"""


def safety_site(tmp: Path) -> config.SiteMap:
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in user_hashes().items()
    )
    text = f'data_dir = "{tmp}"\n' + SITE.format(
        data_dir=tmp / "opcua",
        anonymous="false",
        none_endpoint="false",
        lockout=0.0,
        users=users,
    )
    return config.parse(text + WATCHDOG, "opcua-safety.toml")


class Session:
    """Tag-name writes over one client (node ids from the tag map)."""

    def __init__(self, rt: Runtime, client: Client) -> None:
        assert rt.opcua is not None
        self.rt, self.client, self.ns = rt, client, rt.opcua.namespace_index

    def node(self, tag: str) -> Any:
        return self.client.get_node(ua.NodeId(self.rt.tagmap.tag(tag).node_id, self.ns))

    async def write(self, tag: str, value: Any, vt: ua.VariantType | None = None) -> ua.StatusCode:
        """Write ``value`` as the tag's own type unless ``vt`` says otherwise."""
        vt = vt or VARIANT_TYPES[self.rt.tagmap.tag(tag).type]
        dv = ua.DataValue(ua.Variant(value, vt))
        params = ua.WriteParameters()
        params.NodesToWrite = [
            ua.WriteValue(NodeId=self.node(tag).nodeid, AttributeId=ua.AttributeIds.Value, Value=dv)
        ]
        result: list[ua.StatusCode] = await self.client.uaclient.write(params)
        return result[0]

    async def read(self, tag: str) -> Any:
        return await self.node(tag).read_value()

    async def step(self, cycles: int) -> None:
        assert (await self.write("Clock.StepCycles", cycles, U32)).is_good()
        await self.write("Clock.Step", False, B)
        assert (await self.write("Clock.Step", True, B)).is_good()

    async def trigger(self, clock: Session, inst: str, **ops: Any) -> None:
        for name, value in ops.items():
            assert (await self.write(f"{inst}.{name}", value)).is_good()
        await self.write(f"{inst}.Execute", False, B)
        await clock.step(1)
        assert (await self.write(f"{inst}.Execute", True, B)).is_good()


async def login(rt: Runtime, tmp: Path, user: str, password: str | None = None) -> Client:
    client = await secure_client(rt, tmp, user, password)
    await client.connect()
    return client


async def test_opcua_writes_are_audited_with_the_user_and_never_the_password(
    tmp_path: Path,
) -> None:
    async with running(safety_site(tmp_path)) as rt:
        op = await login(rt, tmp_path, "operator")
        viewer = await login(rt, tmp_path, "viewer")
        try:
            s_op, s_view = Session(rt, op), Session(rt, viewer)
            assert (await s_op.write("MAJ_1.Speed", 25.0, F)).is_good()  # 10 -> 25
            code = await s_op.write("Clock.StepCycles", 9, U32)  # admins only
            assert code.value == ua.StatusCodes.BadUserAccessDenied
            code = await s_view.write("MAJ_1.Speed", 30.0, F)  # viewers write nothing
            assert code.value == ua.StatusCodes.BadUserAccessDenied
            code = await s_op.write("MAJ_1.Speed", 1, I32)  # a REAL needs a Float
            assert code.value == ua.StatusCodes.BadTypeMismatch
        finally:
            await op.disconnect()
            await viewer.disconnect()
        with pytest.raises(ua.UaError):  # a failed login: its password must not leak either
            await login(rt, tmp_path, "admin", "not-the-admin-password")
    text = (tmp_path / "audit.jsonl").read_text("utf-8")
    for _, password in USERS.values():
        assert password not in text
    assert "not-the-admin-password" not in text
    records = [json.loads(line) for line in text.splitlines()]
    writes = [r for r in records if r["event"] == "write" and r["protocol"] == "opcua"]
    seen = [(r["user"], r["role"], r["result"], r["tag"], r.get("reason", "")) for r in writes]
    assert seen == [
        ("operator", "operator", "accepted", "MAJ_1.Speed", ""),
        ("operator", "operator", "refused", "Clock.StepCycles", "BadUserAccessDenied"),
        ("viewer", "viewer", "refused", "MAJ_1.Speed", "BadUserAccessDenied"),
        ("operator", "operator", "refused", "MAJ_1.Speed", "BadTypeMismatch"),
    ]
    first = writes[0]
    assert (first["old"], first["new"]) == (10.0, 25.0)
    assert first["address"] == "127.0.0.1" and first["port"] > 0
    # one connection number per session: the operator's lines share theirs, not the viewer's
    assert writes[1]["connection"] == first["connection"] != writes[2]["connection"]


async def test_writes_refused_outside_the_tag_map_are_audited_too(tmp_path: Path) -> None:
    """A write to a namespace-0 node (the server's own) or to a property of ours is
    refused by asyncua's rules, and audited like a refused tag write, naming the node."""
    async with running(safety_site(tmp_path)) as rt:
        op = await login(rt, tmp_path, "operator")
        try:
            assert rt.opcua is not None
            ns = rt.opcua.namespace_index
            product = ua.NodeId(ua.ObjectIds.Server_ServerStatus_BuildInfo_ProductName)
            eu_range = ua.NodeId("Axes.Axis1.ActualPosition.EURange", ns)
            params = ua.WriteParameters()
            for node, value in ((product, ua.Variant("forged")), (eu_range, ua.Variant(1.0))):
                params.NodesToWrite.append(
                    ua.WriteValue(
                        NodeId=node, AttributeId=ua.AttributeIds.Value, Value=ua.DataValue(value)
                    )
                )
            codes = await op.uaclient.write(params)
            assert [c.is_good() for c in codes] == [False, False]
            names = [c.name for c in codes]
            assert "BadNodeIdUnknown" not in names  # both nodes exist; neither is writable
        finally:
            await op.disconnect()
    records = [json.loads(line) for line in (tmp_path / "audit.jsonl").read_text().splitlines()]
    refused = [r for r in records if r["event"] == "write" and r["result"] == "refused"]
    seen = [(r["user"], r["role"], r.get("node"), r["reason"]) for r in refused]
    assert seen == [
        ("operator", "operator", product.to_string(), names[0]),
        ("operator", "operator", eu_range.to_string(), names[1]),
    ]


async def test_a_heartbeat_over_opcua_keeps_the_group_running_and_its_loss_trips_it(
    tmp_path: Path,
) -> None:
    async with running(safety_site(tmp_path)) as rt:
        hmi = await login(rt, tmp_path, "operator")
        admin = await login(rt, tmp_path, "admin")  # the clock, and a second connection
        try:
            h, clock = Session(rt, hmi), Session(rt, admin)
            await h.trigger(clock, "MSO_1", Axis=1)
            await clock.step(1)
            await h.trigger(clock, "MAJ_1", Axis=1, Speed=10.0, AccelRate=100.0)
            beat = 0
            for _ in range(10):  # 10 x 40 cycles = 0.8 s, beats every 40 cycles < 50
                beat += 1
                assert (await h.write("HMI1.Heartbeat", beat, U32)).is_good()
                await clock.step(40)
            assert await h.read("HMI1.State") == 1  # armed
            assert await h.read("HMI1.Fault") is False
            assert await h.read("Axis1.CommandVelocity") == pytest.approx(10.0)
            # the HMI goes silent; another connection's beats do not stand in for it
            await clock.step(8)  # 48 cycles since the HMI's last beat
            assert (await clock.write("HMI1.Heartbeat", 1000, U32)).is_good()
            await clock.step(1)  # 49
            assert await h.read("Axis1.CommandVelocity") == pytest.approx(10.0)
            assert await h.read("HMI1.Fault") is False
            await clock.step(4)  # 53: the stop ran at 50 (one 2 ms cycle), then the latch
            assert await h.read("Axis1.CommandVelocity") == 0.0
            assert await h.read("HMI1.Fault") is True
            assert await h.read("HMI1.Trips") == 1
            # the HMI comes back and beats: still latched, nothing moves
            assert (await h.write("HMI1.Heartbeat", beat + 1, U32)).is_good()
            await clock.step(20)
            assert await h.read("HMI1.Fault") is True
            assert await h.read("Axis1.CommandVelocity") == 0.0
        finally:
            await hmi.disconnect()
            await admin.disconnect()
