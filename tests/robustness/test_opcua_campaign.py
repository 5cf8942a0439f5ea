"""Malformed and abusive OPC UA traffic against a running server (loopback only).

Batches of one kind of abuse each, reproducible from a seed (``MOTION_FUZZ_SEED``, default
20250131), at least 2,000 messages per run (``MOTION_FUZZ_LONG=1``: ten times as many).
The server runs as deployed (``motion-server run``: the scan and each front-end in a
process of its own), with the realtime clock,
transport limits far below asyncua's 100 MB default (8 KiB chunks, 8 chunks, 32 KiB
messages) and a session limit. After every batch
a proper client (Basic256Sha256 SignAndEncrypt, user name) that stayed connected reads
``Diagnostics.DroppedCycles`` within 1 s and finds 0 (no cycle was late beyond the
catch-up bound), and a fresh secure client can still connect and log in. Counts and
checks are printed (``pytest -s`` shows them).

Every connection refused for a fault of its channel (a chunk with a wrong sequence number,
channel id or token, a message before any channel) gets an Error message, then its end.
Then, against the same server: a chunk size lie streamed on four connections at once
(64 MiB each) keeps the OPC UA process within 20 MB of its memory and drops no motion
cycle; and every operation limit is answered with ``BadTooManyOperations`` one operation
past it, while a request of exactly the limit is served.

A second server offers anonymous sessions on the None endpoint (where every request
reaches asyncua's decoders) and keeps an audit log: at least 2,000 mutated requests on
sessions leave at most 20 log lines per 10 s of the OPC UA front-end and no traceback;
CreateSession, ActivateSession, CreateSubscription 120 times on one connection hold one
subscription at a time and free it when the connection closes; 100 browse paths of
2,000 elements are refused before they are decoded; and 200 writes to NodeIds of random
bytes are all refused and audited in valid UTF-8.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import random
import stat
import struct
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio
from asyncua import Client, ua
from asyncua.crypto.security_policies import SecurityPolicyNone
from asyncua.ua.ua_binary import struct_to_binary

from motion_server import config
from tests.integration.test_opcua_limits import outcome, requests
from tests.opcua_raw import RawChannel, header, patch
from tests.opcua_support import SITE, USERS, secure_client_at, user_hashes
from tests.robustness.server_process import ServerProcess

pytestmark = pytest.mark.asyncio(loop_scope="module")

SEED = int(os.environ.get("MOTION_FUZZ_SEED", "20250131"))
SCALE = 10 if os.environ.get("MOTION_FUZZ_LONG") else 1
MIN_MESSAGES = 2_000 * SCALE
MAX_SESSIONS = 12
CHUNK = 8192
CHUNKS = 8
MESSAGE = 32768
#: operation limits and quotas of the campaign's site (requests past them fit in MESSAGE)
LIMITS = {
    "max_nodes_per_read": 50,
    "max_nodes_per_write": 40,
    "max_nodes_per_browse": 10,
    "max_nodes_per_translate_browse_paths": 10,
    "max_nodes_per_register_nodes": 50,
    "max_nodes_per_method_call": 10,
    "max_nodes_per_history_read": 10,
    "max_nodes_per_node_management": 10,
    "max_monitored_items_per_call": 50,
    "max_subscriptions_per_session": 5,
    "max_monitored_items_per_session": 100,
}
#: the lying-header stream: connections at once, bytes each, the memory the process may grow
STREAMS = 4
STREAM_BYTES = 64 << 20
MEMORY_GROWTH = 20_000_000


def campaign_site(data_dir: Path) -> str:
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in user_hashes().items()
    )
    text = SITE.format(
        data_dir=data_dir, anonymous="false", none_endpoint="false", lockout=0.0, users=users
    )
    text = text.replace('clock = "manual"', 'clock = "realtime"')
    limits = (
        f"max_sessions = {MAX_SESSIONS}\nmax_chunk_size = {CHUNK}\n"
        f"max_chunk_count = {CHUNKS}\nmax_message_size = {MESSAGE}\n"
    ) + "".join(f"{name} = {value}\n" for name, value in LIMITS.items())
    text = text.replace("[opcua]\n", "[opcua]\n" + limits, 1)
    config.parse(text, "opcua-campaign.toml")  # a bad map fails here, not in the child
    return text


# -- raw messages ------------------------------------------------------------------------------
def hello(url: str, recv: int = 65535, max_msg: int = 0, chunks: int = 0) -> bytes:
    raw = url.encode()
    body = struct.pack("<IIIII", 0, recv, recv, max_msg, chunks) + struct.pack("<i", len(raw))
    return header(b"HELF", 8 + len(body) + len(raw)) + body + raw


def zero_size(r: random.Random, url: str) -> list[bytes]:
    kind = r.choice([b"HELF", b"OPNF", b"MSGF", b"MSGC", b"CLOF", b"ERRF"])
    return [header(kind, 0) + r.randbytes(r.randrange(0, 16))]


def lying_header(r: random.Random, url: str) -> list[bytes]:
    good = hello(url)
    claim = r.choice([1, 7, 9, len(good) - 1, len(good) + 1, 2000, 0x7FFFFFFF, 0xFFFFFFFF])
    return [good[:4] + struct.pack("<I", claim) + good[8:]]


def unknown_type(r: random.Random, url: str) -> list[bytes]:
    kind = bytes(r.choice(b"ABCDXYZ") for _ in range(3)) + r.choice([b"F", b"C", b"A", b"Q"])
    body = r.randbytes(r.randrange(0, 64))
    return [header(kind, 8 + len(body)) + body]


def oversize_chunk(r: random.Random, url: str) -> list[bytes]:
    size = r.choice([CHUNK + 1, 65536, 1 << 20, 100 << 20])
    return [hello(url), header(b"MSGF", size) + r.randbytes(512)]


def garbage(r: random.Random, url: str) -> list[bytes]:
    return [r.randbytes(r.randrange(1, 400))]


def bad_hello(r: random.Random, url: str) -> list[bytes]:
    """Hello with limits below the minimum, absurd URLs, or a second Hello."""
    variants = [
        hello(url, recv=r.randrange(0, 8192)),
        hello("opc.tcp://" + "x" * r.randrange(4096, 9000)),
        hello(url) + hello(url),
        hello(url)[:-3],
    ]
    return [r.choice(variants)]


RAW: dict[str, Callable[[random.Random, str], list[bytes]]] = {
    "zero-size header": zero_size,
    "lying chunk header": lying_header,
    "unknown message type": unknown_type,
    "oversize chunk": oversize_chunk,
    "bad hello": bad_hello,
    "garbage": garbage,
}


async def send_raw(port: int, messages: list[bytes]) -> None:
    """One connection: send, read what comes back for a moment, close."""
    reader, writer = await asyncio.wait_for(asyncio.open_connection("127.0.0.1", port), 5)
    try:
        for m in messages:
            writer.write(m)
        with contextlib.suppress(OSError, ConnectionError):
            await writer.drain()
        with contextlib.suppress(asyncio.TimeoutError, OSError, ConnectionError):
            await asyncio.wait_for(reader.read(4096), 0.05)
    finally:
        writer.close()
        with contextlib.suppress(OSError, ConnectionError):
            await writer.wait_closed()


async def raw_batch(port: int, url: str, gen: Callable[..., list[bytes]], n: int) -> int:
    r = random.Random(f"{SEED}:{gen.__name__}:{n}")
    sent = 0
    parallel = 10
    for start in range(0, n, parallel):
        batch = [gen(r, url) for _ in range(min(parallel, n - start))]
        await asyncio.gather(*(send_raw(port, m) for m in batch))
        sent += sum(len(m) for m in batch)
    return sent  # messages


async def open_channel(srv: ServerProcess) -> Client:
    """A client with a secure channel (None policy: discovery only) and no session."""
    client = Client(srv.endpoint, timeout=5)
    client.security_policy = SecurityPolicyNone()
    await client.connect_socket()
    await client.send_hello()
    await client.open_secure_channel()
    return client


async def too_many_chunks(srv: ServerProcess, r: random.Random, n: int) -> int:
    """Intermediate chunks past max_chunk_count (and past max_message_size) on an open
    channel; the server must drop the message (and the channel), not buffer it."""
    sent = 0
    while sent < n:
        client = await open_channel(srv)
        proto = client.uaclient.protocol
        assert proto is not None and proto.transport is not None
        token = proto._connection.security_token
        count = r.randrange(CHUNKS + 1, 4 * CHUNKS)
        first = proto._connection._sequence_number + 1  # the channel's next sequence number
        for seq in range(first, first + count):
            body = r.randbytes(CHUNK - 24)
            chunk = header(b"MSGC", 24 + len(body)) + struct.pack(
                "<IIII", token.ChannelId, token.TokenId, seq, 77
            )
            proto.transport.write(chunk + body)
            sent += 1
        deadline = time.monotonic() + 2
        while proto.transport is not None and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        assert proto.transport is None, "the server kept a channel past max_chunk_count"
    return sent


async def before_activate(srv: ServerProcess, r: random.Random, n: int) -> int:
    """Read and Write on a session that was created but never activated: refused."""
    sent = 0
    while sent < n:
        client = await open_channel(srv)
        try:
            params = ua.CreateSessionParameters(
                ClientDescription=ua.ApplicationDescription(
                    ApplicationUri="urn:campaign", ApplicationType=ua.ApplicationType.Client
                ),
                EndpointUrl=srv.endpoint,
                SessionName="never activated",
                ClientNonce=r.randbytes(32),
                RequestedSessionTimeout=10_000,
            )
            await client.uaclient.create_session(params)  # not Client's: it wants a policy
            node = client.get_node(ua.NodeId("Clock.Cycle", srv.namespace_index))
            for _ in range(10):
                with pytest.raises(ua.UaError):
                    if r.random() < 0.5:
                        await node.read_value()
                    else:
                        await node.write_value(ua.DataValue(ua.Variant(1, ua.VariantType.UInt32)))
                sent += 1
        finally:
            with contextlib.suppress(Exception):
                client.disconnect_socket()
    return sent


async def subscriptions_left_behind(
    srv: ServerProcess, observer: Client, client_dir: Path, n: int
) -> int:
    """Sessions that subscribe, then close without deleting their subscriptions."""
    before = (await srv.stats(observer))["subscriptions"]
    sent = 0
    while sent < n:
        client = await secure_client_at(srv.endpoint, client_dir, "viewer")
        await client.connect()
        ns = srv.namespace_index
        for _ in range(3):
            sub = await client.create_subscription(50, None)
            nodes = [client.get_node(ua.NodeId(f"Clock.{f}", ns)) for f in ("Cycle", "Time")]
            await sub.subscribe_data_change(nodes)
            sent += 2
        await client.uaclient.close_session(delete_subscriptions=False)
        sent += 1
        with contextlib.suppress(Exception):
            await client.close_secure_channel()
        client.disconnect_socket()
    deadline = time.monotonic() + 5
    left = (await srv.stats(observer))["subscriptions"]
    while left > before and time.monotonic() < deadline:
        await asyncio.sleep(0.05)
        left = (await srv.stats(observer))["subscriptions"]
    assert left == before, "subscriptions outlived their sessions"
    return sent


async def dead_channels(srv: ServerProcess, r: random.Random, n: int) -> int:
    """Chunks with a wrong sequence number, channel id or token on an open channel, or a
    message on a connection that never opened one: each answered with an Error message,
    then the connection's end (asyncua left such connections open, unanswered)."""
    codes = {
        "sequence": ua.StatusCodes.BadSequenceNumberInvalid,
        "channel": ua.StatusCodes.BadTcpSecureChannelUnknown,
        "token": ua.StatusCodes.BadSecureChannelTokenUnknown,
        "no channel": ua.StatusCodes.BadTcpSecureChannelUnknown,
    }

    async def one(fault: str, shift: int) -> None:
        ch = await RawChannel.connect(srv.port, srv.endpoint)
        try:
            if fault == "no channel":
                await ch.hello()
                ch.send(ch.get_endpoints())
            else:
                await ch.open()
                chunk = ch.get_endpoints()
                token = ch.conn.security_token
                seq = struct.unpack_from("<I", chunk, 16)[0]
                ch.send(
                    {
                        "sequence": lambda: patch(chunk, seq=seq + shift),
                        "channel": lambda: patch(chunk, channel=token.ChannelId + shift),
                        "token": lambda: patch(chunk, token=token.TokenId + shift),
                    }[fault]()
                )
            code, _ = await ch.error()
            assert code == codes[fault], (fault, hex(code))
        finally:
            await ch.close()

    sent = 0
    while sent < n:
        batch = [(r.choice(list(codes)), r.randrange(1, 1 << 16)) for _ in range(10)]
        await asyncio.gather(*(one(fault, shift) for fault, shift in batch))
        sent += len(batch)
    return sent


