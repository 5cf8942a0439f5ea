"""A small site for the OPC UA tests (manual clock, ephemeral port, no Modbus), its users,
and asyncua clients on the secure endpoint."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from pathlib import Path

from asyncua import Client, ua
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

from motion_server import config
from motion_server.frontends.opcua_users import hash_password
from motion_server.runtime import Runtime

#: user -> (role, password)
USERS = {
    "viewer": ("viewer", "look-only"),
    "operator": ("operator", "run-the-line"),
    "admin": ("admin", "own-the-clock"),
}
CLIENT_URI = "urn:motion-server:test-client"

SITE = """
[site]
name = "opcua_test"
namespace_uri = "urn:motion-server:opcua-test"

[controller]
clock = "manual"
status_log_interval = 0.0

[modbus]
enabled = false

[opcua]
port = 0
data_dir = "{data_dir}"
allow_anonymous = {anonymous}
allow_none_endpoint = {none_endpoint}
login_lockout_s = {lockout}
{users}

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Axis1", "Axis2", "Axis3"]

# the master: a virtual axis (actual = command, no drive lag)
[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[[axes]]
name = "Axis2"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

# MC_Power is level-controlled: on its own axis, so that it does not hold Axis1 off
[[axes]]
name = "Axis3"
type = "virtual"

[instructions]
every_type = true

[[instructions.instances]]
name = "MC_Power_1"
type = "MC_Power"
operands = {{ Axis = 3 }}
"""


def opcua_site(
    data_dir: Path,
    hashes: dict[str, str],
    anonymous: bool = False,
    none_endpoint: bool = False,
    lockout: float = 30.0,
) -> config.SiteMap:
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in hashes.items()
    )
    text = SITE.format(
        data_dir=data_dir,
        anonymous=str(anonymous).lower(),
        none_endpoint=str(none_endpoint).lower(),
        lockout=lockout,
        users=users,
    )
    return config.parse(text, "opcua-test.toml")


def user_hashes() -> dict[str, str]:
    # a low scrypt cost keeps the tests fast; the format and the check are the same
    return {name: hash_password(pw, n=2**10) for name, (_, pw) in USERS.items()}


@contextlib.asynccontextmanager
async def running(site: config.SiteMap) -> AsyncIterator[Runtime]:
    rt = Runtime(site)
    task = asyncio.create_task(rt.serve())
    try:
        await asyncio.wait_for(rt.ready.wait(), 30.0)
        assert rt.opcua is not None
        yield rt
    finally:
        rt.request_stop()
        await asyncio.wait_for(task, 20.0)


async def secure_client(
    rt: Runtime,
    client_dir: Path,
    user: str | None,
    password: str | None = None,
    mode: ua.MessageSecurityMode = ua.MessageSecurityMode.SignAndEncrypt,
) -> Client:
    """A client on the Basic256Sha256 endpoint (not connected yet)."""
    assert rt.opcua is not None
    return await secure_client_at(rt.opcua.endpoint, client_dir, user, password, mode)


async def secure_client_at(
    endpoint: str,
    client_dir: Path,
    user: str | None,
    password: str | None = None,
    mode: ua.MessageSecurityMode = ua.MessageSecurityMode.SignAndEncrypt,
) -> Client:
    """:func:`secure_client` for a server known by its endpoint (another process)."""
    client = Client(endpoint, timeout=10)
    client.application_uri = CLIENT_URI
    cert, key = await client.setup_self_signed_certificate(
        client_dir / "client-key.pem", client_dir / "client-cert.der"
    )
    await client.set_security(SecurityPolicyBasic256Sha256, str(cert), str(key), mode=mode)
    if user is not None:
        client.set_user(user)
        client.set_password(password if password is not None else USERS[user][1])
    return client
