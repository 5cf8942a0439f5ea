"""Modbus TCP front-end: holding registers over the scan's image (:class:`~.view.ImageView`).

The front-end parses Modbus TCP itself: :mod:`.modbus_protocol` splits each connection's
byte stream into ADUs and answers every complete one, in order, whatever the
segmentation; :mod:`.modbus_pdu` decodes requests with the Modbus Application Protocol's
checks. This module listens, admits and times connections, and serves each request on
the image. Status registers are encoded from the snapshot the scan published last
(nothing is pushed per cycle), so a read always shows the last completed cycle.

Served: FC3 (read), FC6 and FC16 (write), FC22 (mask write) and FC23 (read/write).
Exceptions:

- 01 every other function code (0..255: coils, discrete inputs, input registers,
  diagnostics, file records, ...);
- 02 a register outside the map, or a write that touches a read-only register or that
  the access rules or the client's role refuse;
- 03 a malformed request (a PDU whose length does not fit its function code, FC3 count
  outside 1..125, FC16 count outside 1..123 or a byte count other than 2 x count, FC23
  read count outside 1..125 or write count outside 1..121), or a value the tag cannot
  hold (a SINT beyond -128..127, an unknown ``Clock.Mode``, a non-finite hand-wheel input);
- 04 the scan cannot take writes (gone, or refused this front-end);
- 0B (gateway target failed to respond) a unit id other than the site's; with
  ``unit_id = 0`` every unit id is answered.

A header with a protocol id other than 0 or a length outside 2..254 closes the
connection at once: nothing after it can be delimited.

Reads show the last cycle the scan published; writes are judged here and queued for the
scan's next cycle; a client reads back what it wrote at once. A write that covers only
part of a 32/64-bit value changes those words: operands are latched on the trigger's
edge, so a client may write the two halves separately. A write to ``Clock.Step`` is
answered once the cycles it asked for have run (manual clock); requests pipelined behind
it are answered after it.

Safety (``motion_server.safety``): each connection is a :class:`ClientInfo` (address,
port, a connection number); requests are served ``writing_as`` it, so watchdogs and the
audit log know who wrote. ``[modbus.access]`` (:class:`AccessPolicy`) closes connections
from networks not allowed and past ``max_connections`` at once, and refuses writes
(read-only mode, per-network write ranges) with exception 02. Accepted writes reach the
audit log through the image's observers; refused ones (by the rules, the image, or the
request's own checks) are audited here with their reason and registers.

Time limits: a connection is closed after ``idle_timeout`` seconds (default 60) without
a complete request, and when a frame takes longer than :data:`FRAME_TIMEOUT` to arrive
whole. At ``max_connections``, a new client takes the place of a connection whose
incomplete frame has been arriving for :data:`STALLED_AFTER` or more (the longest such
one): bytes that trickle in never hold a slot against a client that sends requests.

Modbus/TCP Security (``[modbus.tls]``, :mod:`.modbus_tls`): a second listener (port 802
by default) serves the same image through the same handling, access policy, connection
limit (shared) and time limits, inside TLS with a required client certificate. The
handshake runs per connection (``loop.start_tls``) after the allowlist and the limit
admitted it, so a failed one is logged with its address, counted and audited, and holds
nothing afterwards. A refused handshake (no certificate, another CA, too slow) is audited
with its reason; an accepted one with the certificate's subject CN as ``user`` and its
role, which then limits the writes (:class:`~motion_server.safety.roles.Role`: viewer
none, operator all but ``Clock``, admin all) on top of ``[modbus.access]``. Frames are
parsed as on plain TCP.

Triggers and disconnects: the front-end never changes a trigger on a client's behalf. An
``Execute`` left high by a client that disconnected stays high in the image; a client
that reconnects and writes 1 again (a cyclic master re-sending its output block) makes no
rising edge, so nothing fires twice. To fire again a client writes 0, then 1. (Lowering
the triggers on disconnect was rejected: it turns exactly that stale re-write into an
edge.)
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import itertools
import logging
import ssl
from typing import TYPE_CHECKING

from ..config import ModbusTlsSection
from ..safety.access import AccessPolicy
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo
from ..safety.roles import Role
from ..tagmap import TagMap
from .modbus_protocol import Answer, ModbusConnection
from .modbus_requests import RequestServer
from .modbus_tls import handshake_failure, identify, server_context, server_files
from .view import ImageView

if TYPE_CHECKING:
    from pymodbus.simulator import SimData

log = logging.getLogger("motion_server.modbus")

#: seconds a frame may take from its first byte to its last
FRAME_TIMEOUT = 5.0
#: at the connection limit, a connection whose incomplete frame is this old gives way
STALLED_AFTER = 1.0
#: seconds a TLS connection being closed waits for the peer's close_notify
TLS_SHUTDOWN_TIMEOUT = 2.0

_connection_numbers = itertools.count(1)


class Listener:
    """One listening socket (plain Modbus TCP, or TLS with ``tls``) and the connections
    it holds (:attr:`active_connections`, from accept to close)."""

    def __init__(self, frontend: ModbusFrontend, tls: ssl.SSLContext | None) -> None:
        self.frontend = frontend
        self.tls = tls
        self.server: asyncio.Server | None = None
        self.active_connections: dict[int, ModbusConnection] = {}

    async def listen(self, host: str, port: int) -> None:
        loop = asyncio.get_running_loop()
        self.server = await loop.create_server(
            lambda: ModbusConnection(self, tls=self.tls is not None), host, port
        )

    @property
    def port(self) -> int:
        sockets = self.server.sockets if self.server is not None else ()
        if not sockets:
            raise RuntimeError("not listening")
        port: int = sockets[0].getsockname()[1]
        return port

    # -- Service (modbus_protocol) ------------------------------------------------------------
    def opened(self, conn: ModbusConnection) -> None:
        assert conn.transport is not None
        peer = conn.transport.get_extra_info("peername") or ("", 0)
        conn.client = ClientInfo(
            conn.client.protocol, str(peer[0]), int(peer[1]), next(_connection_numbers)
        )
        self.active_connections[conn.client.connection] = conn
        if self.frontend._admit(conn) and self.tls is not None:
            self.frontend._secure(conn, self.tls)

    def closed(self, conn: ModbusConnection) -> None:
        self.active_connections.pop(conn.client.connection, None)
        self.frontend._left(conn)

    def answer(self, conn: ModbusConnection, tid: int, unit: int, pdu: bytes) -> Answer:
        return self.frontend.handler.answer(conn.client, tid, unit, pdu)

    def bad_header(self, conn: ModbusConnection, why: str) -> None:
        self.frontend._bad_header(conn, why)

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
        for conn in list(self.active_connections.values()):
            conn.close(abort=True)
        self.active_connections.clear()
        if self.server is not None:
            await self.server.wait_closed()


class ModbusFrontend:
    """A Modbus TCP server for one image. ``await start()`` binds (port 0 picks an
    ephemeral port, see :attr:`port`); ``await stop()`` closes it. ``policy`` enforces
    ``[modbus.access]``; ``audit`` records refused writes and connections; ``tls``
    (``[modbus.tls]``, when enabled) adds the Modbus/TCP Security listener
    (:attr:`tls_port`). :attr:`server` and :attr:`tls_server` are the listeners (None
    when not listening)."""

    def __init__(
        self,
        image: ImageView,
        host: str = "127.0.0.1",
        port: int = 5020,
        unit_id: int | None = None,
        policy: AccessPolicy | None = None,
        audit: AuditLog | None = None,
        tls: ModbusTlsSection | None = None,
    ) -> None:
        self.image = image
        self.host = host
        self.requested_port = port
        self.unit_id = image.map.unit_id if unit_id is None else unit_id
        self.policy = policy
        self.audit = audit
        self.tls = tls if tls is not None and tls.enabled else None
        self.server: Listener | None = None
        self.tls_server: Listener | None = None
        #: seconds without a complete request before a connection is closed (0: never)
        self.idle_timeout = policy.idle_timeout if policy is not None else 0.0
        #: seconds a frame may take to arrive whole
        self.frame_timeout = FRAME_TIMEOUT
        #: serves the requests (and counts them)
        self.handler = RequestServer(image, self.unit_id, policy, audit)
        self.refused_connections = 0
        self.idle_closed = 0
        #: connections closed because a frame took longer than ``frame_timeout``
        self.frame_timeouts = 0
        #: connections that gave their place to a new one (a stalled frame, at the limit)
        self.evicted = 0
        #: connections closed for a header that delimits no frame
        self.bad_headers = 0
        #: TLS handshakes that failed (no certificate, another CA, too slow, ...)
        self.tls_refused = 0
        #: the admitted connections (both listeners; TLS ones from before the handshake)
        self.connections: dict[int, ModbusConnection] = {}
        self._handshakes: set[asyncio.Task[None]] = set()
        self._sweeper: asyncio.Task[None] | None = None

    async def start(self) -> None:
        try:
            if self.tls is None or not self.tls.tls_only:
                self.server = await self._listen(self.requested_port, None)
                log.info("Modbus TCP on %s:%d, unit id %d", self.host, self.port, self.unit_id)
                self._say_plain_role()
            if self.tls is not None:
                context = await self._tls_context(self.tls)
                self.tls_server = await self._listen(self.tls.port, context)
                log.info(
                    "Modbus/TCP Security (TLS) on %s:%d, unit id %d, client certificates "
                    "verified against %s",
                    self.host,
                    self.tls_port,
                    self.unit_id,
                    self.tls.ca_file,
                )
        except BaseException:
            await self.stop()
            raise
        self._sweeper = asyncio.create_task(self._sweep())

    def _say_plain_role(self) -> None:
        """One line at start: what plain Modbus TCP clients may write, and why."""
        if self.policy is None:
            return
        plain = self.policy.plain
        if plain.role == Role.ADMIN and plain.secured:
            # as the None-endpoint warning: an open door on a site that authenticates
            log.warning(
                "Modbus TCP: plain clients have role admin (%s): anyone who reaches port %d "
                "may write the Clock tags",
                plain.why,
                self.port,
            )
        elif plain.role != Role.ADMIN or plain.secured:
            log.warning("Modbus TCP: plain clients have role %s (%s)", plain.role.label, plain.why)
        else:
            log.info("Modbus TCP: plain clients have role admin (%s)", plain.why)

    async def _listen(self, port: int, tls: ssl.SSLContext | None) -> Listener:
        listener = Listener(self, tls)
        await listener.listen(self.host, port)
        return listener

    async def _tls_context(self, cfg: ModbusTlsSection) -> ssl.SSLContext:
        site = self.image.map.site
        cert, key = await server_files(
            cfg, f"{self.image.map.namespace_uri}:modbus-tls", f"motion-server {site} Modbus/TLS"
        )
        return server_context(cert, key, cfg.ca_file)

    async def stop(self) -> None:
        if self._sweeper is not None:
            self._sweeper.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._sweeper
            self._sweeper = None
        for conn in self.connections.values():
            conn.dropped = True
        for task in list(self._handshakes):
            task.cancel()
        await asyncio.gather(*self._handshakes, return_exceptions=True)
        for listener in (self.server, self.tls_server):
            if listener is not None:
                await listener.close()
        self.server = self.tls_server = None
        self.connections.clear()

    @property
    def requests(self) -> int:
        """Requests answered (complete ADUs)."""
        return self.handler.requests

    @property
    def exceptions(self) -> int:
        """Exception answers."""
        return self.handler.exceptions

    @property
    def port(self) -> int:
        """The bound TCP port of plain Modbus TCP (after :meth:`start`)."""
        return _bound_port(self.server, "Modbus TCP")

    @property
    def tls_port(self) -> int:
        """The bound TCP port of Modbus/TCP Security (after :meth:`start`)."""
        return _bound_port(self.tls_server, "Modbus/TCP Security")

    # -- connections ------------------------------------------------------------------------
    def _admit(self, conn: ModbusConnection) -> bool:
        client = conn.client
        reason = None
        if self.policy is not None:
            reason = self.policy.connection_refused(client.address)
            full = len(self.connections) >= self.policy.max_connections
            if reason is None and full and not self._evict_stalled():
                reason = f"connection limit {self.policy.max_connections} reached"
        if reason is not None:
            self.refused_connections += 1
            log.info(
                "Modbus connection from %s:%d refused: %s", client.address, client.port, reason
            )
            if self.audit is not None:
                self.audit.connection(client, "connect", "refused", reason)
            conn.close(abort=True)
            return False
        self.connections[client.connection] = conn
        return True

    def _evict_stalled(self) -> bool:
        """Close the connection whose incomplete frame began longest ago, if that was
        :data:`STALLED_AFTER` or more (True: a place was freed)."""
        now = asyncio.get_running_loop().time()
        stalled = [
            (c.partial_since, c)
            for c in self.connections.values()
            if c.partial_since is not None and c.ready and now - c.partial_since >= STALLED_AFTER
        ]
        if not stalled:
            return False
        since, victim = min(stalled, key=lambda sc: sc[0])
        self.evicted += 1
        self._drop(victim, "evicted", f"frame incomplete for {now - since:.1f} s at the limit")
        return True

    def _drop(self, conn: ModbusConnection, result: str, reason: str = "") -> None:
        """Close an admitted connection from the server's side, logged and audited."""
        client = conn.client
        log.info("Modbus connection %s closed: %s %s", client.key, result, reason)
        if self.audit is not None:
            self.audit.connection(client, "disconnect", result, reason)
        self.connections.pop(client.connection, None)
        conn.close(abort=result != "idle timeout")

    def _left(self, conn: ModbusConnection) -> None:
        self.connections.pop(conn.client.connection, None)

    def _bad_header(self, conn: ModbusConnection, why: str) -> None:
        self.bad_headers += 1
        self._drop(conn, "bad header", why)

    async def _sweep(self) -> None:
        """Close connections idle past ``idle_timeout`` and frames slower than
        ``frame_timeout``."""
        loop = asyncio.get_running_loop()
        while True:
            limits = [self.frame_timeout] + [self.idle_timeout] * (self.idle_timeout > 0)
            await asyncio.sleep(min(min(limits) / 4, 1.0))
            now = loop.time()
            for conn in list(self.connections.values()):
                if conn.busy or conn.closing:
                    continue  # a request being served (a long Clock.Step) is no silence
                since = conn.partial_since
                if since is not None and conn.ready and now - since > self.frame_timeout:
                    self.frame_timeouts += 1
                    self._drop(conn, "frame timeout", f"incomplete for {now - since:.1f} s")
                elif self.idle_timeout > 0 and now - conn.last_request > self.idle_timeout:
                    self.idle_closed += 1
                    self._drop(conn, "idle timeout")

    # -- TLS ----------------------------------------------------------------------------------
    def _secure(self, conn: ModbusConnection, context: ssl.SSLContext) -> None:
        """Start the TLS handshake of an admitted connection."""
        task = asyncio.get_running_loop().create_task(self._handshake(conn, context))
        self._handshakes.add(task)
        task.add_done_callback(self._handshakes.discard)

    async def _handshake(self, conn: ModbusConnection, context: ssl.SSLContext) -> None:
        assert self.tls is not None and conn.transport is not None
        loop = asyncio.get_running_loop()
        try:
            secure = await loop.start_tls(
                conn.transport,
                conn,
                context,
                server_side=True,
                ssl_handshake_timeout=self.tls.handshake_timeout,
                ssl_shutdown_timeout=TLS_SHUTDOWN_TIMEOUT,
            )
            if secure is None:  # closed while shaking hands
                raise ConnectionResetError("connection closed during the handshake")
            ssl_object = secure.get_extra_info("ssl_object")
            der = ssl_object.getpeercert(binary_form=True) if ssl_object is not None else None
            if not der:  # CERT_REQUIRED makes this a failed handshake already
                raise ssl.SSLError("no client certificate")
            who = identify(der, self.tls.roles, self.tls.default_role)
        except Exception as exc:
            self._handshake_failed(conn, handshake_failure(exc))
            return
        if conn.closing:
            secure.close()  # the client left, or the server closed it, meanwhile
            return
        client = dataclasses.replace(conn.client, user=who.name, role=who.role.label)
        level = logging.INFO if who.recognised else logging.WARNING
        log.log(level, "Modbus/TLS connection %s: %r, %s", client.key, who.name, who.why)
        if self.audit is not None:
            self.audit.connection(client, "connect", "accepted", who.why)
        conn.handshake_done(secure, client)

    def _handshake_failed(self, conn: ModbusConnection, reason: str) -> None:
        self._left(conn)
        if conn.tls and self.tls_server is not None:
            self.tls_server.active_connections.pop(conn.client.connection, None)
        if not conn.dropped:
            client = conn.client
            self.tls_refused += 1
            log.info(
                "Modbus/TLS connection from %s:%d refused: %s", client.address, client.port, reason
            )
            if self.audit is not None:
                self.audit.connection(client, "connect", "refused", f"TLS handshake: {reason}")
        conn.close(abort=True)


def sim_data(tagmap: TagMap) -> list[SimData]:
    """The map's register blocks as pymodbus ``SimData`` ranges (read-only status, writable
    command region, read-only tail): the same registers on a bare pymodbus server, the
    baseline ``bench/modbus_throughput.py`` measures against. The server does not use it."""
    from pymodbus.simulator import DataType, SimData

    out: list[SimData] = []
    for b in tagmap.blocks:
        parts = (
            (b.base, b.command_start, True),
            (b.command_start, b.command_end, False),
            (b.command_end, b.end, True),
        )
        for start, end, readonly in parts:
            if end > start:
                out.append(
                    SimData(
                        address=start,
                        count=end - start,
                        values=0,
                        datatype=DataType.REGISTERS,
                        readonly=readonly,
                    )
                )
    return out


def _bound_port(listener: Listener | None, what: str) -> int:
    if listener is None or listener.server is None or not listener.server.sockets:
        raise RuntimeError(f"{what} is not listening")
    return listener.port
