"""What a hostile OPC UA client leaves in the log: one line per refused message, no
traceback, and not more than ``opcua_log.LINES`` lines per ``opcua_log.WINDOW_S`` seconds
(real sockets, raw requests on an anonymous session).

asyncua logged a traceback ("Error while processing message") for every request whose
parameters do not decode, and a Hello whose EndpointUrl is not UTF-8 raised inside the
front-end (a traceback, then ``BadTcpInternalError``).
"""

from __future__ import annotations

import asyncio
import logging
import struct
from collections.abc import AsyncIterator

import pytest
import pytest_asyncio
from asyncua import ua
from asyncua.ua.ua_binary import struct_to_binary

from motion_server.frontends import opcua_log
from motion_server.runtime import Runtime
from tests.opcua_raw import RawChannel, header
from tests.opcua_support import opcua_site, running, user_hashes

pytestmark = pytest.mark.asyncio(loop_scope="module")
Codes = ua.StatusCodes
#: TimestampsToReturn is an enumeration of 0..4 (OPC 10000-4, 7.40): 7 does not decode
BAD_TIMESTAMPS = 7


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    site = opcua_site(
        tmp_path_factory.mktemp("opcua"), user_hashes(), anonymous=True, none_endpoint=True
    )
    async with running(site) as runtime:
        yield runtime


async def session(rt: Runtime) -> RawChannel:
    assert rt.opcua is not None
    ch = await RawChannel.connect(rt.opcua.port, rt.opcua.endpoint)
    await ch.open()
    assert await ch.anonymous_session() == Codes.Good
    return ch


def read_request(ch: RawChannel, timestamps: int) -> bytes:
    """A Read of Clock.Cycle with ``timestamps`` as its TimestampsToReturn, encoded."""
    assert ch.token is not None
    request = ua.ReadRequest()
    request.RequestHeader.AuthenticationToken = ch.token
    request.Parameters.TimestampsToReturn = ua.TimestampsToReturn.Both
    request.Parameters.NodesToRead = [
        ua.ReadValueId(ua.NodeId(ua.ObjectIds.Server_ServerStatus_State), ua.AttributeIds.Value)
    ]
    body = struct_to_binary(request)
    # TimestampsToReturn follows the request header and MaxAge (a Double)
    both = struct.pack("<d", 0.0) + struct.pack("<I", int(ua.TimestampsToReturn.Both))
    at = body.index(both) + 8
    return body[:at] + struct.pack("<I", timestamps) + body[at + 4 :]


def served_levels(caplog: pytest.LogCaptureFixture) -> None:
    """The levels the server logs at (launch.setup_logging): INFO, asyncua WARNING."""
    caplog.set_level(logging.WARNING, logger="asyncua")
    caplog.set_level(logging.INFO)  # last: it sets the level of caplog's handler too


def opcua_records(caplog: pytest.LogCaptureFixture) -> list[logging.LogRecord]:
    return [
        r
        for r in caplog.records
        if r.name.startswith("asyncua") or r.name.startswith("motion_server.opcua")
    ]


async def test_a_request_that_does_not_decode_is_one_line_and_a_service_fault(
    rt: Runtime, caplog: pytest.LogCaptureFixture
) -> None:
    ch = await session(rt)
    try:
        caplog.clear()
        served_levels(caplog)
        ch.send(ch.request(read_request(ch, BAD_TIMESTAMPS)))
        assert await ch.service_result() == Codes.BadDecodingError
        # the channel and the session go on
        ch.send(ch.request(read_request(ch, int(ua.TimestampsToReturn.Both))))
        assert await ch.service_result() == Codes.Good
        records = opcua_records(caplog)
        assert len(records) == 1, [r.getMessage() for r in records]
        assert records[0].exc_info is None and "Traceback" not in caplog.text
        assert "BadDecodingError" in records[0].getMessage()
    finally:
        await ch.close()


async def test_a_hello_whose_endpoint_url_is_not_utf8_is_refused_in_one_line(
    rt: Runtime, caplog: pytest.LogCaptureFixture
) -> None:
    assert rt.opcua is not None
    url = rt.opcua.endpoint.encode() + b"\xff\xfe"
    body = struct.pack("<IIIII", 0, 65535, 65535, 0, 0) + struct.pack("<i", len(url))
    caplog.clear()
    served_levels(caplog)
    ch = await RawChannel.connect(rt.opcua.port, rt.opcua.endpoint)
    ch.send(header(b"HELF", 8 + len(body) + len(url)) + body + url)
    assert (await ch.error())[0] == Codes.BadTcpEndpointUrlInvalid
    await ch.close()
    records = opcua_records(caplog)
    assert len(records) == 1, [r.getMessage() for r in records]
    assert records[0].exc_info is None and "Traceback" not in caplog.text


async def test_a_flood_of_refused_requests_is_rate_limited(
    rt: Runtime, caplog: pytest.LogCaptureFixture
) -> None:
    assert rt.opcua is not None and rt.opcua.flood_gate is not None
    gate = rt.opcua.flood_gate
    before = gate.suppressed
    ch = await session(rt)
    refused = 5 * opcua_log.LINES
    try:
        caplog.clear()
        served_levels(caplog)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        for _ in range(refused):
            ch.send(ch.request(read_request(ch, BAD_TIMESTAMPS)))
            assert await ch.service_result() == Codes.BadDecodingError
        assert loop.time() - t0 < opcua_log.WINDOW_S  # so it met two windows at most
        # LINES lines a window, and the "suppressed" line of the first
        assert len(opcua_records(caplog)) <= 2 * opcua_log.LINES + 1
    finally:
        await ch.close()
    assert gate.suppressed - before >= refused - 2 * opcua_log.LINES
