"""OPC UA on the wire, byte by byte: Hello, a None-policy OpenSecureChannel, service
requests on that channel, and the Error message a server answers a fault with.

A test opens a :class:`RawChannel`, sends what it likes (including chunks with a wrong
channel id, token or sequence number) and reads what comes back with :meth:`error`
(an ERR message, then the end of the connection) or :meth:`response`.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import struct
from typing import Any

from asyncua import ua
from asyncua.common.connection import SecureConnection, TransportLimits
from asyncua.common.utils import Buffer
from asyncua.crypto.security_policies import SecurityPolicyNone
from asyncua.ua.ua_binary import (
    header_from_binary,
    nodeid_from_binary,
    struct_from_binary,
    struct_to_binary,
)

#: a bound on every wait: a server that neither answers nor closes fails the test
WAIT_S = 3.0


def header(kind: bytes, size: int) -> bytes:
    return kind + struct.pack("<I", size)


def hello(url: str, recv: int = 65535, send: int = 65535, max_msg: int = 0) -> bytes:
    raw = url.encode()
    body = struct.pack("<IIIII", 0, recv, send, max_msg, 0) + struct.pack("<i", len(raw))
    return header(b"HELF", 8 + len(body) + len(raw)) + body + raw


class RawChannel:
    """One TCP connection to an OPC UA server, driven by hand."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, url: str):
        self.reader, self.writer, self.url = reader, writer, url
        self.conn = SecureConnection(SecurityPolicyNone(), TransportLimits())
        self.request_id = 0
        #: the authentication token of the session last created on this channel
        self.token = ua.NodeId()

    @classmethod
    async def connect(cls, port: int, url: str, local_host: str | None = None) -> RawChannel:
        """A connection to 127.0.0.1:``port``, from ``local_host`` if given (any address
        of 127.0.0.0/8 is this machine: a second client address for the tests)."""
        local = (local_host, 0) if local_host is not None else None
        opening = asyncio.open_connection("127.0.0.1", port, local_addr=local)
        reader, writer = await asyncio.wait_for(opening, 5)
        return cls(reader, writer, url)

    def send(self, data: bytes) -> None:
        self.writer.write(data)

    async def chunk(self, wait: float = WAIT_S) -> tuple[bytes, bytes]:
        """The next chunk from the server: (8-byte header, rest), within ``wait`` seconds."""
        head = await asyncio.wait_for(self.reader.readexactly(8), wait)
        size = struct.unpack_from("<I", head, 4)[0]
        return head, await asyncio.wait_for(self.reader.readexactly(size - 8), wait)

    async def error(self) -> tuple[int, str]:
        """The Error message the server sent (status code, reason), after which the
        server must have closed the connection."""
        head, body = await self.chunk()
        assert head[:4] == b"ERRF", f"expected an Error message, got {head[:4]!r}"
        err = struct_from_binary(ua.ErrorMessage, Buffer(body))
        rest = await asyncio.wait_for(self.reader.read(), WAIT_S)  # then end of stream
        assert rest == b"", f"{len(rest)} bytes after the Error message"
        return err.Error.value, err.Reason or ""

    async def hello(self) -> None:
        self.send(hello(self.url))
        head, _ = await self.chunk()
        assert head[:4] == b"ACKF", head

    def open_request(self, policy_uri: str | None = None) -> bytes:
        req = ua.OpenSecureChannelRequest()
        req.Parameters.ClientProtocolVersion = 0
        req.Parameters.RequestType = ua.SecurityTokenRequestType.Issue
        req.Parameters.SecurityMode = ua.MessageSecurityMode.None_
        req.Parameters.ClientNonce = b""
        req.Parameters.RequestedLifetime = 600_000
        self.request_id += 1
        data = self.conn.message_to_binary(
            struct_to_binary(req), ua.MessageType.SecureOpen, request_id=self.request_id
        )
        if policy_uri is not None:  # the policy URI is the first field after the header
            old = SecurityPolicyNone.URI.encode()
            new = policy_uri.encode()
            data = data.replace(
                struct.pack("<i", len(old)) + old, struct.pack("<i", len(new)) + new
            )
            data = data[:4] + struct.pack("<I", len(data)) + data[8:]
        return data

    async def open(self) -> None:
        """Hello, then a None-policy OpenSecureChannel (the channel discovery uses)."""
        await self.hello()
        self.send(self.open_request())
        head, rest = await self.chunk()
        assert head[:4] == b"OPNF", head
        buf = Buffer(head + rest)
        msg = self.conn.receive_from_header_and_body(header_from_binary(buf), buf)
        response = struct_from_binary(ua.OpenSecureChannelResponse, msg.body())
        self.conn.set_channel(response.Parameters, ua.SecurityTokenRequestType.Issue, b"")

    def request(self, request: Any) -> bytes:
        """``request`` (or its encoding) as the next chunk(s) on the channel (right ids,
        next sequence number)."""
        self.request_id += 1
        body = request if isinstance(request, bytes) else struct_to_binary(request)
        return self.conn.message_to_binary(
            body, ua.MessageType.SecureMessage, request_id=self.request_id
        )

    def get_endpoints(self) -> bytes:
        req = ua.GetEndpointsRequest()
        req.Parameters.EndpointUrl = self.url
        return self.request(req)

    async def response(self, kind: type) -> Any:
        head, rest = await self.chunk()
        assert head[:4] == b"MSGF", head
        buf = Buffer(head + rest)
        msg = self.conn.receive_from_header_and_body(header_from_binary(buf), buf)
        return struct_from_binary(kind, msg.body())

    async def service_result(self, wait: float = WAIT_S) -> int:
        """The service result of the next response (a ServiceFault or any response)."""
        head, rest = await self.chunk(wait)
        assert head[:4] == b"MSGF", head
        buf = Buffer(head + rest)
        msg = self.conn.receive_from_header_and_body(header_from_binary(buf), buf)
        body = msg.body()
        nodeid_from_binary(body)  # the response's type
        return int(struct_from_binary(ua.ResponseHeader, body).ServiceResult.value)

    async def call(self, request: Any, wait: float = WAIT_S) -> int:
        """Send ``request`` on the current session (its token set); its service result."""
        request.RequestHeader.AuthenticationToken = self.token
        self.send(self.request(request))
        return await self.service_result(wait)

    async def create_session(self) -> None:
        """CreateSession on this channel (asyncua's client would close the last one)."""
        create = ua.CreateSessionRequest()
        create.Parameters.ClientDescription = ua.ApplicationDescription(
            ApplicationUri="urn:raw", ApplicationType=ua.ApplicationType.Client
        )
        create.Parameters.EndpointUrl = self.url
        create.Parameters.ClientNonce = os.urandom(32)
        create.Parameters.RequestedSessionTimeout = 60_000
        self.send(self.request(create))
        session = await self.response(ua.CreateSessionResponse)
        assert session.ResponseHeader.ServiceResult.is_good(), session.ResponseHeader
        self.token = session.Parameters.AuthenticationToken

    async def anonymous_session(self) -> int:
        """CreateSession, then ActivateSession as anonymous: the activation's result."""
        await self.create_session()
        activate = ua.ActivateSessionRequest()
        activate.Parameters.UserIdentityToken = ua.AnonymousIdentityToken(PolicyId="anonymous")
        return await self.call(activate)

    async def create_subscription(self) -> int:
        """CreateSubscription (1 s publishing) on the current session: its result."""
        request = ua.CreateSubscriptionRequest()
        request.Parameters.RequestedPublishingInterval = 1000.0
        request.Parameters.RequestedLifetimeCount = 600
        request.Parameters.RequestedMaxKeepAliveCount = 20
        request.Parameters.PublishingEnabled = True
        return await self.call(request)

    async def close(self) -> None:
        self.writer.close()
        with contextlib.suppress(OSError, ConnectionError):
            await self.writer.wait_closed()


def patch(
    chunk: bytes, channel: int | None = None, token: int | None = None, seq: int | None = None
) -> bytes:
    """A None-policy MSG chunk with its channel id, token id or sequence number replaced
    (they are in clear: header 8, channel 4, token 4, sequence 4, request 4)."""
    out = bytearray(chunk)
    for offset, value in ((8, channel), (12, token), (16, seq)):
        if value is not None:
            struct.pack_into("<I", out, offset, value)
    return bytes(out)
