"""Silent OPC UA clients over real sockets on 127.0.0.1: ``[opcua] idle_timeout`` closes
connections that send nothing, and a session whose client goes silent is closed after
its session timeout with its subscriptions, while live sessions go on working.

The server runs on the None endpoint with anonymous viewers (loopback; security plays no
part in timeouts). The silent session talks through a relay that can go quiet like a
hung client or a pulled cable: it then forwards nothing either way and keeps both
sockets open, and it notes when the server last received a byte from the client.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import struct
import time
from collections.abc import AsyncIterator
from pathlib import Path

from asyncua import Client
from asyncua.server.internal_session import SessionState

from motion_server import config
from tests.opcua_support import SITE, running

IDLE = 0.5  # s, the raw-socket test
SESSION_TIMEOUT = 5.0  # s, the smallest session timeout asyncua grants (and we allow)


def idle_site(tmp: Path, idle: float, max_session_timeout: float = 600.0) -> config.SiteMap:
    text = SITE.format(
        data_dir=tmp / "opcua-data", anonymous="true", none_endpoint="true", lockout=0.0, users=""
    )
    settings = f"idle_timeout = {idle}\nmax_session_timeout_s = {max_session_timeout}\n"
    text = text.replace("[opcua]\n", "[opcua]\n" + settings, 1)
    text = f'data_dir = "{tmp}"\n' + text + "\n[audit]\nenabled = true\n"
    return config.parse(text, "opcua-idle.toml")


def hello(url: str) -> bytes:
    """An OPC UA Hello (OPC 10000-6 §7.1.2.3): version, buffer sizes, limits, URL."""
    raw = url.encode()
    body = struct.pack("<IIIII", 0, 65535, 65535, 0, 0) + struct.pack("<i", len(raw)) + raw
    return b"HELF" + struct.pack("<I", 8 + len(body)) + body


@contextlib.asynccontextmanager
async def anonymous(url: str, session_timeout_ms: float = 60_000) -> AsyncIterator[Client]:
    client = Client(url, timeout=2)
    client.session_timeout = session_timeout_ms
    await client.connect()
    try:
        yield client
    finally:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(client.disconnect(), 5.0)


async def until(condition: object, timeout: float) -> float:
    """Poll ``condition()`` every 10 ms; the loop time when it held."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not condition():  # type: ignore[operator]
        assert loop.time() < end, "condition not met in time"
        await asyncio.sleep(0.01)
    return loop.time()


async def test_a_socket_that_sends_nothing_is_closed_and_live_sessions_go_on(
    tmp_path: Path,
) -> None:
    async with running(idle_site(tmp_path, IDLE)) as rt:
        assert rt.opcua is not None
        loop = asyncio.get_running_loop()
        async with anonymous(rt.opcua.endpoint) as live:
            node = live.get_node(f"ns={rt.opcua.namespace_index};s=Clock.Mode")
            assert await node.read_value() == 1  # manual
            # a socket that never sends anything
            t0 = loop.time()
            reader, writer = await asyncio.open_connection("127.0.0.1", rt.opcua.port)
            assert await asyncio.wait_for(reader.read(64), 5.0) == b""  # closed by the server
            silent = loop.time() - t0
            writer.close()
            # a socket that says Hello, gets its Acknowledge, and falls silent
            reader, writer = await asyncio.open_connection("127.0.0.1", rt.opcua.port)
            writer.write(hello(rt.opcua.endpoint))
            await writer.drain()
            t1 = loop.time()
            ack = await asyncio.wait_for(reader.read(8), 5.0)
            assert ack[:4] == b"ACKF"
            while chunk := await asyncio.wait_for(reader.read(64), 5.0):
                assert len(chunk) < 64  # the rest of the Acknowledge, then the close
            after_hello = loop.time() - t1
            writer.close()
            # closed after the timeout, not before; late by at most two check periods
            # (timeout / 4 each) plus scheduling
            for waited in (silent, after_hello):
                assert IDLE <= waited < IDLE + 1.0, waited
            assert rt.opcua.idle_closed == 2
            # the live session is not touched: its client talks once a second (asyncua's
            # watchdog), less often than the idle timeout asks, but its activated
            # session's timeout (60 s) is what counts for it
            await asyncio.sleep(2 * IDLE)
            assert await node.read_value() == 1
            assert rt.opcua.idle_closed == 2
    lines = [json.loads(x) for x in (tmp_path / "audit.jsonl").read_text().splitlines()]
    idle = [r for r in lines if r["event"] == "disconnect"]
    assert [r["result"] for r in idle] == ["idle timeout", "idle timeout"]
    assert all(r["protocol"] == "opcua" and r["address"] == "127.0.0.1" for r in idle)


