"""A front-end's end of its write queue to the scan (asyncio).

:meth:`ScanLink.send` hands a judged batch to the scan without waiting (one packet, or
fragments, on a ``SOCK_SEQPACKET`` socket) and returns a :class:`Ticket`; the scan
acknowledges every batch once the image shows it (and, for a ``Clock.Step``, once its
cycles ran). A front-end awaits the ticket only where the protocol answer must wait.

Flow control: the scan applies only a budget of writes per cycle, the rest waits
(:mod:`motion_server.scan.writes`). A client (connection) may have
:data:`IN_FLIGHT_PER_CLIENT` batches unacknowledged; the ticket of one more says it
``waits``, so its answer waits for the scan and a client that writes faster than its
share of the budget is slowed down to it, instead of piling up a queue that the scan
would work through long after.
"""

from __future__ import annotations

import asyncio
import logging
import os
import socket
from collections import deque
from typing import Protocol

from ..image import wire
from ..safety.client import ClientInfo
from ..tagmap import TagAccessError

log = logging.getLogger("motion_server.frontends")

#: how long a front-end waits for the scan's WELCOME
CONNECT_TIMEOUT = 30.0
#: batches of one client the scan has not acknowledged, beyond which the answer to the
#: client's next write waits for the scan to apply it
IN_FLIGHT_PER_CLIENT = 8
_SEQ_MASK = 0xFFFFFFFF


class ScanUnavailable(TagAccessError):
    """The scan does not take writes (it is stopping, or gone)."""


class WriteRefused(TagAccessError):
    """The scan refused a write the answer waited for, or the command it carried failed
    (a snapshot): the reason is in the server's log."""


class Ticket:
    """One batch on its way to the scan."""

    __slots__ = ("_future", "ack", "client", "seq", "waits")

    def __init__(self, seq: int, client: str = "") -> None:
        self.seq = seq
        #: the key of the client that wrote it
        self.client = client
        #: the protocol answer waits for the acknowledgement (a Clock.Step; a client with
        #: too many writes in flight)
        self.waits = False
        self.ack: wire.Ack | None = None
        self._future: asyncio.Future[wire.Ack] | None = None

    def _resolve(self, ack: wire.Ack) -> None:
        self.ack = ack
        if self._future is not None and not self._future.done():
            self._future.set_result(ack)

    def _fail(self, exc: BaseException) -> None:
        if self._future is not None and not self._future.done():
            self._future.set_exception(exc)
            self._future.exception()  # retrieved: no "never retrieved" warning

    async def done(self) -> wire.Ack:
        """The scan's acknowledgement (the image shows the write)."""
        if self.ack is not None:
            return self.ack
        if self._future is None:
            self._future = asyncio.get_running_loop().create_future()
        return await self._future


class Link(Protocol):
    """What a view needs of its link: send a batch, say whether it is broken."""

    broken: str

    def send(self, items: list[tuple[int, float]], client: ClientInfo) -> Ticket: ...


