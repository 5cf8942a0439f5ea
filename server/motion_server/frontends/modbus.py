"""Modbus TCP front-end: holding registers over a :class:`~motion_server.tagmap.TagImage`.

Built on the pymodbus 3.16 ``SimDevice``/``SimData`` API: every register block of the tag
map becomes a ``SimData`` range (the read-only parts marked ``readonly``), and one async
``action`` hook translates each request into tag-image reads and writes. Status registers
are filled on read from the image (nothing is pushed per cycle), so a read always shows
the last completed cycle.

Served: FC3 (read), FC6 and FC16 (write), FC22 (mask write) and FC23 (read/write).
Exceptions:

- 01 another function code (coils, discrete inputs, input registers);
- 02 a register outside the map, or a write that touches a read-only register;
- 03 a value the tag cannot hold (a SINT beyond -128..127, an unknown ``Clock.Mode``, a
  non-finite hand-wheel input), or a malformed count (pymodbus);
- 11 (gateway target failed to respond) a unit id other than the site's; with
  ``unit_id = 0`` every unit id is answered.

Reads show the last cycle the scan published; writes are judged here and queued for the
scan's next cycle (:class:`~.view.ImageView`); a client reads back what it wrote at once.
A write that covers only part of a 32/64-bit value changes those words: operands are
latched on the trigger's edge, so a client may write the two halves separately. A write
to ``Clock.Step`` is answered once the cycles it asked for have run (manual clock).
When the scan cannot take writes (gone, or refused this front-end) a write answers 04.
Known upstream limits: several requests pipelined in one TCP segment get only the first
answered.

Safety (``motion_server.safety``): each connection is a :class:`ClientInfo` (address,
port, a connection number); requests are served ``writing_as`` it, so watchdogs and the
audit log know who wrote. ``[modbus.access]`` (:class:`AccessPolicy`) closes connections
from networks not allowed and past ``max_connections`` at once, closes connections idle
longer than ``idle_timeout``, and refuses writes (read-only mode, per-network write
ranges) with exception 02. Accepted writes reach the audit log through the tag image's
observers; refused ones are audited here with their reason.

Modbus/TCP Security (``[modbus.tls]``, :mod:`.modbus_tls`): a second listener (port 802
by default) serves the same tag image through the same handler, action hook, access
policy, connection limit (shared) and idle timeout, inside TLS with a required client
certificate. It is pymodbus's TCP server with the handshake done per connection
(``loop.start_tls``) after the allowlist and the limit admitted it, rather than
pymodbus's ``ModbusTlsServer``: that one hands the socket to asyncio's TLS server, whose
failed handshakes reach no handler (no address to log, nothing counted, a 60 s handshake
timeout) and leave one handler each in the listener's ``active_connections`` for the
server's life. A refused handshake (no certificate, another CA, too slow) is logged and
audited with its reason; an accepted one with the certificate's subject CN as ``user``
and its role, which then limits the writes (:class:`~motion_server.safety.roles.Role`:
viewer none, operator all but ``Clock``, admin all) on top of ``[modbus.access]``.
Refused writes answer exception 02 like the other refusals. Frames are parsed as on plain
TCP (pymodbus's socket framer: the MBAP length delimits them).

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
from contextvars import ContextVar
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusIOException
from pymodbus.pdu import ExceptionResponse
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice
from pymodbus.transaction import TransactionManager

from ..config import ModbusTlsSection
from ..safety.access import AccessPolicy
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo, current_client, writing_as
from ..safety.roles import Role, RoleRegisters
from ..tagmap import AddressError, BadValueError, ReadOnlyError, TagMap
from .modbus_tls import handshake_failure, identify, server_context, server_files
from .view import ImageView, ScanUnavailable

log = logging.getLogger("motion_server.modbus")

#: function codes the front-end answers (the others get exception 01)
SERVED_FUNCTION_CODES = frozenset({3, 6, 16, 22, 23})
#: the function codes that write (audited when refused)
WRITE_FUNCTION_CODES = frozenset({5, 6, 15, 16, 22, 23})
#: the highest register + 1
ADDRESS_SPACE = 65536
#: seconds a TLS connection being closed waits for the peer's close_notify
TLS_SHUTDOWN_TIMEOUT = 2.0


def sim_data(tagmap: TagMap) -> list[SimData]:
    """One ``SimData`` range per part of every block: read-only status, writable
    command region, read-only tail. Addresses outside every block stay invalid."""
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


_connection_numbers = itertools.count(1)
#: why the request being served was refused (for the audit line of its answer)
_REASON: ContextVar[str] = ContextVar("modbus_refusal", default="")


class _Handler(ServerRequestHandler):
    """One client connection: its :class:`ClientInfo`, admission, activity, and its
    requests served on its behalf. On the TLS listener, requests wait for the handshake
    (``tls_pending``)."""

    frontend: ModbusFrontend
    client: ClientInfo
    last_activity: float
    #: a TLS connection whose handshake has not completed: nothing is served yet
    tls_pending = False
    #: closed by the server (idle, shutdown): not a refused handshake
    dropped = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)
        peer = transport.get_extra_info("peername") or ("", 0)
        tls: ssl.SSLContext | None = self.server.tls
        protocol = "modbus" if tls is None else "modbus-tls"
        self.client = ClientInfo(protocol, str(peer[0]), int(peer[1]), next(_connection_numbers))
        self.last_activity = self.loop.time()
        if tls is not None:
            # not a byte to the Modbus parser before the handshake (start_tls takes over)
            transport.pause_reading()  # type: ignore[attr-defined]
            self.tls_pending = True
        if self.frontend._admit(self) and tls is not None:
            self.frontend._secure(self, tls)

    def callback_disconnected(self, exc: Exception | None) -> None:
        super().callback_disconnected(exc)
        self.frontend._left(self)

    def callback_data(self, data: bytes, addr: tuple[Any, ...] | None = None) -> int:
        """pymodbus's handler, but an undecodable request is answered with its own
        function code (upstream answers 0x80: function code 0) and transaction id."""
        self.last_activity = self.loop.time()
        if self.tls_pending:
            return 0  # kept in the buffer until the handshake completed
        try:
            used = TransactionManager.callback_data(self, data, addr)
        except ModbusIOException as exc:
            fc = data[7] & 0x7F if len(data) > 7 else 0
            code = (
                ExcCodes.ILLEGAL_VALUE if fc in SERVED_FUNCTION_CODES else ExcCodes.ILLEGAL_FUNCTION
            )
            self.server_send(
                ExceptionResponse(
                    fc, exception_code=code, device_id=exc.dev_id, transaction=exc.transaction_id
                ),
                addr,
            )
            # skip this frame only (its MBAP length), keep what was pipelined after it
            frame = 6 + int.from_bytes(data[4:6], "big") if len(data) >= 6 else len(data)
            return min(max(frame, 1), len(data))
        if self.last_pdu:
            self.loop.call_soon(self.handle_later)
        return used

    async def handle_request(self) -> None:
        with writing_as(self.client):
            _REASON.set("")
            await super().handle_request()

    def server_send(self, pdu: Any, addr: Any) -> None:
        """Audit every exception answer to a write: ours (with the reason) and the ones
        pymodbus gives before our hook is called (read-only ranges, bad counts)."""
        audit = self.frontend.audit
        if (
            audit is not None
            and isinstance(pdu, ExceptionResponse)
            and (pdu.function_code & 0x7F) in WRITE_FUNCTION_CODES
        ):
            reason = _REASON.get() or f"exception {pdu.exception_code}"
            audit.refused(reason, function_code=pdu.function_code & 0x7F)
        super().server_send(pdu, addr)


class _Server(ModbusTcpServer):
    frontend: ModbusFrontend
    #: the TLS listener's context (None: plain Modbus TCP)
    tls: ssl.SSLContext | None = None

    def callback_new_connection(self) -> _Handler:
        handler = _Handler(self, self.trace_packet, self.trace_pdu, self.trace_connect)
        handler.frontend = self.frontend
        return handler


class ModbusFrontend:
    """A Modbus TCP server for one tag image. ``await start()`` binds (port 0 picks an
    ephemeral port, see :attr:`port`); ``await stop()`` closes it. ``policy`` enforces
    ``[modbus.access]``; ``audit`` records refused writes and connections; ``tls``
    (``[modbus.tls]``, when enabled) adds the Modbus/TCP Security listener
    (:attr:`tls_port`)."""

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
        self.server: ModbusTcpServer | None = None
        self.tls_server: ModbusTcpServer | None = None
        self.requests = 0
        self.exceptions = 0
        self.refused_connections = 0
        self.idle_closed = 0
        #: TLS handshakes that failed (no certificate, another CA, too slow, ...)
        self.tls_refused = 0
        #: the admitted connections (both listeners; TLS ones from before the handshake)
        self.connections: dict[int, _Handler] = {}
        self._roles = RoleRegisters(image.map)
        self._handshakes: set[asyncio.Task[None]] = set()
        self._idle_task: asyncio.Task[None] | None = None

    def devices(self) -> list[SimDevice]:
        devices = [
            SimDevice(id=self.unit_id, simdata=sim_data(self.image.map), action=self._action)
        ]
        if self.unit_id != 0:
            # pymodbus falls back to device 0 for unknown unit ids: answer them with 0x0B
            catch_all = SimData(0, count=ADDRESS_SPACE, values=0, datatype=DataType.REGISTERS)
            devices.append(SimDevice(id=0, simdata=[catch_all], action=self._unknown_unit))
        return devices

    async def start(self) -> None:
        try:
            if self.tls is None or not self.tls.tls_only:
                self.server = await self._listen(self.requested_port, None)
                log.info("Modbus TCP on %s:%d, unit id %d", self.host, self.port, self.unit_id)
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
        if self.policy is not None and self.policy.idle_timeout > 0:
            self._idle_task = asyncio.create_task(self._close_idle(self.policy.idle_timeout))

    async def _listen(self, port: int, tls: ssl.SSLContext | None) -> _Server:
        server = _Server(self.devices(), address=(self.host, port))
        server.frontend = self
        server.tls = tls
        await server.serve_forever(background=True)
        return server

    async def _tls_context(self, cfg: ModbusTlsSection) -> ssl.SSLContext:
        site = self.image.map.site
        cert, key = await server_files(
            cfg, f"{self.image.map.namespace_uri}:modbus-tls", f"motion-server {site} Modbus/TLS"
        )
        return server_context(cert, key, cfg.ca_file)

    async def stop(self) -> None:
        if self._idle_task is not None:
            self._idle_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._idle_task
            self._idle_task = None
        for handler in self.connections.values():
            handler.dropped = True
        for task in list(self._handshakes):
            task.cancel()
        await asyncio.gather(*self._handshakes, return_exceptions=True)
        for server in (self.server, self.tls_server):
            if server is not None:
                await server.shutdown()
        self.server = self.tls_server = None
        self.connections.clear()

    # -- connections ------------------------------------------------------------------------
    def _admit(self, handler: _Handler) -> bool:
        client = handler.client
        reason = None
        if self.policy is not None:
            reason = self.policy.connection_refused(client.address)
            if reason is None and len(self.connections) >= self.policy.max_connections:
                reason = f"connection limit {self.policy.max_connections} reached"
        if reason is not None:
            self.refused_connections += 1
            log.info(
                "Modbus connection from %s:%d refused: %s", client.address, client.port, reason
            )
            if self.audit is not None:
                self.audit.connection(client, "connect", "refused", reason)
            handler.transport.abort()  # type: ignore[attr-defined]
            return False
        self.connections[client.connection] = handler
        return True

    def _secure(self, handler: _Handler, context: ssl.SSLContext) -> None:
        """Start the TLS handshake of an admitted connection."""
        task = asyncio.get_running_loop().create_task(self._handshake(handler, context))
        self._handshakes.add(task)
        task.add_done_callback(self._handshakes.discard)

    async def _handshake(self, handler: _Handler, context: ssl.SSLContext) -> None:
        assert self.tls is not None
        loop = asyncio.get_running_loop()
        try:
            secure = await loop.start_tls(
                handler.transport,  # type: ignore[arg-type]
                handler,
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
            self._handshake_failed(handler, handshake_failure(exc))
            return
        if handler.transport is None or handler.is_closing:
            secure.close()  # the client left before we got here
            return
        handler.transport = secure
        handler.client = dataclasses.replace(handler.client, user=who.name, role=who.role.label)
        handler.tls_pending = False
        client = handler.client
        level = logging.INFO if who.recognised else logging.WARNING
        log.log(level, "Modbus/TLS connection %s: %r, %s", client.key, who.name, who.why)
        if self.audit is not None:
            self.audit.connection(client, "connect", "accepted", who.why)
        if handler.recv_buffer:  # requests sent right behind the handshake
            handler.datagram_received(b"", None)

    def _handshake_failed(self, handler: _Handler, reason: str) -> None:
        self._left(handler)
        if not handler.dropped:
            client = handler.client
            self.tls_refused += 1
            log.info(
                "Modbus/TLS connection from %s:%d refused: %s", client.address, client.port, reason
            )
            if self.audit is not None:
                self.audit.connection(client, "connect", "refused", f"TLS handshake: {reason}")
        if handler.transport is not None:
            handler.close()

    def _left(self, handler: _Handler) -> None:
        client = getattr(handler, "client", None)
        if client is not None:
            self.connections.pop(client.connection, None)

    async def _close_idle(self, timeout: float) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await asyncio.sleep(min(timeout / 4, 1.0))
            now = loop.time()
            for handler in list(self.connections.values()):
                if now - handler.last_activity > timeout:
                    handler.dropped = True
                    self.idle_closed += 1
                    log.info("Modbus connection %s idle: closed", handler.client.key)
                    if self.audit is not None:
                        self.audit.connection(handler.client, "disconnect", "idle timeout")
                    self.connections.pop(handler.client.connection, None)
                    transport = handler.transport
                    if transport is not None:
                        transport.close()

    @property
    def port(self) -> int:
        """The bound TCP port of plain Modbus TCP (after :meth:`start`)."""
        return _bound_port(self.server, "Modbus TCP")

    @property
    def tls_port(self) -> int:
        """The bound TCP port of Modbus/TCP Security (after :meth:`start`)."""
        return _bound_port(self.tls_server, "Modbus/TCP Security")

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        """pymodbus calls this after its own range and read-only checks passed."""
        self.requests += 1
        if function_code not in SERVED_FUNCTION_CODES:
            self.exceptions += 1
            _REASON.set(f"function code {function_code} not served")
            return ExcCodes.ILLEGAL_FUNCTION
        image = self.image
        what = f"{address}+{count}"
        try:
            if set_values is None:
                offset = address - start_address
                registers[offset : offset + count] = image.read_registers(address, count, False)
            else:
                client = current_client()
                if self.policy is not None:
                    reason = self.policy.write_refused(client.address, address, count)
                    if reason is not None:
                        raise PermissionError(reason)
                if client.role:  # Modbus/TCP Security: the certificate's role
                    reason = self._roles.write_refused(Role.named(client.role), address, count)
                    if reason is not None:
                        raise PermissionError(reason)
                ticket = image.write_registers(address, [int(v) for v in set_values], check=False)
                if ticket.waits:
                    await ticket.done()  # a Clock.Step: answer once its cycles ran
            return None
        except (AddressError, ReadOnlyError, PermissionError) as exc:
            log.debug("FC%d %d+%d: %s", function_code, address, count, exc)
            code = ExcCodes.ILLEGAL_ADDRESS
            reason = str(exc)
        except BadValueError as exc:
            log.info("FC%d %d+%d refused: %s", function_code, address, count, exc)
            code = ExcCodes.ILLEGAL_VALUE
            reason = str(exc)
        except ScanUnavailable as exc:
            log.warning("FC%d %d+%d: %s", function_code, address, count, exc)
            code = ExcCodes.DEVICE_FAILURE
            reason = str(exc)
        except Exception as exc:  # never let one request take the server down
            log.exception("FC%d %d+%d failed", function_code, address, count)
            code = ExcCodes.DEVICE_FAILURE
            reason = f"internal error: {type(exc).__name__}"
        self.exceptions += 1
        _REASON.set(f"{what}: {reason}")
        return code

    async def _unknown_unit(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        self.exceptions += 1
        _REASON.set(f"unknown unit id (served: {self.unit_id})")
        return ExcCodes.GATEWAY_NO_RESPONSE


def _bound_port(server: ModbusTcpServer | None, what: str) -> int:
    if server is None or server.transport is None:
        raise RuntimeError(f"{what} is not listening")
    sockets: Any = getattr(server.transport, "sockets", ())
    port: int = sockets[0].getsockname()[1]
    return port