async def session_flood(srv: ServerProcess, n: int) -> int:
    """Connections past max_sessions: the extra ones are refused, the rest still served."""
    url = srv.endpoint
    sent = 0
    while sent < n:
        conns = []
        for _ in range(MAX_SESSIONS * 3):
            with contextlib.suppress(OSError):
                r, w = await asyncio.open_connection("127.0.0.1", srv.port)
                w.write(hello(url))
                conns.append((r, w))
                sent += 1
        acks = 0
        for r, _ in conns:
            with contextlib.suppress(asyncio.TimeoutError, OSError, ConnectionError):
                if (await asyncio.wait_for(r.read(8), 2.0)).startswith(b"ACK"):
                    acks += 1
        # the checking client holds one connection: at most MAX_SESSIONS - 1 more accepted
        assert acks <= MAX_SESSIONS - 1, f"{acks} connections accepted past the limit"
        for _, w in conns:
            w.close()
        await asyncio.sleep(0.05)
    return sent


# -- the campaign --------------------------------------------------------------------------------
@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def server(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[ServerProcess]:
    directory = tmp_path_factory.mktemp("opcua-campaign")
    srv = ServerProcess(campaign_site(directory / "opcua-data"), directory)
    await srv.start()
    try:
        yield srv
    finally:
        await srv.stop()


class Checker:
    """The proper client that stays connected, and the post-batch checks."""

    def __init__(self, srv: ServerProcess, client_dir: Path) -> None:
        self.srv, self.client_dir = srv, client_dir
        self.client: Client | None = None

    async def __aenter__(self) -> Checker:
        self.client = await secure_client_at(self.srv.endpoint, self.client_dir, "operator")
        await self.client.connect()
        await self.srv.stats(self.client)  # learns the namespace index
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self.client is not None:
            await self.client.disconnect()

    async def check(self, label: str) -> tuple[float, int]:
        assert self.client is not None
        ns = self.srv.namespace_index
        dropped = self.client.get_node(ua.NodeId("Diagnostics.DroppedCycles", ns))
        t0 = time.perf_counter()
        value = await asyncio.wait_for(dropped.read_value(), 1.0)
        elapsed = time.perf_counter() - t0
        assert elapsed < 1.0, f"{label}: read answered after {elapsed:.3f} s"
        late = [line for line in self.srv.log().splitlines() if "late" in line]
        assert value == 0, f"{label}: {value} cycles dropped (late beyond catch-up): {late}"
        fresh = await secure_client_at(self.srv.endpoint, self.client_dir, "viewer")
        await asyncio.wait_for(fresh.connect(), 10.0)  # new clients are served too
        cycle = await fresh.get_node(ua.NodeId("Clock.Cycle", ns)).read_value()
        await fresh.disconnect()
        return elapsed, cycle


async def test_malformed_message_campaign(server: ServerProcess, tmp_path: Path) -> None:
    srv = server
    url, port = srv.endpoint, srv.port
    r = random.Random(SEED)
    per_batch = 250 * SCALE
    checker = Checker(srv, tmp_path)
    kinds: list[tuple[str, Callable[[], Awaitable[int]]]] = [
        (name, lambda gen=gen: raw_batch(port, url, gen, per_batch)) for name, gen in RAW.items()
    ]
    kinds += [
        ("too many chunks", lambda: too_many_chunks(srv, r, per_batch)),
        ("before activate", lambda: before_activate(srv, r, per_batch // 5)),
        (
            "subscriptions left",
            lambda: subscriptions_left_behind(srv, checker.client, tmp_path, 21 * SCALE),
        ),
        ("session flood", lambda: session_flood(srv, MAX_SESSIONS * 3 * SCALE)),
        ("dead channels", lambda: dead_channels(srv, r, per_batch // 5)),
    ]
    print(f"\nOPC UA campaign, seed {SEED}, at least {MIN_MESSAGES} messages")
    total = batches = 0
    async with checker:
        while total < MIN_MESSAGES:
            for name, run in kinds:
                result = await run()
                n = result
                total += n
                batches += 1
                elapsed, cycle = await checker.check(name)
                assert checker.client is not None
                stats = await srv.stats(checker.client)
                print(
                    f"batch {batches:3d} {name:20s} {n:5d} messages; valid read in "
                    f"{elapsed * 1000:6.1f} ms; cycle {cycle}; overruns {stats['overruns']}, "
                    f"dropped {stats['dropped']}"
                )
    print(f"total {total} malformed or abusive messages in {batches} batches")
    assert total >= MIN_MESSAGES


# -- the chunk size lie, streamed ------------------------------------------------------------
def rss(pid: int) -> int:
    """Resident memory of process ``pid`` in bytes."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"no VmRSS for {pid}")


async def stream_lie(port: int, total: int, stop: asyncio.Event) -> tuple[int, int]:
    """A MSG header announcing 0x7FFFFFFF bytes, no Hello, then random bytes, on one
    connection after another until ``total`` bytes went out (or ``stop``); returns (bytes
    the kernel took, connections)."""
    block = os.urandom(1 << 16)
    sent = connections = 0
    while sent < total and not stop.is_set():
        _, writer = await asyncio.open_connection("127.0.0.1", port)
        connections += 1
        try:
            writer.write(header(b"MSGF", 0x7FFFFFFF))
            while sent < total and not stop.is_set():
                writer.write(block)
                await asyncio.wait_for(writer.drain(), 5.0)
                sent += len(block)
        except (ConnectionError, OSError):
            pass  # cut by the server: the next connection goes on
        finally:
            writer.close()
            with contextlib.suppress(OSError, ConnectionError):
                await writer.wait_closed()
    return sent, connections


async def test_a_chunk_size_lie_streamed_on_four_connections_costs_no_memory(
    server: ServerProcess, tmp_path: Path
) -> None:
    srv = server
    pid = srv.child("opcua")
    checker = Checker(srv, tmp_path)
    async with checker:
        await checker.check("before the stream")
        base = peak = rss(pid)
        stop = asyncio.Event()

        async def watch() -> None:
            nonlocal peak
            while not stop.is_set():
                peak = max(peak, rss(pid))
                if peak - base > MEMORY_GROWTH:
                    stop.set()  # the lie is being buffered: no need to go on
                await asyncio.sleep(0.01)

        watcher = asyncio.create_task(watch())
        t0 = time.perf_counter()
        results = await asyncio.gather(
            *(stream_lie(srv.port, STREAM_BYTES, stop) for _ in range(STREAMS))
        )
        stop.set()
        await watcher
        elapsed = time.perf_counter() - t0
        peak = max(peak, rss(pid))
        sent = sum(s for s, _ in results)
        connections = sum(c for _, c in results)
        print(
            f"\nchunk size lie: {sent / 2**20:.0f} MiB on {connections} connections "
            f"({STREAMS} at a time) in {elapsed:.1f} s; OPC UA process {base / 1e6:.1f} MB, "
            f"peak +{(peak - base) / 1e6:.1f} MB"
        )
        assert peak - base < MEMORY_GROWTH, f"the OPC UA process grew by {peak - base} bytes"
        assert sent >= STREAMS * STREAM_BYTES
        elapsed, cycle = await checker.check("chunk size lie")  # no cycle dropped, still served
        print(f"after it: a read in {elapsed * 1000:.1f} ms, cycle {cycle}")


# -- operation limits --------------------------------------------------------------------------
async def test_each_operation_limit_is_answered_with_bad_too_many_operations(
    server: ServerProcess, tmp_path: Path
) -> None:
    srv = server
    client = await secure_client_at(srv.endpoint, tmp_path, "admin")
    await client.connect()
    try:
        ns = await client.get_namespace_index(srv.namespace_uri)
        published = ua.ObjectIds.Server_ServerCapabilities_OperationLimits_MaxNodesPerRead
        assert (
            await client.get_node(ua.NodeId(published)).read_value() == LIMITS["max_nodes_per_read"]
        )
        sub = await client.create_subscription(100, None)
        for label, request in requests(client, ns, sub.subscription_id).items():
            limit = LIMITS[label.split(" ")[0]]
            assert await outcome(request(limit + 1)) == ua.StatusCodes.BadTooManyOperations, label
            assert await outcome(request(limit)) != ua.StatusCodes.BadTooManyOperations, label
            print(f"{label}: {limit + 1} operations refused, {limit} served")
        await sub.delete()
    finally:
        await client.disconnect()


# -- mutated requests on a session (the None endpoint, anonymous) -------------------------------
#: how many mutated messages the batch sends, and the log it may leave (see FLOOD_*)
MUTATED = 2_000 * SCALE


def open_site(data_dir: Path) -> str:
    """The campaign's site with anonymous sessions on the None endpoint (where every
    request reaches asyncua's decoders) and the audit log on."""
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in user_hashes().items()
    )
    text = SITE.format(
        data_dir=data_dir / "opcua",
        anonymous="true",
        none_endpoint="true",
        lockout=0.0,
        users=users,
    )
    text = text.replace('clock = "manual"', 'clock = "realtime"')
    text = f'data_dir = "{data_dir}"\n' + text + "\n[audit]\nenabled = true\n"
    config.parse(text, "opcua-open.toml")
    return text


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def open_server(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[ServerProcess]:
    directory = tmp_path_factory.mktemp("opcua-open")
    srv = ServerProcess(open_site(directory), directory)
    await srv.start()
    try:
        yield srv
    finally:
        await srv.stop()


def session_requests(url: str, ns: int) -> list[Any]:
    """One valid request of each service a session uses (the token is set when sent)."""
    cycle = ua.NodeId("Clock.Cycle", ns)
    read = ua.ReadRequest()
    read.Parameters.NodesToRead = [ua.ReadValueId(cycle, ua.AttributeIds.Value)]
    write = ua.WriteRequest()
    write.Parameters.NodesToWrite = [
        ua.WriteValue(
            NodeId=ua.NodeId("Instructions.MAG_1.Ratio", ns),
            AttributeId=ua.AttributeIds.Value,
            Value=ua.DataValue(ua.Variant(1.5, ua.VariantType.Float)),
        )
    ]
    browse = ua.BrowseRequest()
    browse.Parameters.NodesToBrowse = [
        ua.BrowseDescription(NodeId=ua.NodeId(ua.ObjectIds.ObjectsFolder), ResultMask=63)
    ]
    translate = ua.TranslateBrowsePathsToNodeIdsRequest()
    translate.Parameters.BrowsePaths = [
        ua.BrowsePath(
            StartingNode=ua.NodeId(ua.ObjectIds.ObjectsFolder),
            RelativePath=ua.RelativePath(
                Elements=[ua.RelativePathElement(TargetName=ua.QualifiedName("Clock", ns))]
            ),
        )
    ]
    subscribe = ua.CreateSubscriptionRequest()
    subscribe.Parameters.RequestedPublishingInterval = 100.0
    monitor = ua.CreateMonitoredItemsRequest()
    monitor.Parameters.SubscriptionId = 1
    monitor.Parameters.ItemsToCreate = [
        ua.MonitoredItemCreateRequest(ItemToMonitor=ua.ReadValueId(cycle, ua.AttributeIds.Value))
    ]
    register = ua.RegisterNodesRequest()
    register.Parameters.NodesToRegister = [cycle]
    call = ua.CallRequest()
    call.Parameters.MethodsToCall = [
        ua.CallMethodRequest(
            ObjectId=ua.NodeId(ua.ObjectIds.Server),
            MethodId=ua.NodeId(ua.ObjectIds.Server_GetMonitoredItems),
            InputArguments=[ua.Variant(1, ua.VariantType.UInt32)],
        )
    ]
    endpoints = ua.GetEndpointsRequest()
    endpoints.Parameters.EndpointUrl = url
    return [read, write, browse, translate, subscribe, monitor, register, call, endpoints]


def mutate(r: random.Random, data: bytes) -> bytes:
    """``data`` with one random mutation: bytes flipped, cut, inserted, an array length
    or a string length made huge or negative, bytes that are not UTF-8, a slice repeated."""
    b = bytearray(data)
    at = r.randrange(len(b))
    op = r.randrange(6)
    if op == 0:
        for _ in range(r.randrange(1, 5)):
            b[r.randrange(len(b))] ^= 1 << r.randrange(8)
    elif op == 1:
        del b[at:]
    elif op == 2:
        b[at:at] = r.randbytes(r.randrange(1, 16))
    elif op == 3:
        b[at : at + 4] = r.choice([b"\xff\xff\xff\xff", b"\xff\xff\xff\x7f", b"\x00\x00\x00\x80"])
    elif op == 4:
        b[at : at + 3] = b"\xff\xfe\x80"
    else:
        b[at:at] = b[at : at + r.randrange(1, 64)]
    return bytes(b)


def broken_hello(r: random.Random, url: str) -> bytes:
    """A Hello whose EndpointUrl is not UTF-8."""
    raw = url.encode() + r.choice([b"\xff", b"\xed\xa0\x80", b"\xc0\xaf", b"\x80\x80"])
    body = struct.pack("<IIIII", 0, 65535, 65535, 0, 0) + struct.pack("<i", len(raw))
    return header(b"HELF", 8 + len(body) + len(raw)) + body + raw


async def mutated_connection(srv: ServerProcess, r: random.Random, requests: list[Any]) -> int:
    """One connection: a Hello (now and then a broken one), a channel, an anonymous
    session, then up to 10 mutated requests (or chunks) sent at once; what comes back is
    read for a moment. Returns the mutated messages sent."""
    ch = await RawChannel.connect(srv.port, srv.endpoint)
    try:
        if r.random() < 0.05:
            ch.send(broken_hello(r, srv.endpoint))
            with contextlib.suppress(asyncio.TimeoutError, OSError, ConnectionError):
                await asyncio.wait_for(ch.reader.read(), 1.0)
            return 1
        await ch.open()
        assert await ch.anonymous_session() == ua.StatusCodes.Good
        sent = 0
        for _ in range(r.randrange(1, 11)):
            request = r.choice(requests)
            request.RequestHeader.AuthenticationToken = ch.token
            body = struct_to_binary(request)
            if r.random() < 0.8:  # the request mutated, framed right
                chunk = ch.request(mutate(r, body))
            else:  # the chunk mutated, headers included
                chunk = mutate(r, ch.request(body))
            with contextlib.suppress(OSError, ConnectionError):
                ch.send(chunk)
            sent += 1
        with contextlib.suppress(OSError, ConnectionError):
            await ch.writer.drain()
        with contextlib.suppress(asyncio.TimeoutError, OSError, ConnectionError):
            while await asyncio.wait_for(ch.reader.read(65536), 0.2):
                pass
        return sent
    finally:
        await ch.close()


#: the log the mutated batch may leave: lines of the OPC UA front-end per 10 s window
FLOOD_LINES = 20
FLOOD_WINDOW_S = 10.0


async def test_mutated_requests_leave_one_line_each_at_most_and_no_traceback(
    open_server: ServerProcess, tmp_path: Path
) -> None:
    srv = open_server
    checker = Checker(srv, tmp_path)
    async with checker:
        ns = srv.namespace_index
        requests = session_requests(srv.endpoint, ns)
        r = random.Random(f"{SEED}:mutated")
        before = len(srv.log().splitlines())
        t0 = time.monotonic()
        sent = 0
        while sent < MUTATED:
            counts = await asyncio.gather(
                *(mutated_connection(srv, r, requests) for _ in range(10))
            )
            sent += sum(counts)
        elapsed = time.monotonic() - t0
        await asyncio.sleep(0.5)  # the last lines
        await checker.check("mutated requests")
    new = srv.log().splitlines()[before:]
    opcua = [line for line in new if " motion_server.opcua" in line or " asyncua" in line]
    tracebacks = [line for line in new if line.startswith("Traceback")]
    windows = int(elapsed // FLOOD_WINDOW_S) + 2
    print(
        f"\n{sent} mutated messages in {elapsed:.1f} s: {len(new)} log lines, {len(opcua)} "
        f"of the OPC UA front-end, {len(tracebacks)} tracebacks"
    )
    for line in new[:40]:
        print("  ", line[:200])
    assert not tracebacks, "\n".join(new[:200])
    # at most FLOOD_LINES per window, and one "suppressed" line for each window
    assert len(opcua) <= windows * (FLOOD_LINES + 1), len(opcua)


# -- subscription slots, long browse paths, writes of any bytes (the None endpoint) --------------
async def test_session_recreation_on_one_channel_holds_one_subscription_at_a_time(
    open_server: ServerProcess, tmp_path: Path
) -> None:
    """CreateSession, ActivateSession, CreateSubscription 120 times on one connection
    (the server has 100 slots): each new session closes the one it replaces, with its
    subscription; the slots are free at once when the connection closes."""
    srv = open_server
    async with Checker(srv, tmp_path) as checker:
        assert checker.client is not None
        base = (await srv.stats(checker.client))["subscriptions"]
        ch = await RawChannel.connect(srv.port, srv.endpoint)
        try:
            await ch.open()
            results = []
            for _ in range(120):
                results.append(await ch.anonymous_session())
                results.append(await ch.create_subscription())
            assert set(results) == {ua.StatusCodes.Good}
            held = (await srv.stats(checker.client))["subscriptions"]
            assert held == base + 1, held
        finally:
            await ch.close()
        deadline = time.monotonic() + 1.0
        left = (await srv.stats(checker.client))["subscriptions"]
        while left != base and time.monotonic() < deadline:
            await asyncio.sleep(0.02)
            left = (await srv.stats(checker.client))["subscriptions"]
        assert left == base
        sub = await checker.client.create_subscription(100, None)  # a slot for the others
        await sub.delete()
        await checker.check("session re-creation")


async def test_browse_paths_of_2000_elements_are_refused_at_once(
    open_server: ServerProcess, tmp_path: Path
) -> None:
    """The issue's request, 100 paths of 2,000 elements (3 MB), three times: refused
    before it is decoded; the checking client's Read stays within 1 s, no cycle dropped."""
    srv = open_server
    async with Checker(srv, tmp_path) as checker:  # it learns the namespace index
        step = ua.RelativePathElement(
            ReferenceTypeId=ua.NodeId(ua.ObjectIds.HierarchicalReferences),
            IncludeSubtypes=True,
            TargetName=ua.QualifiedName("Clock", srv.namespace_index),
        )
        path = ua.BrowsePath(
            StartingNode=ua.NodeId(ua.ObjectIds.ObjectsFolder),
            RelativePath=ua.RelativePath(Elements=[step] * 2000),
        )
        ch = await RawChannel.connect(srv.port, srv.endpoint)
        try:
            await ch.open()
            assert await ch.anonymous_session() == ua.StatusCodes.Good
            request = ua.TranslateBrowsePathsToNodeIdsRequest()
            request.RequestHeader.AuthenticationToken = ch.token
            request.Parameters.BrowsePaths = [path] * 100
            encoded = struct_to_binary(request)
            for _ in range(3):
                ch.send(ch.request(encoded))
                assert await ch.service_result(30.0) == ua.StatusCodes.BadTooManyOperations
        finally:
            await ch.close()
        elapsed, _ = await checker.check("long browse paths")
        print(f"\nlong browse paths: refused; a Read after them in {elapsed * 1000:.1f} ms")


async def test_refused_writes_of_any_bytes_are_all_audited(open_server: ServerProcess) -> None:
    """Writes of an anonymous viewer to NodeIds of random bytes (mostly not UTF-8, in
    namespace 2, outside the tag map): every one refused and audited in a line of valid
    UTF-8; the audit file is 0600."""
    srv = open_server
    r = random.Random(f"{SEED}:audit")
    names = [b"Campaign." + r.randbytes(r.randrange(1, 24)) for _ in range(200)]
    ch = await RawChannel.connect(srv.port, srv.endpoint)
    try:
        await ch.open()
        assert await ch.anonymous_session() == ua.StatusCodes.Good
        for name in names:
            request = ua.WriteRequest()
            request.Parameters.NodesToWrite = [
                ua.WriteValue(
                    NodeId=ua.NodeId(name.decode("utf-8", "surrogateescape"), 2),
                    AttributeId=ua.AttributeIds.Value,
                    Value=ua.DataValue(ua.Variant(1.0, ua.VariantType.Float)),
                )
            ]
            assert await ch.call(request) == ua.StatusCodes.Good  # the item is refused
    finally:
        await ch.close()
    path = srv.site_file.parent / "audit.jsonl"
    deadline = time.monotonic() + 5.0
    while True:
        lines = path.read_bytes().decode("utf-8").splitlines()  # strictly UTF-8
        records = [json.loads(line) for line in lines]
        ours = [
            r
            for r in records
            if r["result"] == "refused" and str(r.get("node", "")).startswith("ns=2;s=Campaign.")
        ]
        if len(ours) >= len(names) or time.monotonic() > deadline:
            break
        await asyncio.sleep(0.1)
    print(f"\n{len(names)} writes of random NodeIds refused: {len(ours)} audited")
    assert len(ours) == len(names)
    expected = [
        "ns=2;s="
        + n.decode("utf-8", "surrogateescape")
        .encode("utf-8", "surrogateescape")
        .decode("utf-8", "backslashreplace")
        for n in names
    ]
    assert [r["node"] for r in ours] == expected
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
