"""The OPC UA wire: framing, secure channels and sessions as the specification has them,
where asyncua 2.1 does not.

asyncua's connection protocol (``OPCUAProtocol``) appends every received byte to one
buffer until a chunk is complete, whatever the header announced: a header claiming
2 GiB, before any Hello, makes the server buffer all a client streams. Its secure
channel (``SecureConnection`` and ``UaProcessor``) raises a bare ``UaError`` on a wrong
sequence number, channel id or token and on a broken Hello or OpenSecureChannel; the
connection loop logs it and goes on, so the connection stays open and unanswered. It
also serves a SecureMessage sent before any OpenSecureChannel (channel 0, token 0) with
no security at all, whatever endpoints the server offers: a session, a login and writes
on a server that has no None endpoint. And it keeps an activated session, and its
subscriptions, for up to its session timeout after its connection dropped, for a client
to take it over on another channel.

This module replaces those parts without forking asyncua (subclasses only):

- :class:`GuardedProtocol` frames chunks itself (an :class:`asyncio.BufferedProtocol`
  reading into one buffer per connection, :data:`HELLO_MAX` bytes before the Hello and
  ``max_chunk_size`` after it: a connection never holds more than one chunk's worth of
  unread bytes, plus the chunk the processor is serving). Each header is
  judged as soon as its 8 bytes are in: before a Hello only a Hello of at most
  :data:`HELLO_MAX` bytes is accepted; after it, no chunk larger than ``max_chunk_size``.
- :class:`GuardedConnection` and :class:`GuardedProcessor` turn every fatal channel
  error into an Error message (ERR) with the status code Part 6 names, then the
  connection closes: :class:`ChannelFault`.
- :class:`GuardedProcessor` refuses a user name token on a channel without security
  (``BadIdentityTokenRejected``: a password never crosses the wire in clear, even
  encrypted with the server's key, since the unsigned channel carrying the session
  could be taken over), lets a session be activated only on the channel that created
  it, closes a session with its connection, closes the session a new CreateSession on
  the same channel replaces (asyncua forgets it there, and it lives on with its
  subscriptions and its activation until its timeout: 120 CreateSession, ActivateSession,
  CreateSubscription on one connection took every subscription slot of the server for a
  minute after the connection closed), and passes each request to a ``screen``
  (the operation limits, :mod:`.opcua_limits`) once its session is activated.
- :class:`WireServer` is asyncua's ``Server`` with these parts, and with no user name
  token offered on an endpoint without security.
- :class:`GuardedProcessor` also applies the communication fault the Clock tags ask for
  (``Wire.answers``, :mod:`.comm_faults`): a service request's answer delayed or dropped.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from asyncua import Server, ua
from asyncua.common.connection import SecureConnection, TransportLimits
from asyncua.common.utils import Buffer, NotEnoughData, ServiceError
from asyncua.crypto.security_policies import SecurityPolicyNone
from asyncua.crypto.uacrypto import InvalidSignature
from asyncua.server.binary_server_asyncio import BinaryServer, OPCUAProtocol
from asyncua.server.internal_server import InternalServer
from asyncua.server.internal_session import InternalSession
from asyncua.server.uaprocessor import UaProcessor
from asyncua.ua.ua_binary import header_from_binary, struct_from_binary, uatcp_to_binary
from asyncua.ua.uaerrors import BadRequestTooLarge, UaError, UaStatusCodeError

from ..tagmap import CommFault
from .comm_faults import Fault

log = logging.getLogger("motion_server.opcua")

Codes = ua.StatusCodes
HEADER = 8
#: the largest EndpointUrl of a Hello (Part 6, 7.1.2.3)
MAX_URL = 4096
#: the smallest and the largest Hello: header, five UInt32, the URL's length and bytes
HELLO_MIN = HEADER + 5 * 4 + 4
HELLO_MAX = HELLO_MIN + MAX_URL
#: the smallest chunk a peer's buffers may take (Part 6, 7.1.2.3; no ECC policy here)
MIN_BUFFER = 8192
#: a secure chunk: header, channel id, and at least a security header's first field
SECURE_MIN = HEADER + 4 + 4
#: chunk types each message type may carry (F final, C intermediate, A abort)
CHUNK_TYPES = {b"HEL": b"F", b"OPN": b"F", b"CLO": b"F", b"MSG": b"FCA"}
_ACTIVATE = ua.NodeId(ua.ObjectIds.ActivateSessionRequest_Encoding_DefaultBinary)
_CREATE = ua.NodeId(ua.ObjectIds.CreateSessionRequest_Encoding_DefaultBinary)
_WRAP = (1 << 32) - 1024  # sequence numbers wrap below 1024 after this (Part 6, 6.7.2.4)
#: after an Error message: the most bytes read and dropped, the longest wait, before closing
DRAIN_BYTES = 1 << 16
DRAIN_S = 1.0
_SCRATCH = bytearray(1 << 14)  # where dropped bytes are read (shared, never looked at)

#: exceptions of parameters that do not decode (asyncua's decoders raise them all)
DECODING: tuple[type[Exception], ...] = (
    struct.error,
    ValueError,  # an enumeration out of range; UnicodeError is one too
    IndexError,
    OverflowError,
    NotEnoughData,
    UaError,
)

#: judges one request of an activated session before asyncua serves it (raises a
#: ServiceError to answer a ServiceFault): type id, body after the request header, session
Screen = Callable[[ua.NodeId, Buffer, InternalSession], None]
#: the communication fault for an answer to the client at a TCP port (None: none)
Answers = Callable[[int], Fault | None]


class ChannelFault(Exception):
    """A fatal error of the connection or its secure channel: answered with an Error
    message carrying ``code``, then the connection closes."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code
        self.reason = reason

    @property
    def name(self) -> str:
        return ua.StatusCode(self.code).name

    def message(self) -> bytes:
        """The Error message (ERR) on the wire."""
        err = ua.ErrorMessage(ua.StatusCode(self.code), self.reason[:256])
        return uatcp_to_binary(ua.MessageType.Error, err)