class Relay:
    """A TCP relay to ``port`` for one client connection; ``quiet()`` makes it silent."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.silent = False
        #: loop time of the last byte passed on to the server
        self.last_to_server = 0.0
        #: loop time at which the server closed its side (None: still open)
        self.server_closed: float | None = None
        #: the relay's address as the server sees it
        self.upstream: tuple[str, int] = ("", 0)
        self._writers: list[asyncio.StreamWriter] = []
        self._tasks: list[asyncio.Task[None]] = []
        self._listener: asyncio.Server | None = None

    async def start(self) -> str:
        self._listener = await asyncio.start_server(self._accept, "127.0.0.1", 0)
        port = self._listener.sockets[0].getsockname()[1]
        return f"opc.tcp://127.0.0.1:{port}/"

    def quiet(self) -> None:
        self.silent = True

    async def _accept(self, creader: asyncio.StreamReader, cwriter: asyncio.StreamWriter) -> None:
        assert self.upstream == ("", 0), "one client connection only"
        sreader, swriter = await asyncio.open_connection("127.0.0.1", self.port)
        self.upstream = swriter.get_extra_info("sockname")[:2]
        self._writers += [cwriter, swriter]
        loop = asyncio.get_running_loop()

        async def pump(src: asyncio.StreamReader, dst: asyncio.StreamWriter, up: bool) -> None:
            with contextlib.suppress(OSError):
                while data := await src.read(65536):
                    if self.silent:
                        continue  # swallowed: neither side hears the other
                    if up:
                        self.last_to_server = loop.time()
                    dst.write(data)
            if not up:
                self.server_closed = loop.time()

        self._tasks += [
            asyncio.create_task(pump(creader, swriter, True)),
            asyncio.create_task(pump(sreader, cwriter, False)),
        ]

    async def close(self) -> None:
        for writer in self._writers:
            writer.close()
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        if self._listener is not None:
            self._listener.close()


async def test_a_silent_session_is_closed_after_its_timeout_with_its_subscriptions(
    tmp_path: Path,
) -> None:
    site = idle_site(tmp_path, idle=1.0, max_session_timeout=SESSION_TIMEOUT)
    async with running(site) as rt:
        assert rt.opcua is not None and rt.opcua.server is not None
        iserver = rt.opcua.server.iserver
        relay = Relay(rt.opcua.port)
        url = await relay.start()
        try:
            async with (
                anonymous(rt.opcua.endpoint) as live,
                anonymous(url, session_timeout_ms=60_000) as hung,
            ):
                # the server revises the asked 60 s down to its maximum
                assert hung.session_timeout == SESSION_TIMEOUT * 1000
                node = f"ns={rt.opcua.namespace_index};s=Clock.Cycle"
                sub = await hung.create_subscription(100, None)
                await sub.subscribe_data_change(hung.get_node(node))
                proto = next(
                    p for p in rt.opcua.server.bserver.clients if p.peer_name[:2] == relay.upstream
                )
                session = proto.processor.session
                assert session is not None and session.state == SessionState.Activated
                assert session.session_timeout == SESSION_TIMEOUT

                def subscriptions() -> int:
                    return sum(
                        s.session_id == session.session_id
                        for s in iserver.subscription_service.subscriptions.values()
                    )

                assert subscriptions() == 1
                relay.quiet()
                t0 = time.monotonic()
                closed = await until(lambda: session.state == SessionState.Closed, 10.0)
                assert subscriptions() == 0
                # no earlier than the session timeout after the last request the server
                # got; asyncua checks at least every timeout / 4
                assert closed - relay.last_to_server > SESSION_TIMEOUT
                assert closed - relay.last_to_server < SESSION_TIMEOUT * 1.25 + 0.5
                # the connection goes too: silent longer than the idle timeout, and no
                # longer holding an activated session (asyncua leaves it open)
                await until(lambda: relay.server_closed is not None, 3.0)
                assert rt.opcua.idle_closed == 1
                assert time.monotonic() - t0 < 9.0
                # the other session was never in danger
                assert await live.get_node(node).read_value() == 0
                await relay.close()  # the hung client's own teardown fails fast now
        finally:
            await relay.close()
