"""Roles on every writable node kind, and the failed-login lockout, over a real socket.

The rule (frontends/opcua.py ``required_role``): viewers write nothing; operators write
instruction operands and Execute, hand-wheel inputs, fault injection and the Safety
tags (heartbeat, reset); only admins write the Clock tags. Lockout:
``max_login_failures`` wrong passwords from one address lock it out, even with the right
password, for ``login_lockout_s``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua

from motion_server import config
from motion_server.frontends.opcua_space import VARIANT_TYPES
from motion_server.runtime import Runtime
from tests.opcua_support import SITE, USERS, running, secure_client, user_hashes

EXTRA = """
[[axes]]
name = "Wheel"
type = "feedback_only"

[[watchdogs]]
name = "HMI1"
timeout = 1.0
group = "Group1"
"""

#: one writable tag of every node kind, and a value it accepts
NODE_KINDS: dict[str, Any] = {
    "MAJ_1.Speed": 12.5,  # instruction operand
    "MAJ_1.Execute": False,  # trigger (False: no motion, the role check is the same)
    "Wheel.FeedbackInput": 3.25,  # hand-wheel input
    "Axis1.InjectPosSoftOvertravel": False,  # fault injection (False: no fault)
    "HMI1.Heartbeat": 7,  # Safety: heartbeat
    "HMI1.Reset": False,  # Safety: reset
    "Clock.StepCycles": 3,  # Clock
}
ADMIN_ONLY = {"Clock.StepCycles"}


def roles_site(tmp: Path, failures: int = 5, lockout: float = 0.0) -> config.SiteMap:
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in user_hashes().items()
    )
    text = SITE.format(
        data_dir=tmp, anonymous="false", none_endpoint="false", lockout=lockout, users=users
    )
    text = text.replace("[opcua]\n", f"[opcua]\nmax_login_failures = {failures}\n", 1)
    text = text.replace(
        'axes = ["Axis1", "Axis2", "Axis3"]', 'axes = ["Axis1", "Axis2", "Axis3", "Wheel"]'
    )
    return config.parse(text + EXTRA, "opcua-roles.toml")


async def write(rt: Runtime, client: Client, tag: str, value: Any) -> int:
    assert rt.opcua is not None
    t = rt.tagmap.tag(tag)
    wv = ua.WriteValue(
        NodeId=ua.NodeId(t.node_id, rt.opcua.namespace_index),
        AttributeId=ua.AttributeIds.Value,
        Value=ua.DataValue(ua.Variant(value, VARIANT_TYPES[t.type])),
    )
    codes = await client.uaclient.write(ua.WriteParameters(NodesToWrite=[wv]))
    return int(codes[0].value)


async def test_every_writable_node_kind_enforces_the_roles(tmp_path: Path) -> None:
    good, denied = ua.StatusCodes.Good, ua.StatusCodes.BadUserAccessDenied
    async with running(roles_site(tmp_path)) as rt:
        assert {t.name for t in rt.tagmap if t.writable} >= NODE_KINDS.keys()
        for user in ("viewer", "operator", "admin"):
            client = await secure_client(rt, tmp_path, user)
            await client.connect()
            try:
                for tag, value in NODE_KINDS.items():
                    allowed = user == "admin" or (user == "operator" and tag not in ADMIN_ONLY)
                    code = await write(rt, client, tag, value)
                    assert code == (good if allowed else denied), (user, tag, hex(code))
                    if allowed and not isinstance(value, bool):
                        assert rt.image.read(tag) == value, (user, tag)
            finally:
                await client.disconnect()


async def test_repeated_failed_logins_lock_the_address_out(tmp_path: Path) -> None:
    async with running(roles_site(tmp_path, failures=3, lockout=300.0)) as rt:
        for _ in range(3):
            client = await secure_client(rt, tmp_path, "operator", "wrong")
            with pytest.raises(ua.UaError):
                await client.connect()
        # locked out: the right password is refused too
        client = await secure_client(rt, tmp_path, "operator")
        with pytest.raises(ua.UaError):
            await client.connect()
        assert rt.opcua is not None and rt.opcua.directory.limiter.locked("127.0.0.1")
        # after the lockout ends, the right password works again
        rt.opcua.directory.limiter._locked_until["127.0.0.1"] = 0.0
        client = await secure_client(rt, tmp_path, "operator")
        await client.connect()
        await client.disconnect()
