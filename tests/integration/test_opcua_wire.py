"""The OPC UA wire under hostile input (real sockets, byte by byte).

Every fatal fault of the connection or its secure channel is answered with an Error
message (ERR) carrying the status code OPC 10000-6 (7.1.5, 6.7) names, and the server
then closes the connection: a header announcing more than a Hello can be before the
Hello, or more than ``max_chunk_size`` after it; a message other than Hello first; a
broken Hello or OpenSecureChannel; a chunk for no channel, another channel, an unknown
token or with a sequence number out of order. Nothing of such a connection is served:
in particular no session on a channel that was never opened.

A user name and password is refused on a channel without security
(``BadIdentityTokenRejected``, OPC 10000-4 5.7.3 Table 18), whether or not the site
offers the None endpoint, and that endpoint offers no user name token. A session ends
with its connection, and its subscriptions with it.
"""

from __future__ import annotations

import asyncio
import os
import struct
import time
from collections.abc import AsyncIterator
from pathlib import Path

import pytest
import pytest_asyncio
from asyncua import ua

from motion_server.config import OpcUaSection
from motion_server.runtime import Runtime
from tests.opcua_raw import RawChannel, header, hello, patch
from tests.opcua_support import USERS, opcua_site, running, secure_client, user_hashes

pytestmark = pytest.mark.asyncio(loop_scope="module")
Codes = ua.StatusCodes
CHUNK = OpcUaSection().max_chunk_size  # the test site keeps the default


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    site = opcua_site(tmp_path_factory.mktemp("opcua"), user_hashes(), lockout=0.0)
    async with running(site) as runtime:
        yield runtime


async def raw(rt: Runtime) -> RawChannel:
    assert rt.opcua is not None
    return await RawChannel.connect(rt.opcua.port, rt.opcua.endpoint)


# -- framing ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("first", "code"),
    [
        # a lying header before any Hello: refused on its 8 bytes, nothing buffered
        (header(b"MSGF", 0x7FFFFFFF), Codes.BadTcpMessageTypeInvalid),
        (header(b"HELF", 0x7FFFFFFF), Codes.BadTcpMessageTooLarge),
        (header(b"HELF", 8 + 5 * 4 + 4 + 4096 + 1), Codes.BadTcpMessageTooLarge),
        (header(b"OPNF", 200), Codes.BadTcpMessageTypeInvalid),
        (header(b"XYZF", 16), Codes.BadTcpMessageTypeInvalid),
        (header(b"HELC", 40), Codes.BadTcpMessageTypeInvalid),
        (header(b"HELF", 8), Codes.BadDecodingError),
    ],
)
async def test_a_first_header_that_is_not_a_hello_is_refused_at_once(
    rt: Runtime, first: bytes, code: int
) -> None:
    ch = await raw(rt)
    ch.send(first)
    assert (await ch.error())[0] == code


async def test_a_header_beyond_max_chunk_size_after_the_hello_is_refused(rt: Runtime) -> None:
    for size in (CHUNK + 1, 0x7FFFFFFF, 0xFFFFFFFF):
        ch = await raw(rt)
        await ch.hello()
        ch.send(header(b"MSGF", size))
        assert (await ch.error())[0] == Codes.BadTcpMessageTooLarge


async def test_a_stream_behind_a_lying_header_is_cut_after_its_header(rt: Runtime) -> None:
    """The server closes after the 8-byte header: a 64 MiB stream cannot get through."""
    ch = await raw(rt)
    ch.send(header(b"MSGF", 0x7FFFFFFF))
    sent = 0
    block = os.urandom(1 << 16)
    with pytest.raises(ConnectionError):
        while sent < 64 << 20:
            ch.send(block)
            await ch.writer.drain()
            sent += len(block)
    # what the kernel buffers on both sides, never the stream
    assert sent < 16 << 20


