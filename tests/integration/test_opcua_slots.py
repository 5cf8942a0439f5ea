"""Subscription slots: one client cannot hold them all (real sockets, raw requests).

asyncua keeps a session that a second CreateSession on the same channel replaces: the
old one, its subscriptions and its activation slot live on until its session timeout,
so one anonymous connection that creates, activates and subscribes again and again takes
every subscription slot of the server. Here a replaced session is closed with its
subscriptions, a closed connection takes every session it created with it at once, and
the subscriptions of all the sessions from one client address count against
``max_subscriptions_per_client``.

A second client address on this machine: any address of 127.0.0.0/8 is loopback, so the
"attacker" connects from 127.0.0.2 and the other clients from 127.0.0.1.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from pathlib import Path

import pytest
import pytest_asyncio
from asyncua import Client, ua

from motion_server import config
from motion_server.runtime import Runtime
from tests.opcua_raw import RawChannel
from tests.opcua_support import SITE, USERS, running, user_hashes

pytestmark = pytest.mark.asyncio(loop_scope="module")
Codes = ua.StatusCodes
#: the server's subscription slots, a client address's share, a session's share
MAX_SUBSCRIPTIONS = 20
PER_CLIENT = 8
PER_SESSION = 3
OTHER_HOST = "127.0.0.2"
#: Server.ServerDiagnostics.ServerDiagnosticsSummary.CurrentSubscriptionCount
SUBSCRIPTIONS = ua.NodeId(
    ua.ObjectIds.Server_ServerDiagnostics_ServerDiagnosticsSummary_CurrentSubscriptionCount
)


def slots_site(data_dir: Path) -> config.SiteMap:
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in user_hashes().items()
    )
    text = SITE.format(
        data_dir=data_dir, anonymous="true", none_endpoint="true", lockout=0.0, users=users
    )
    fields = (
        f"max_subscriptions = {MAX_SUBSCRIPTIONS}\n"
        f"max_subscriptions_per_client = {PER_CLIENT}\n"
        f"max_subscriptions_per_session = {PER_SESSION}\n"
    )
    return config.parse(text.replace("[opcua]\n", "[opcua]\n" + fields, 1), "slots.toml")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    async with running(slots_site(tmp_path_factory.mktemp("opcua"))) as runtime:
        yield runtime


@contextlib.asynccontextmanager
async def observer(rt: Runtime) -> AsyncIterator[Client]:
    """An anonymous client from 127.0.0.1 (the None endpoint)."""
    assert rt.opcua is not None
    client = Client(rt.opcua.endpoint, timeout=5)
    await client.connect()
    try:
        yield client
    finally:
        await client.disconnect()


async def held(client: Client) -> int:
    """The server's current subscription count, as any client reads it."""
    return int(await client.get_node(SUBSCRIPTIONS).read_value())


async def settle(client: Client, expected: int, within: float = 1.0) -> int:
    """The subscription count once it is ``expected``, or after ``within`` seconds."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + within
    count = await held(client)
    while count != expected and loop.time() < deadline:
        await asyncio.sleep(0.02)
        count = await held(client)
    return count


async def raw(rt: Runtime, host: str = OTHER_HOST) -> RawChannel:
    assert rt.opcua is not None
    ch = await RawChannel.connect(rt.opcua.port, rt.opcua.endpoint, local_host=host)
    await ch.open()
    return ch


async def test_a_session_replaced_on_its_channel_is_closed_with_its_subscriptions(
    rt: Runtime,
) -> None:
    async with observer(rt) as other:
        base = await held(other)
        ch = await raw(rt)
        try:
            # six times the slots the server has: each round's subscription must replace
            # the last one, never add to it
            for round_ in range(6 * MAX_SUBSCRIPTIONS):
                assert await ch.anonymous_session() == Codes.Good, round_
                assert await ch.create_subscription() == Codes.Good, round_
            assert await settle(other, base + 1) == base + 1
            # and the other client is served
            sub = await other.create_subscription(100, None)
            await sub.delete()
        finally:
            await ch.close()
        # its last session goes with the connection, at once
        assert await settle(other, base) == base


async def test_one_client_address_holds_at_most_its_share_of_the_slots(rt: Runtime) -> None:
    async with observer(rt) as other:
        base = await held(other)
        channels: list[RawChannel] = []
        results: list[int] = []
        try:
            # connections from one address, each session filling its own quota
            for _ in range(MAX_SUBSCRIPTIONS // PER_SESSION + 1):
                ch = await raw(rt)
                channels.append(ch)
                assert await ch.anonymous_session() == Codes.Good
                results += [await ch.create_subscription() for _ in range(PER_SESSION)]
            assert results.count(Codes.Good) == PER_CLIENT
            assert set(results[PER_CLIENT:]) == {Codes.BadTooManySubscriptions}
            assert await held(other) == base + PER_CLIENT
            # another address still gets every slot that is left
            mine = [
                await other.create_subscription(100, None)
                for _ in range(min(PER_SESSION, MAX_SUBSCRIPTIONS - base - PER_CLIENT))
            ]
            for sub in mine:
                await sub.delete()
        finally:
            for ch in channels:
                await ch.close()
        assert await settle(other, base) == base