@dataclass
class Wire:
    """What the guarded parts need from the front-end: the largest chunk accepted after
    the Hello, the request screen, and who hears of connections closed for a fault
    (``on_fault(peer, fault)``)."""

    max_chunk_size: int
    screen: Screen | None = None
    on_fault: Callable[[Any, ChannelFault], None] | None = None
    #: connections closed for a fault (diagnostics, tests)
    faults: int = 0
    #: the communication fault the answers of a client get (None: never any)
    answers: Answers | None = None


def judge_header(head: bytes, hello_seen: bool, max_chunk: int) -> ChannelFault | None:
    """The fault of a chunk header, or None if a chunk of that type and size may follow."""
    kind, chunk, size = head[:3], head[3:4], struct.unpack_from("<I", head, 4)[0]
    allowed = CHUNK_TYPES.get(kind)
    if allowed is None:
        return ChannelFault(Codes.BadTcpMessageTypeInvalid, f"unknown message type {kind!r}")
    if chunk not in allowed:
        return ChannelFault(Codes.BadTcpMessageTypeInvalid, f"chunk type {chunk!r} on {kind!r}")
    if not hello_seen:
        if kind != b"HEL":
            return ChannelFault(Codes.BadTcpMessageTypeInvalid, f"{kind!r} before a Hello")
        if size > HELLO_MAX:
            return ChannelFault(Codes.BadTcpMessageTooLarge, f"Hello of {size} bytes")
        if size < HELLO_MIN:
            return ChannelFault(Codes.BadDecodingError, f"Hello of {size} bytes")
        return None
    if kind == b"HEL":
        return ChannelFault(Codes.BadTcpMessageTypeInvalid, "a second Hello")
    if size > max_chunk:
        return ChannelFault(Codes.BadTcpMessageTooLarge, f"chunk of {size} bytes > {max_chunk}")
    if size < SECURE_MIN:
        return ChannelFault(Codes.BadDecodingError, f"chunk of {size} bytes")
    return None