async def test_requests_pipelined_in_one_segment_are_all_answered_in_order(
    rt: Runtime,
) -> None:
    """Framing holds one chunk's worth of bytes at a time, but loses none: 20 requests
    in one send (and a request split into 1-byte sends) are all answered, in order."""
    ch = await raw(rt)
    await ch.open()
    reqs = []
    for i in range(20):
        req = ua.GetEndpointsRequest()
        req.RequestHeader.RequestHandle = 1000 + i
        req.Parameters.EndpointUrl = ch.url
        reqs.append(ch.request(req))
    ch.send(b"".join(reqs))
    handles = [
        (await ch.response(ua.GetEndpointsResponse)).ResponseHeader.RequestHandle for _ in reqs
    ]
    assert handles == [1000 + i for i in range(20)]
    one = ch.get_endpoints()
    for k in range(len(one)):
        ch.send(one[k : k + 1])
        await ch.writer.drain()
    assert (await ch.response(ua.GetEndpointsResponse)).Endpoints
    await ch.close()


# -- Hello --------------------------------------------------------------------------------------
async def test_broken_hellos_are_answered_with_an_error(rt: Runtime) -> None:
    assert rt.opcua is not None
    url = rt.opcua.endpoint
    good = hello(url)
    truncated_url = good[:28] + struct.pack("<i", 5000) + good[32:]  # URL longer than the body
    cases = [
        (hello(url, recv=1024), Codes.BadConnectionRejected),  # buffers below 8192 bytes
        (hello(url, send=0), Codes.BadConnectionRejected),
        (truncated_url, Codes.BadDecodingError),
        (good + good, Codes.BadTcpMessageTypeInvalid),  # a second Hello
    ]
    for data, code in cases:
        ch = await raw(rt)
        ch.send(data)
        if data == good + good:
            head, _ = await ch.chunk()
            assert head[:4] == b"ACKF"
        assert (await ch.error())[0] == code, data[:40]


# -- OpenSecureChannel --------------------------------------------------------------------------
async def test_broken_open_secure_channel_requests_are_answered_with_an_error(
    rt: Runtime,
) -> None:
    ch = await raw(rt)
    await ch.hello()
    ch.send(ch.open_request("http://opcfoundation.org/UA/SecurityPolicy#Nonsense"))
    assert (await ch.error())[0] == Codes.BadSecurityPolicyRejected

    ch = await raw(rt)
    await ch.hello()
    good = ch.open_request()
    ch.send(good[:-20] + b"\xff" * 20)  # the request body cut short by garbage
    assert (await ch.error())[0] == Codes.BadSecurityChecksFailed

    ch = await raw(rt)
    await ch.hello()
    ch.send(header(b"OPNF", 12) + b"\x00\x00\x00\x00")  # no security header at all
    assert (await ch.error())[0] == Codes.BadDecodingError


# -- secure messages ------------------------------------------------------------------------------
async def test_a_message_before_any_secure_channel_is_refused(rt: Runtime) -> None:
    """asyncua served it on channel 0 with no security: here a CreateSession (or any
    service) on a connection that never opened a channel is an ERR."""
    ch = await raw(rt)
    await ch.hello()
    req = ua.CreateSessionRequest()
    req.Parameters.ClientNonce = os.urandom(32)
    req.Parameters.RequestedSessionTimeout = 10_000
    ch.send(ch.request(req))
    assert (await ch.error())[0] == Codes.BadTcpSecureChannelUnknown


@pytest.mark.parametrize(
    ("fault", "code"),
    [
        ("sequence", Codes.BadSequenceNumberInvalid),
        ("repeated sequence", Codes.BadSequenceNumberInvalid),
        ("channel", Codes.BadTcpSecureChannelUnknown),
        ("token", Codes.BadSecureChannelTokenUnknown),
    ],
)
async def test_a_chunk_with_a_wrong_id_or_sequence_number_ends_the_channel(
    rt: Runtime, fault: str, code: int
) -> None:
    ch = await raw(rt)
    await ch.open()
    ch.send(ch.get_endpoints())  # a good request first: the channel works
    endpoints = await ch.response(ua.GetEndpointsResponse)
    assert endpoints.Endpoints
    chunk = ch.get_endpoints()
    token = ch.conn.security_token
    seq = struct.unpack_from("<I", chunk, 16)[0]
    bad = {
        "sequence": patch(chunk, seq=seq + 5),
        "repeated sequence": patch(chunk, seq=seq - 1),
        "channel": patch(chunk, channel=token.ChannelId + 1),
        "token": patch(chunk, token=token.TokenId + 1),
    }[fault]
    ch.send(bad)
    assert (await ch.error())[0] == code