class ScanLink:
    """``await connect()`` says HELLO; then :meth:`send` batches; :meth:`close` at the end."""

    def __init__(self, sock: socket.socket, channel: int, fingerprint: int) -> None:
        sock.setblocking(False)
        self.sock = sock
        self.channel = channel
        self.fingerprint = fingerprint
        self._seq = 0
        self._tickets: dict[int, Ticket] = {}
        #: client key -> its batches not acknowledged yet
        self._in_flight: dict[str, int] = {}
        self._outbox: deque[bytes] = deque()
        self._welcome: asyncio.Future[int] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._writing = False
        self.broken: str = ""

    @property
    def seq(self) -> int:
        """The sequence number of the last batch sent."""
        return self._seq

    async def connect(self, timeout: float = CONNECT_TIMEOUT) -> None:
        loop = asyncio.get_running_loop()
        self._loop = loop
        self._welcome = loop.create_future()
        loop.add_reader(self.sock.fileno(), self._readable)
        self._send(wire.encode_hello(self.channel, os.getpid(), self.fingerprint))
        try:
            applied = await asyncio.wait_for(self._welcome, timeout)
        except TimeoutError:
            raise ScanUnavailable("the scan did not answer") from None
        self._seq = applied & _SEQ_MASK

    def close(self) -> None:
        if self._loop is not None:
            self._loop.remove_reader(self.sock.fileno())
            if self._writing:
                self._loop.remove_writer(self.sock.fileno())
        self._fail_all(ScanUnavailable("the front-end is closing"))

    def send(self, items: list[tuple[int, float]], client: ClientInfo) -> Ticket:
        """Queue a batch of (slot, value) for the scan's next cycle."""
        if self.broken:
            raise ScanUnavailable(f"the scan is not reachable ({self.broken})")
        self._seq = (self._seq + 1) & _SEQ_MASK or 1
        ticket = Ticket(self._seq, client.key)
        self._tickets[ticket.seq] = ticket
        n = self._in_flight.get(ticket.client, 0) + 1
        self._in_flight[ticket.client] = n
        ticket.waits = n > IN_FLIGHT_PER_CLIENT
        for packet in wire.encode_batch(wire.Batch(ticket.seq, client, items)):
            self._send(packet)
        return ticket

    # -- socket -----------------------------------------------------------------------------
    def _send(self, packet: bytes) -> None:
        if self._outbox:
            self._outbox.append(packet)
            return
        try:
            self.sock.send(packet)
        except BlockingIOError:
            self._outbox.append(packet)
            self._want_write()
        except OSError as exc:
            self._break(str(exc))

    def _want_write(self) -> None:
        if not self._writing and self._loop is not None:
            self._loop.add_writer(self.sock.fileno(), self._writable)
            self._writing = True

    def _writable(self) -> None:
        while self._outbox:
            try:
                self.sock.send(self._outbox[0])
            except BlockingIOError:
                return
            except OSError as exc:
                self._break(str(exc))
                return
            self._outbox.popleft()
        if self._writing and self._loop is not None:
            self._loop.remove_writer(self.sock.fileno())
            self._writing = False

    def _readable(self) -> None:
        while True:
            try:
                data = self.sock.recv(1 << 16)
            except BlockingIOError:
                return
            except OSError as exc:
                self._break(str(exc))
                return
            if not data:
                # the scan ended, stopped or died: the supervisor says which, in one line
                self._break("the scan closed the channel", logging.DEBUG)
                return
            try:
                self._packet(data)
            except (wire.WireError, ValueError) as exc:
                log.warning("a malformed packet from the scan: %s", exc)

    def _packet(self, data: bytes) -> None:
        kind, _, _ = wire.header(data)
        welcome = self._welcome
        if kind == wire.Kind.ACK:
            if welcome is not None and not welcome.done():
                return  # addressed to a front-end that ran here before
            ack = wire.decode_ack(data)
            ticket = self._tickets.pop(ack.seq, None)
            if ticket is not None:
                self._landed(ticket)
                ticket._resolve(ack)
        elif kind == wire.Kind.WELCOME:
            if welcome is not None and not welcome.done():
                welcome.set_result(int(wire.decode_text(data) or 0))
        elif kind == wire.Kind.REFUSED:
            reason = wire.decode_text(data)
            self._break(f"refused: {reason}")
            if welcome is not None and not welcome.done():
                welcome.set_exception(ScanUnavailable(f"the scan refused this front-end: {reason}"))

    def _break(self, why: str, level: int = logging.ERROR) -> None:
        if not self.broken:
            self.broken = why
            log.log(level, "link to the scan lost: %s", why)
        if self._loop is not None:
            self._loop.remove_reader(self.sock.fileno())
        self._fail_all(ScanUnavailable(why))

    def _landed(self, ticket: Ticket) -> None:
        n = self._in_flight.get(ticket.client, 0) - 1
        if n > 0:
            self._in_flight[ticket.client] = n
        else:
            self._in_flight.pop(ticket.client, None)

    def _fail_all(self, exc: BaseException) -> None:
        self._in_flight.clear()
        tickets, self._tickets = self._tickets, {}
        for t in tickets.values():
            t._fail(exc)