def check_hello(body: Buffer) -> None:
    """Refuse a Hello that cannot be decoded or asks for less than the minimum buffers."""
    try:
        hello = struct_from_binary(ua.Hello, body.copy())
    except Exception as exc:
        raise ChannelFault(Codes.BadDecodingError, f"Hello: {exc}") from None
    if hello.ReceiveBufferSize < MIN_BUFFER or hello.SendBufferSize < MIN_BUFFER:
        # the OPC Foundation's ANSI C stack answers BadConnectionRejected here too
        raise ChannelFault(
            Codes.BadConnectionRejected,
            f"buffers of {hello.ReceiveBufferSize}/{hello.SendBufferSize} bytes < {MIN_BUFFER}",
        )
    url = hello.EndpointUrl
    if url is not None:
        # asyncua decodes strings with surrogateescape: bytes that are not UTF-8 arrive as
        # lone surrogates, which raised on encode (a traceback, then BadTcpInternalError)
        try:
            size = len(url.encode("utf-8"))
        except UnicodeEncodeError:
            raise ChannelFault(Codes.BadTcpEndpointUrlInvalid, "EndpointUrl is not UTF-8") from None
        if size > MAX_URL:
            raise ChannelFault(Codes.BadTcpEndpointUrlInvalid, "EndpointUrl longer than 4096 bytes")


class GuardedConnection(SecureConnection):
    """asyncua's secure channel with typed faults: a chunk for no channel or another
    channel, an unknown token, a sequence number out of order, a policy the server does
    not offer, a chunk that fails its security checks."""

    def receive_from_header_and_body(self, header: ua.Header, body: Buffer) -> Any:
        kind = header.MessageType
        if kind in (ua.MessageType.SecureMessage, ua.MessageType.SecureClose):
            if not self.is_open():
                # asyncua would serve it on channel 0 with no security at all
                raise ChannelFault(Codes.BadTcpSecureChannelUnknown, "no secure channel is open")
            if header.ChannelId != self.security_token.ChannelId:
                raise ChannelFault(
                    Codes.BadTcpSecureChannelUnknown, f"unknown channel {header.ChannelId}"
                )
        elif (
            kind == ua.MessageType.SecureOpen
            and self.is_open()
            and header.ChannelId != self.security_token.ChannelId
        ):
            raise ChannelFault(
                Codes.BadTcpSecureChannelUnknown, f"renewal of channel {header.ChannelId}"
            )
        try:
            return super().receive_from_header_and_body(header, body)
        except (ChannelFault, BadRequestTooLarge):
            raise  # asyncua's processor answers BadRequestTooLarge with an ERR itself
        except UaStatusCodeError as exc:
            raise ChannelFault(exc.code, str(exc)) from None
        except Exception as exc:  # a signature, a decryption, a header that does not decode
            raise ChannelFault(Codes.BadSecurityChecksFailed, _text(exc)) from None

    def _check_sym_header(self, security_hdr: ua.SymmetricAlgorithmHeader) -> None:
        try:
            super()._check_sym_header(security_hdr)
        except ua.UaError as exc:  # asyncua: unknown or expired token id
            raise ChannelFault(Codes.BadSecureChannelTokenUnknown, str(exc)) from None

    def _check_incoming_chunk(self, chunk: Any) -> None:
        seq = chunk.SequenceHeader.SequenceNumber
        last = self._peer_sequence_number
        if last is not None and seq != last + 1 and not (seq < 1024 and last >= _WRAP):
            reason = f"sequence number {seq} after {last}"
            raise ChannelFault(Codes.BadSequenceNumberInvalid, reason)
        super()._check_incoming_chunk(chunk)

    def select_policy(
        self, uri: str, peer_certificate: bytes | None, mode: ua.MessageSecurityMode | None = None
    ) -> None:
        try:
            super().select_policy(uri, peer_certificate, mode)
        except ua.UaError as exc:  # asyncua: "No matching policy"
            known = any(p.matches(uri) for p in self._policies)
            code = Codes.BadSecurityModeRejected if known else Codes.BadSecurityPolicyRejected
            raise ChannelFault(code, str(exc)) from None