# -- user names need a secure channel --------------------------------------------------------------
async def activate_over_none(rt: Runtime, user: str) -> int:
    """CreateSession and ActivateSession with a clear-text password on a None channel;
    the ActivateSession's service result."""
    ch = await raw(rt)
    try:
        await ch.open()
        create = ua.CreateSessionRequest()
        create.Parameters.ClientDescription = ua.ApplicationDescription(
            ApplicationUri="urn:raw", ApplicationType=ua.ApplicationType.Client
        )
        create.Parameters.EndpointUrl = ch.url
        create.Parameters.ClientNonce = os.urandom(32)
        create.Parameters.RequestedSessionTimeout = 10_000
        ch.send(ch.request(create))
        session = await ch.response(ua.CreateSessionResponse)
        assert session.ResponseHeader.ServiceResult.is_good()
        activate = ua.ActivateSessionRequest()
        activate.RequestHeader.AuthenticationToken = session.Parameters.AuthenticationToken
        activate.Parameters.UserIdentityToken = ua.UserNameIdentityToken(
            PolicyId="username", UserName=user, Password=USERS[user][1].encode()
        )
        ch.send(ch.request(activate))
        return await ch.service_result()
    finally:
        await ch.close()


async def test_a_password_over_a_channel_without_security_is_refused(rt: Runtime) -> None:
    await refuses_a_password_over_none(rt, none_endpoint=False)


async def test_a_password_over_the_none_endpoint_is_refused(tmp_path: Path) -> None:
    site = opcua_site(tmp_path / "opcua", user_hashes(), none_endpoint=True)
    async with running(site) as rt:
        await refuses_a_password_over_none(rt, none_endpoint=True)


async def refuses_a_password_over_none(rt: Runtime, none_endpoint: bool) -> None:
    assert await activate_over_none(rt, "admin") == Codes.BadIdentityTokenRejected
    # the None endpoint, where there is one, offers no user name token
    ch = await raw(rt)
    await ch.open()
    ch.send(ch.get_endpoints())
    endpoints = (await ch.response(ua.GetEndpointsResponse)).Endpoints
    await ch.close()
    modes = {e.SecurityMode for e in endpoints}
    assert (ua.MessageSecurityMode.None_ in modes) == none_endpoint
    for e in endpoints:
        kinds = {t.TokenType for t in e.UserIdentityTokens}
        if e.SecurityMode == ua.MessageSecurityMode.None_:
            assert ua.UserTokenType.UserName not in kinds
        else:
            assert ua.UserTokenType.UserName in kinds


# -- sessions --------------------------------------------------------------------------------
async def test_a_sessions_subscriptions_go_when_its_connection_drops(
    rt: Runtime, tmp_path: Path
) -> None:
    """asyncua kept the session and its subscriptions (and their slots) for the session
    timeout, up to 600 s, for a client to take them over on another channel."""
    assert rt.opcua is not None and rt.opcua.server is not None
    subs = rt.opcua.server.iserver.subscription_service.subscriptions
    before = len(subs)
    client = await secure_client(rt, tmp_path, "viewer")
    await client.connect()
    await client.create_subscription(100, None)
    await client.create_subscription(100, None)
    assert len(subs) == before + 2
    client.disconnect_socket()  # no CloseSession: the connection is simply gone
    deadline = time.monotonic() + 2.0
    while len(subs) > before and time.monotonic() < deadline:
        await asyncio.sleep(0.02)
    assert len(subs) == before
