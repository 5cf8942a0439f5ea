"""One Modbus TCP connection: the byte stream split into ADUs by the MBAP header, every
complete ADU answered, in order, whatever the segmentation.

:class:`ModbusConnection` is an :class:`asyncio.Protocol`. Bytes are appended to
:attr:`~ModbusConnection.recv_buffer`; each complete ADU in it is handed to the
:class:`Service` (the front-end), whose answer is either the answer ADU at once (reads,
and writes that need not wait) or a coroutine that produces it (a ``Clock.Step`` answered
once its cycles ran). The answers of one received chunk go out in one write; while a
coroutine runs, nothing after its request is served (reading pauses, the rest stays in
the buffer), so answers keep the order of the requests.

Fair share: one turn serves at most :data:`REQUESTS_PER_TURN` requests of a connection.
When more complete requests wait in its buffer, the connection stops reading and takes
its next turn through ``loop.call_soon``: behind every callback already due, so the other
connections' received bytes (and the scan link) are served in between, round-robin. A
client that pipelines thousands of requests in one segment delays another client's
request by one turn, not by its whole flood.

A header that delimits no frame (protocol id other than 0, length outside 2..254) closes
the connection at once: nothing after it can be delimited. The buffer therefore holds at
most one incomplete frame (under 260 bytes) plus what one read brought while a request
was waiting; when the peer does not read its answers (the transport's write buffer above
its high-water mark) reading pauses until it does.

Times kept for the front-end's sweep: :attr:`~ModbusConnection.last_request` (the last
complete request, or the connection's start) and :attr:`~ModbusConnection.partial_since`
(when the bytes in the buffer began to arrive, None when it is empty; it counts against
the client only while the connection is :attr:`~ModbusConnection.ready`, i.e. waiting
for the client's bytes rather than the client for its answers). A connection
on the TLS listener serves nothing before its handshake completed
(:attr:`~ModbusConnection.tls_pending`): what arrives meanwhile waits in the buffer.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Coroutine
from typing import Any, Protocol

from ..safety.client import ClientInfo
from .modbus_pdu import HEADER_SIZE, HeaderError, header

log = logging.getLogger("motion_server.modbus")

#: answers written at once while serving one received chunk, at most (then the
#: transport's flow control may pause the connection)
FLUSH_BYTES = 65536
#: requests of one connection served in one turn, at most (then the other connections')
REQUESTS_PER_TURN = 16
#: what :meth:`Service.answer` returns: the answer ADU, or a coroutine producing it
Answer = bytes | Coroutine[Any, Any, bytes]


class Service(Protocol):
    """What a connection needs of the front-end."""

    def opened(self, conn: ModbusConnection) -> None:
        """A new connection (``conn.client`` set): admit it (or close it)."""

    def closed(self, conn: ModbusConnection) -> None:
        """The connection is gone (whoever closed it)."""

    def answer(self, conn: ModbusConnection, tid: int, unit: int, pdu: bytes) -> Answer:
        """The answer ADU to one request (``pdu``: function code and data)."""

    def bad_header(self, conn: ModbusConnection, why: str) -> None:
        """The connection sent a header that delimits no frame (it is being closed)."""


class ModbusConnection(asyncio.Protocol):
    """One client connection (see the module)."""

    def __init__(self, service: Service, tls: bool = False) -> None:
        self.service = service
        #: on the Modbus/TCP Security listener
        self.tls = tls
        self.transport: asyncio.Transport | None = None
        self.client = ClientInfo("modbus-tls" if tls else "modbus", "")
        self.recv_buffer = bytearray()
        self.last_request = 0.0
        self.partial_since: float | None = None
        #: a TLS connection whose handshake has not completed: nothing is served yet
        self.tls_pending = tls
        #: closed by the server (idle, shutdown, refused): not the peer's doing
        self.dropped = False
        self.closing = False
        self._loop = asyncio.get_running_loop()
        self._waiting: asyncio.Task[None] | None = None
        self._write_paused = False
        self._reading = True
        #: the next turn of a connection that had more requests than one turn serves
        self._turn: asyncio.Handle | None = None

    # -- asyncio callbacks --------------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        self.last_request = self._loop.time()
        if self.tls_pending:
            # not a byte to the parser before the handshake (start_tls takes over)
            self._pause()
        self.service.opened(self)

    def connection_lost(self, exc: Exception | None) -> None:
        self.closing = True
        if self._waiting is not None:
            self._waiting.cancel()
            self._waiting = None
        if self._turn is not None:
            self._turn.cancel()
            self._turn = None
        self.recv_buffer.clear()
        self.service.closed(self)

    def data_received(self, data: bytes) -> None:
        if self.closing:
            return
        self.recv_buffer += data
        if self.partial_since is None:
            self.partial_since = self._loop.time()
        if self.ready:
            self._serve()

    def eof_received(self) -> bool:
        return False  # close: a half-closed client gets no more answers

    def pause_writing(self) -> None:
        self._write_paused = True
        self._pause()

    def resume_writing(self) -> None:
        self._write_paused = False
        self.resume()

    # -- state --------------------------------------------------------------------------------
    @property
    def ready(self) -> bool:
        """The buffer may be served now (no handshake, wait, full peer or turn of the
        other connections in the way)."""
        return not (
            self.tls_pending
            or self._waiting is not None
            or self._write_paused
            or self.closing
            or self._turn is not None
        )

    @property
    def busy(self) -> bool:
        """A request is being served (its answer waits for the scan)."""
        return self._waiting is not None

    def handshake_done(self, transport: asyncio.Transport, client: ClientInfo) -> None:
        """The TLS handshake completed: serve over ``transport`` as ``client``."""
        self.transport = transport
        self.client = client
        self.tls_pending = False
        self._reading = True  # the TLS transport reads from the start
        if self.recv_buffer:  # requests sent right behind the handshake
            self._serve()

    def close(self, abort: bool = False) -> None:
        """Close from the server's side (answers already written go out unless ``abort``)."""
        self.dropped = True
        self.closing = True
        if self.transport is not None:
            if abort:
                self.transport.abort()
            else:
                self.transport.close()

    def resume(self) -> None:
        """Serve what waits in the buffer, then read again."""
        if not self.ready:
            return
        if self.recv_buffer:
            self._serve()
        if self.ready and not self._reading and self.transport is not None:
            self._reading = True
            self.transport.resume_reading()

    def _pause(self) -> None:
        if self._reading and self.transport is not None:
            self._reading = False
            with contextlib.suppress(RuntimeError, AttributeError):
                self.transport.pause_reading()

    # -- framing ------------------------------------------------------------------------------
    def _serve(self) -> None:
        """Answer every complete ADU in the buffer, in order."""
        buf = self.recv_buffer
        transport = self.transport
        assert transport is not None
        service = self.service
        end = len(buf)
        pos = 0
        out: list[bytes] = []
        size = 0
        served = 0
        while end - pos >= 6:
            if served == REQUESTS_PER_TURN:  # the others' turn: this one continues after
                self._pause()
                self._turn = self._loop.call_soon(self._next_turn)
                break
            try:
                tid, length = header(buf, pos)
            except HeaderError as exc:
                if out:
                    transport.write(b"".join(out))
                service.bad_header(self, str(exc))
                self.close()
                return
            stop = pos + 6 + length
            if stop > end:
                break
            unit = buf[pos + HEADER_SIZE - 1]
            pdu = bytes(buf[pos + HEADER_SIZE : stop])
            pos = stop
            served += 1
            answer = service.answer(self, tid, unit, pdu)
            if not isinstance(answer, bytes):
                # the answer waits (for the scan): nothing after it is served meanwhile
                self._waiting = self._loop.create_task(self._finish(answer))
                self._pause()
                break
            out.append(answer)
            size += len(answer)
            if size >= FLUSH_BYTES:
                transport.write(b"".join(out))
                out.clear()
                size = 0
                if self._write_paused:  # the peer does not read: neither do we
                    break
        del buf[:pos]
        if out:
            transport.write(b"".join(out))
        if pos:
            self.last_request = self._loop.time()
            self.partial_since = self.last_request if buf else None

    def _next_turn(self) -> None:
        self._turn = None
        self.resume()

    async def _finish(self, answer: Coroutine[Any, Any, bytes]) -> None:
        try:
            data = await answer
        except asyncio.CancelledError:
            raise
        except Exception:  # the front-end answers every failure itself; never a traceback out
            log.exception("Modbus connection %s: answer failed", self.client.key)
            self._waiting = None
            self.close(abort=True)
            return
        self._waiting = None
        if self.closing or self.transport is None:
            return
        self.transport.write(data)
        self.last_request = self._loop.time()
        if self.recv_buffer:  # what arrived meanwhile counts from now
            self.partial_since = self.last_request
        self.resume()