class GuardedProcessor(UaProcessor):
    """asyncua's request processor on a :class:`GuardedConnection` (see the module
    docstring for what it refuses)."""

    def __init__(
        self, iserver: InternalServer, transport: Any, limits: TransportLimits, wire: Wire
    ) -> None:
        super().__init__(iserver, transport, limits)
        self.wire = wire
        self._connection = GuardedConnection(SecurityPolicyNone(), self._limits)
        peer = self.name
        self._port = int(peer[1]) if isinstance(peer, tuple) and len(peer) >= 2 else 0
        #: the answer of the request being served is dropped (a communication fault)
        self._dropping = False
        #: the request being served was judged on arrival (its answer is not judged again)
        self._serving = False

    async def process_message(self, seqhdr: Any, body: Buffer) -> Any:
        """A service request: answered, or its answer delayed or dropped when a
        communication fault is set for this client (decided now, as it arrives)."""
        answers = self.wire.answers
        fault = answers(self._port) if answers is not None else None
        if fault is not None and fault.mode == CommFault.DELAY:
            await asyncio.sleep(fault.delay)
        self._dropping = fault is not None and fault.mode == CommFault.DROP
        self._serving = True
        try:
            return await super().process_message(seqhdr, body)
        finally:
            self._serving = self._dropping = False

    def send_response(
        self,
        requesthandle: Any,
        seqhdr: Any,
        response: Any,
        msgtype: ua.MessageType = ua.MessageType.SecureMessage,
    ) -> None:
        if self._serving:
            if self._dropping:
                return
        elif msgtype == ua.MessageType.SecureMessage and self.wire.answers is not None:
            # sent later than its request (a Publish): judged now
            fault = self.wire.answers(self._port)
            if fault is not None:
                if fault.mode == CommFault.DROP:
                    return
                asyncio.get_running_loop().call_later(
                    fault.delay, self._send_late, requesthandle, seqhdr, response, msgtype
                )
                return
        super().send_response(requesthandle, seqhdr, response, msgtype)

    def _send_late(self, requesthandle: Any, seqhdr: Any, response: Any, msgtype: Any) -> None:
        if not self._transport.is_closing():
            UaProcessor.send_response(self, requesthandle, seqhdr, response, msgtype)

    async def process(self, header: ua.Header, body: Buffer) -> bool:
        if header.MessageType == ua.MessageType.Hello:
            check_hello(body)
        try:
            ok: bool = await super().process(header, body)
        except ChannelFault:
            raise
        except InvalidSignature as exc:
            raise ChannelFault(Codes.BadSecurityChecksFailed, _text(exc)) from None
        except Exception as exc:  # a request header that does not decode; a broken OPN
            if header.MessageType == ua.MessageType.SecureOpen:
                raise ChannelFault(Codes.BadSecurityChecksFailed, _text(exc)) from None
            raise ChannelFault(Codes.BadDecodingError, _text(exc)) from None
        return ok

    async def _process_message(
        self, typeid: ua.NodeId, requesthdr: ua.RequestHeader, seqhdr: Any, body: Buffer
    ) -> Any:
        session = self.session
        if typeid == _CREATE and session is not None:
            await self._replace(session)
        elif typeid == _ACTIVATE:
            if session is None:
                # asyncua would look the session up by its authentication token and move
                # it to this channel; here a session lives and dies with its connection
                raise ServiceError(Codes.BadSessionIdInvalid)
            if self._connection.security_policy.Mode == ua.MessageSecurityMode.None_:
                self._refuse_user_name(body)
        elif session is not None and session.is_activated() and self.wire.screen is not None:
            self.wire.screen(typeid, body, session)
        try:
            return await super()._process_message(typeid, requesthdr, seqhdr, body)
        except (ServiceError, UaStatusCodeError):
            raise  # asyncua answers them with a ServiceFault (and one line)
        except Exception as exc:
            # asyncua's process_message answers BadInternalError and logs a traceback
            # ("Error while processing message") for every exception here, above all
            # parameters that do not decode (a truncated body, an enumeration out of
            # range, an array length beyond the body); one line of ours instead
            code = Codes.BadDecodingError if isinstance(exc, DECODING) else Codes.BadInternalError
            name = ua.ObjectIdNames.get(typeid.Identifier, str(typeid)).split("_Encoding")[0]
            log.info(
                "OPC UA request from %s: %s %s (%s): %s",
                self.name,
                name,
                "does not decode" if code == Codes.BadDecodingError else "failed",
                _text(exc),
                ua.StatusCode(code).name,
            )
            log.debug("OPC UA request from %s failed", self.name, exc_info=True)
            fault = ua.ServiceFault()
            fault.ResponseHeader.ServiceResult = ua.StatusCode(code)
            self.send_response(requesthdr.RequestHandle, seqhdr, fault)
            return True

    async def _replace(self, session: InternalSession) -> None:
        """Close ``session`` (and its subscriptions) before a new CreateSession on its
        channel replaces it. asyncua's processor holds one session per channel and
        simply overwrites it, leaving the old one open, unreachable from here (an
        ActivateSession always acts on the current one), until its own timeout; and
        starts a new session watchdog without stopping the old one."""
        # asyncua leaves the attribute untyped
        watchdog: asyncio.Task[None] | None = getattr(self, "_session_watchdog_task", None)
        if watchdog is not None and not watchdog.done():
            watchdog.cancel()
        self._session_watchdog_task = None
        self.session = None
        await session.close_session(True)

    def _refuse_user_name(self, body: Buffer) -> None:
        try:
            params = struct_from_binary(ua.ActivateSessionParameters, body.copy())
        except Exception:
            return  # asyncua answers what does not decode
        token = params.UserIdentityToken
        if isinstance(token, ua.UserNameIdentityToken):
            log.warning(
                "OPC UA: login of %r from %s over a channel without security refused",
                token.UserName,
                self.name,
            )
            raise ServiceError(Codes.BadIdentityTokenRejected)

    def _should_close_session_on_transport_loss(self) -> bool:
        return True  # with its subscriptions (asyncua keeps them for the session timeout)


