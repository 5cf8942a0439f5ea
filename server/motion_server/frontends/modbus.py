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

A write that covers only part of a 32/64-bit value changes those words: operands are
latched on the trigger's edge, so a client may write the two halves separately. A write
to ``Clock.Step`` is answered once the cycles it asked for have run (manual clock).
Known upstream limits: several requests pipelined in one TCP segment get only the first
answered.

Safety (``motion_server.safety``): each connection is a :class:`ClientInfo` (address,
port, a connection number); requests are served ``writing_as`` it, so watchdogs and the
audit log know who wrote. ``[modbus.access]`` (:class:`AccessPolicy`) closes connections
from networks not allowed and past ``max_connections`` at once, closes connections idle
longer than ``idle_timeout``, and refuses writes (read-only mode, per-network write
ranges) with exception 02. Accepted writes reach the audit log through the tag image's
observers; refused ones are audited here with their reason.

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
import itertools
import logging
from contextvars import ContextVar
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusIOException
from pymodbus.pdu import ExceptionResponse
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice
from pymodbus.transaction import TransactionManager

from ..safety.access import AccessPolicy
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo, current_client, writing_as
from ..tagmap import AddressError, BadValueError, ReadOnlyError, TagImage, TagMap

log = logging.getLogger("motion_server.modbus")

#: function codes the front-end answers (the others get exception 01)
SERVED_FUNCTION_CODES = frozenset({3, 6, 16, 22, 23})
#: the function codes that write (audited when refused)
WRITE_FUNCTION_CODES = frozenset({5, 6, 15, 16, 22, 23})
#: the highest register + 1
ADDRESS_SPACE = 65536


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
    requests served on its behalf."""

    frontend: ModbusFrontend
    client: ClientInfo
    last_activity: float

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)
        peer = transport.get_extra_info("peername") or ("", 0)
        self.client = ClientInfo("modbus", str(peer[0]), int(peer[1]), next(_connection_numbers))
        self.last_activity = self.loop.time()
        self.frontend._admit(self)

    def callback_disconnected(self, exc: Exception | None) -> None:
        super().callback_disconnected(exc)
        self.frontend._left(self)

    def callback_data(self, data: bytes, addr: tuple[Any, ...] | None = None) -> int:
        """pymodbus's handler, but an undecodable request is answered with its own
        function code (upstream answers 0x80: function code 0) and transaction id."""
        self.last_activity = self.loop.time()
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

    def callback_new_connection(self) -> _Handler:
        handler = _Handler(self, self.trace_packet, self.trace_pdu, self.trace_connect)
        handler.frontend = self.frontend
        return handler


class ModbusFrontend:
    """A Modbus TCP server for one tag image. ``await start()`` binds (port 0 picks an
    ephemeral port, see :attr:`port`); ``await stop()`` closes it. ``policy`` enforces
    ``[modbus.access]``; ``audit`` records refused writes and connections."""

    def __init__(
        self,
        image: TagImage,
        host: str = "127.0.0.1",
        port: int = 5020,
        unit_id: int | None = None,
        policy: AccessPolicy | None = None,
        audit: AuditLog | None = None,
    ) -> None:
        self.image = image
        self.host = host
        self.requested_port = port
        self.unit_id = image.map.unit_id if unit_id is None else unit_id
        self.policy = policy
        self.audit = audit
        self.server: ModbusTcpServer | None = None
        self.requests = 0
        self.exceptions = 0
        self.refused_connections = 0
        self.idle_closed = 0
        #: the admitted connections
        self.connections: dict[int, _Handler] = {}
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
        server = _Server(self.devices(), address=(self.host, self.requested_port))
        server.frontend = self
        self.server = server
        await server.serve_forever(background=True)
        if self.policy is not None and self.policy.idle_timeout > 0:
            self._idle_task = asyncio.create_task(self._close_idle(self.policy.idle_timeout))
        log.info("Modbus TCP on %s:%d, unit id %d", self.host, self.port, self.unit_id)

    async def stop(self) -> None:
        if self._idle_task is not None:
            self._idle_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._idle_task
            self._idle_task = None
        if self.server is not None:
            await self.server.shutdown()
            self.server = None
        self.connections.clear()

    # -- connections ------------------------------------------------------------------------
    def _admit(self, handler: _Handler) -> None:
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
            return
        self.connections[client.connection] = handler

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
        """The bound TCP port (after :meth:`start`)."""
        if self.server is None or self.server.transport is None:
            raise RuntimeError("the Modbus server is not listening")
        sockets: Any = getattr(self.server.transport, "sockets", ())
        port: int = sockets[0].getsockname()[1]
        return port

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
                if self.policy is not None:
                    reason = self.policy.write_refused(current_client().address, address, count)
                    if reason is not None:
                        raise PermissionError(reason)
                if image.write_registers(address, [int(v) for v in set_values], check=False):
                    await image.settle()  # a Clock.Step: answer once its cycles ran
            return None
        except (AddressError, ReadOnlyError, PermissionError) as exc:
            log.debug("FC%d %d+%d: %s", function_code, address, count, exc)
            code = ExcCodes.ILLEGAL_ADDRESS
            reason = str(exc)
        except BadValueError as exc:
            log.info("FC%d %d+%d refused: %s", function_code, address, count, exc)
            code = ExcCodes.ILLEGAL_VALUE
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