class GuardedProtocol(OPCUAProtocol, asyncio.BufferedProtocol):
    """One connection: frames chunks as the module docstring says and answers every
    fatal fault with an Error message before closing. ``received_at`` is the loop time
    of the last byte received.

    Bytes are read into one buffer per connection that holds at most one chunk: Hello's
    largest before the Hello, ``max_chunk_size`` after it. The first chunk's header is
    judged as soon as its 8 bytes are in (and the chunk before it is served); once the
    chunk is complete it is handed to the processor's queue; what follows it waits in
    the buffer until the processor has served it, and reading pauses when the buffer is
    full."""

    def __init__(self, *args: Any, wire: Wire, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.wire = wire
        self.received_at = 0.0
        self._buf = bytearray(HELLO_MAX)
        self._filled = 0
        #: the size announced by the header at the start of the buffer (0: not judged yet)
        self._size = 0
        self._hello_seen = False
        self._waiting = False  # a chunk is in the processor's queue or being served
        self._paused = False
        self._failed = False
        self._drain = DRAIN_BYTES

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.received_at = asyncio.get_running_loop().time()
        super().connection_made(transport)
        if self.processor is not None:
            self.processor: UaProcessor | None = GuardedProcessor(
                self.iserver, self.transport, self.limits, self.wire
            )
            self.processor.set_policies(self.policies)

    def connection_lost(self, ex: Exception | None) -> None:
        self._buf = bytearray()
        super().connection_lost(ex)

    # -- framing (asyncio.BufferedProtocol) ------------------------------------------------
    def get_buffer(self, sizehint: int) -> memoryview:
        if self._failed:
            return memoryview(_SCRATCH)
        return memoryview(self._buf)[self._filled :]  # never empty: see _frame

    def buffer_updated(self, nbytes: int) -> None:
        self.received_at = asyncio.get_running_loop().time()
        if self._failed:  # after the Error message: read what the peer had sent, then close
            self._drain -= nbytes
            if self._drain <= 0 and self.transport is not None:
                self.transport.close()
            return
        self._filled += nbytes
        self._frame()

    def _frame(self) -> None:
        """Judge the header at the start of the buffer; queue its chunk once complete,
        unless the processor has one still (waiting or being served). Reading pauses only
        when the buffer is full."""
        if self._failed:
            return
        if self._waiting:
            self._reading(self._filled < len(self._buf))
            return
        if self._filled >= HEADER and not self._size:
            head = bytes(self._buf[:HEADER])
            fault = judge_header(head, self._hello_seen, self.wire.max_chunk_size)
            if fault is not None:
                self.fail(fault)
                return
            self._size = struct.unpack_from("<I", head, 4)[0]
            if not self._hello_seen:
                self._hello_seen = True
                room = bytearray(max(self.wire.max_chunk_size, HELLO_MAX))
                room[: self._filled] = self._buf[: self._filled]
                self._buf = room  # a new buffer: the old one may still be exported
        size = self._size
        if not size or self._filled < size:
            self._reading(True)
            return
        data = bytes(self._buf[:size])
        rest = self._filled - size
        self._buf[:rest] = self._buf[size : self._filled]  # same length: no resize
        self._filled, self._size = rest, 0
        buf = Buffer(data)
        header = header_from_binary(buf)
        self.messages.put_nowait((header, buf))  # never full: one chunk waits at most
        self._waiting = True
        self._reading(self._filled < len(self._buf))

    def _reading(self, on: bool) -> None:
        transport = self.transport
        if transport is None or transport.is_closing() or on != self._paused:
            return
        self._paused = not on
        if on:
            transport.resume_reading()
        else:
            transport.pause_reading()

    def data_received(self, data: bytes) -> None:  # asyncio calls buffer_updated instead
        raise RuntimeError("GuardedProtocol receives through get_buffer/buffer_updated")

    async def _process_one_msg(self, header: Any, buf: Buffer) -> bool:
        if self.processor is None or self._failed:
            return not self._failed
        try:
            ok = await self.processor.process(header, buf)
        except ChannelFault as fault:
            self.fail(fault)
            return False
        except Exception as exc:  # one line (the stack at DEBUG): a client can repeat it
            log.warning("OPC UA: message from %s failed: %s", self.peer_name, _text(exc))
            log.debug("OPC UA: message from %s failed", self.peer_name, exc_info=True)
            self.fail(ChannelFault(Codes.BadTcpInternalError, _text(exc)))
            return False
        if not ok:
            if self.transport is not None:
                self.transport.close()
            return False
        # the next chunk is judged once this one is served (its answer goes out first)
        self._waiting = False
        self._frame()
        return True

    def fail(self, fault: ChannelFault) -> None:
        """Answer ``fault`` with an Error message and close (once). The close is graceful
        (Part 6, 7.1.5): the Error message, then end of stream; what the peer had already
        sent is read and dropped (at most :data:`DRAIN_BYTES`, for at most
        :data:`DRAIN_S`), since closing a socket with unread data resets the connection
        and can destroy the Error message on its way."""
        transport = self.transport
        if self._failed or transport is None:
            return
        self._failed = True
        self._filled = self._size = 0
        self.wire.faults += 1
        log.info("OPC UA connection %s: %s (%s): closed", self.peer_name, fault.name, fault.reason)
        if self.wire.on_fault is not None:
            self.wire.on_fault(self.peer_name, fault)
        transport.write(fault.message())
        # the peer may be gone already: asyncio's write_eof then raises OSError 107
        # (ENOTCONN) from shutdown(), out of this protocol callback, with a traceback
        with contextlib.suppress(OSError):
            if transport.can_write_eof():
                transport.write_eof()
        if self._paused:
            self._paused = False
            transport.resume_reading()  # to drain
        asyncio.get_running_loop().call_later(DRAIN_S, transport.close)


class GuardedBinaryServer(BinaryServer):
    """asyncua's listener with a :class:`GuardedProtocol` per connection."""

    def __init__(self, base: BinaryServer, wire: Wire) -> None:
        super().__init__(base.iserver, base.hostname, base.port, base.limits)
        self.wire = wire

    def _make_protocol(self) -> GuardedProtocol:
        return GuardedProtocol(
            iserver=self.iserver,
            policies=self._policies,
            clients=self.clients,
            closing_tasks=self.closing_tasks,
            limits=self.limits,
            wire=self.wire,
        )


class WireServer(Server):
    """asyncua's ``Server`` with the guarded wire. ``Server.start`` builds its listener
    in place (``self.bserver = BinaryServer(...)``, then starts it) with no hook; the
    ``bserver`` property swaps in a :class:`GuardedBinaryServer` as it is assigned."""

    def __init__(self, wire: Wire, **kwargs: Any) -> None:
        self.wire = wire
        self._guarded: GuardedBinaryServer | None = None
        super().__init__(**kwargs)

    @property
    def bserver(self) -> GuardedBinaryServer | None:
        return self._guarded

    @bserver.setter
    def bserver(self, value: BinaryServer | None) -> None:
        if value is not None and not isinstance(value, GuardedBinaryServer):
            value = GuardedBinaryServer(value, self.wire)
        self._guarded = value

    def _set_endpoints(self, policy: Any, mode: ua.MessageSecurityMode, level: int) -> None:
        super()._set_endpoints(policy, mode, level)
        if mode == ua.MessageSecurityMode.None_:
            # asyncua offers user names there (encrypted with the server's key); the
            # processor refuses them on such a channel, so do not offer them
            endpoint = self.iserver.endpoints[-1]
            endpoint.UserIdentityTokens = [
                t for t in endpoint.UserIdentityTokens if t.TokenType != ua.UserTokenType.UserName
            ]


def _text(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"
