"""Modbus TCP framing over raw sockets on 127.0.0.1: pipelined and split requests, bad
headers, every function code, slow senders, and what the audit log says of refusals.

The numbers come from the Modbus Application Protocol Specification V1.1b3 and the
Modbus Messaging on TCP/IP Implementation Guide V1.0b: the MBAP header is 7 bytes
(transaction id, protocol id 0, length, unit id), its length counts the unit id and the
PDU (2..254: an ADU is at most 260 bytes); FC3 reads 1..125 registers, FC16 writes
1..123 with a byte count of twice that, FC23 reads 1..125 and writes 1..121; FC6 and
FC22 answer with an echo of the request, FC16 with its address and count. The server's
own promises come from its README: exception 01 for every function code but 3, 6, 16, 22
and 23, 0B for a unit id other than the site's.

The site's clock is manual: nothing changes between two reads unless a client writes,
so an answer can be compared with the same request sent alone.
"""

from __future__ import annotations

import contextlib
import json
import socket
import struct
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_server import config
from motion_server.frontends.modbus import FRAME_TIMEOUT, STALLED_AFTER
from tests.modbus_support import SITE, ServerThread

UNIT = 1


def site(extra: str = "", data_dir: Path | None = None) -> config.SiteMap:
    head = f'data_dir = "{data_dir}"\n' if data_dir is not None else ""
    return config.parse(head + SITE.format(word_order="big", unit_id=UNIT) + extra, "framing.toml")


def adu(tid: int, pdu: bytes, unit: int = UNIT, protocol: int = 0) -> bytes:
    return struct.pack(">HHHB", tid, protocol, len(pdu) + 1, unit) + pdu


def fc3(address: int, count: int) -> bytes:
    return struct.pack(">BHH", 3, address, count)


def fc6(address: int, value: int) -> bytes:
    return struct.pack(">BHH", 6, address, value)


def fc16(address: int, values: list[int]) -> bytes:
    n = len(values)
    return struct.pack(f">BHHB{n}H", 16, address, n, 2 * n, *values)


def connect(port: int, timeout: float = 5.0) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def answers(sock: socket.socket, n: int) -> list[tuple[int, int, bytes]]:
    """``n`` answer ADUs as (transaction id, unit id, PDU), delimited by their headers."""
    buf = b""
    out: list[tuple[int, int, bytes]] = []
    while len(out) < n:
        while len(buf) >= 6 and len(buf) >= 6 + struct.unpack_from(">H", buf, 4)[0]:
            tid, protocol, length, unit = struct.unpack_from(">HHHB", buf)
            assert protocol == 0
            out.append((tid, unit, buf[7 : 6 + length]))
            buf = buf[6 + length :]
        if len(out) >= n:
            break
        chunk = sock.recv(65536)
        assert chunk, f"closed after {len(out)} of {n} answers"
        buf += chunk
    assert buf == b"", "more bytes than answers"
    return out


def call(port: int, pdu: bytes, tid: int = 1) -> bytes:
    """One request on a fresh connection; its answer PDU."""
    with connect(port) as sock:
        sock.sendall(adu(tid, pdu))
        ((got, _, answer),) = answers(sock, 1)
    assert got == tid
    return answer


def closed_by_server(sock: socket.socket, within: float) -> bool:
    """True when the server closes ``sock`` within ``within`` s (EOF or reset), with no
    byte sent first."""
    sock.settimeout(within)
    try:
        return sock.recv(1024) == b""
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


@pytest.fixture(scope="module")
def server() -> Iterator[ServerThread]:
    with ServerThread(site()) as srv:
        yield srv


def tag_address(srv: ServerThread, name: str) -> int:
    assert srv.runtime is not None
    return srv.runtime.tagmap.tag(name).address


# -- pipelining and segmentation ----------------------------------------------------------------
READS = [(0, 20), (0, 120), (11, 1), (50, 22), (1000, 100), (1014, 4), (1050, 50), (20000, 10)]


def read_requests(n: int) -> list[tuple[int, bytes]]:
    """``n`` FC3 requests over several ranges, each with its own transaction id."""
    return [(0x100 + k, fc3(*READS[k % len(READS)])) for k in range(n)]


@pytest.mark.parametrize("n", [1, 2, 10, 50, 200])
def test_every_request_in_one_send_is_answered_in_order(server: ServerThread, n: int) -> None:
    alone = {r: call(server.port, fc3(*r)) for r in READS}
    requests = read_requests(n)
    with connect(server.port) as sock:
        sock.sendall(b"".join(adu(tid, pdu) for tid, pdu in requests))
        got = answers(sock, n)
    for k, ((tid, _), (answer_tid, unit, answer)) in enumerate(zip(requests, got, strict=True)):
        assert (answer_tid, unit) == (tid, UNIT), f"answer {k}"
        assert answer == alone[READS[k % len(READS)]], f"answer {k}"
        assert answer[1] == 2 * READS[k % len(READS)][1]  # byte count


def test_200_pipelined_reads_and_writes_keep_their_order(server: ServerThread) -> None:
    """Writes of MAJ_1.Speed's high word interleaved with reads of it: each read shows the
    write just before it (writes wait for the scan with the manual clock, so answers
    behind them must wait too)."""
    speed = tag_address(server, "MAJ_1.Speed")
    requests: list[tuple[int, bytes]] = []
    expected: list[bytes] = []
    written = None
    for k in range(200):
        tid = 0x2000 + k
        if k % 4 == 1:  # 0x4100 + k with a low word 0: 8.0 .. 25.0 as a REAL
            written = 0x4100 + k
            requests.append((tid, fc6(speed, written)))
            expected.append(fc6(speed, written))  # FC6 echoes the request
        elif k % 4 == 2:
            requests.append((tid, fc3(speed, 1)))
            assert written is not None
            expected.append(bytes([3, 2]) + struct.pack(">H", written))
        else:
            requests.append((tid, fc3(1000, 100)))
            expected.append(b"")  # checked against a lone read below
    lone = call(server.port, fc3(1000, 100))
    with connect(server.port) as sock:
        sock.sendall(b"".join(adu(tid, pdu) for tid, pdu in requests))
        got = answers(sock, 200)
    for k, ((tid, _), (answer_tid, _, answer)) in enumerate(zip(requests, got, strict=True)):
        assert answer_tid == tid, f"answer {k}"
        assert answer == (expected[k] or lone), f"answer {k}"
    assert call(server.port, fc3(speed, 2)) == bytes([3, 4]) + struct.pack(">HH", written, 0)


def test_frames_split_at_every_byte_boundary_are_all_answered(server: ServerThread) -> None:
    """A request whose first bytes share a segment with the one before it, for every
    split point of three requests, and the whole stream one byte per send."""
    requests = read_requests(3)
    alone = [call(server.port, pdu) for _, pdu in requests]
    stream = b"".join(adu(tid, pdu) for tid, pdu in requests)
    for cut in range(1, len(stream)):
        with connect(server.port) as sock:
            sock.sendall(stream[:cut])
            time.sleep(0.001)  # two segments (TCP_NODELAY), not a condition of the result
            sock.sendall(stream[cut:])
            got = answers(sock, 3)
        assert [(t, a) for t, _, a in got] == [
            (tid, alone[k]) for k, (tid, _) in enumerate(requests)
        ], f"cut at byte {cut}"
    with connect(server.port) as sock:
        for i in range(len(stream)):
            sock.sendall(stream[i : i + 1])
            time.sleep(0.001)
        got = answers(sock, 3)
    assert [a for _, _, a in got] == alone


def test_a_client_that_reads_late_still_gets_every_answer_in_order(server: ServerThread) -> None:
    """2,000 reads of 120 registers (498,000 bytes of answers) sent before reading any:
    the server stops reading while the client does not, and loses nothing."""
    pdu = fc3(0, 120)
    expected = call(server.port, pdu)
    n = 2000
    with connect(server.port, timeout=10.0) as sock:
        sock.sendall(b"".join(adu(k & 0xFFFF, pdu) for k in range(n)))
        got = answers(sock, n)
    assert [t for t, _, _ in got] == list(range(n))
    assert all(a == expected for _, _, a in got)


# -- bad headers -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("protocol", "length"),
    [(7, 6), (0xFFFF, 6), (1, 2), (0, 0), (0, 1), (0, 255), (0, 65535)],
)
def test_a_header_that_delimits_no_frame_closes_the_connection_at_once(
    server: ServerThread, protocol: int, length: int
) -> None:
    good = adu(0x11, fc3(11, 1))
    bad = struct.pack(">HHHB", 0x22, protocol, length, UNIT) + fc3(11, 1)
    with connect(server.port) as sock:
        sock.sendall(good + bad)  # the request before it is answered, then the close
        ((tid, _, answer),) = answers(sock, 1)
        assert tid == 0x11 and answer[0] == 3
        assert closed_by_server(sock, 1.0), f"protocol {protocol}, length {length}"
    # the header alone (6 bytes) is enough to judge it
    with connect(server.port) as sock:
        sock.sendall(bad[:6])
        assert closed_by_server(sock, 1.0), f"protocol {protocol}, length {length}: 6 bytes"
    assert call(server.port, fc3(11, 1))[0] == 3


# -- function codes ----------------------------------------------------------------------------
def test_each_function_code_answers_as_documented(server: ServerThread) -> None:
    speed = tag_address(server, "MAJ_1.Speed")
    execute = tag_address(server, "MAJ_1.Execute")
    valid = {
        3: fc3(11, 1),
        6: fc6(speed + 1, 0),
        16: fc16(speed, [0x4120, 0]),  # 10.0
        22: struct.pack(">BHHH", 22, execute, 0xFFFF, 0),  # AND all, OR none: unchanged
        23: struct.pack(">BHHHHBH", 23, 11, 1, speed + 1, 1, 2, 0),
    }
    with connect(server.port) as sock:
        for fc in range(256):
            bodies = [valid[fc]] if fc in valid else [bytes([fc]), bytes([fc]) + bytes(4)]
            if fc not in valid:
                bodies.append(bytes([fc]) + bytes(range(1, 21)))
            for tid, pdu in enumerate(bodies):
                sock.sendall(adu(tid, pdu))
                ((got, unit, answer),) = answers(sock, 1)
                assert (got, unit) == (tid, UNIT)
                if fc in valid:
                    assert answer[0] == fc, f"FC{fc}: {answer.hex()}"
                else:
                    assert answer == bytes([fc | 0x80, 1]), f"FC{fc} {pdu.hex()}: {answer.hex()}"
    assert call(server.port, fc3(speed, 2)) == bytes([3, 4, 0x41, 0x20, 0, 0])
    assert call(server.port, fc6(speed + 1, 0)) == fc6(speed + 1, 0)
    assert call(server.port, fc16(speed, [0x4120, 0])) == fc16(speed, [0x4120, 0])[:5]


MALFORMED = {
    "FC3 count 0": fc3(0, 0),
    "FC3 count 126": fc3(0, 126),
    "FC3 one byte short": fc3(0, 1)[:-1],
    "FC3 one byte long": fc3(0, 1) + b"\x00",
    "FC6 short": fc6(20512, 0)[:-1],
    "FC6 long": fc6(20512, 0) + b"\x00",
    "FC16 count 0": struct.pack(">BHHB", 16, 20512, 0, 0),
    "FC16 count 124": struct.pack(">BHHB", 16, 20512, 124, 248),  # no room for the data
    "FC16 byte count odd": struct.pack(">BHHB", 16, 20512, 2, 5) + bytes(5),
    "FC16 data short": struct.pack(">BHHB", 16, 20512, 2, 4) + bytes(3),
    "FC16 data long": struct.pack(">BHHB", 16, 20512, 2, 4) + bytes(5),
    "FC16 no byte count": struct.pack(">BHH", 16, 20512, 2),
    "FC22 short": struct.pack(">BHH", 22, 20506, 0xFFFF),
    "FC23 read count 126": struct.pack(">BHHHHBH", 23, 0, 126, 20513, 1, 2, 0),
    "FC23 write count 122": struct.pack(">BHHHHB", 23, 0, 1, 20512, 122, 244),
    "FC23 write count 0": struct.pack(">BHHHHB", 23, 0, 1, 20512, 0, 0),
    "FC23 byte count wrong": struct.pack(">BHHHHBH", 23, 0, 1, 20513, 1, 4, 0),
    "FC23 header only": bytes([23]),
}


def test_malformed_counts_and_lengths_answer_exception_03(server: ServerThread) -> None:
    speed = tag_address(server, "MAJ_1.Speed")
    assert speed == 20512  # the addresses written into MALFORMED
    with connect(server.port) as sock:
        for k, (what, pdu) in enumerate(MALFORMED.items()):
            sock.sendall(adu(k, pdu))
            ((tid, _, answer),) = answers(sock, 1)
            assert tid == k and answer == bytes([pdu[0] | 0x80, 3]), f"{what}: {answer.hex()}"
    assert call(server.port, fc3(speed, 2)) != b""  # the connection and server live on


def test_unit_ids_other_than_the_sites_answer_0b(server: ServerThread) -> None:
    with connect(server.port) as sock:
        for k, unit in enumerate((0, 2, 17, 247, 255)):
            for pdu in (fc3(11, 1), fc6(20513, 0), bytes([43, 14, 1, 0])):
                sock.sendall(adu(k, pdu, unit=unit))
                ((tid, got_unit, answer),) = answers(sock, 1)
                assert (tid, got_unit) == (k, unit)
                assert answer == bytes([pdu[0] | 0x80, 0x0B]), f"unit {unit}: {answer.hex()}"


# -- time limits ---------------------------------------------------------------------------------
def test_the_idle_timeout_counts_from_the_last_complete_request() -> None:
    """A frame trickling in (one byte every 0.2 s) does not keep a connection alive: it
    is closed once ``idle_timeout`` (1 s) passed since its last complete request."""
    assert config.ModbusAccessSection().idle_timeout == 60.0  # the default is not "never"
    with ServerThread(site("\n[modbus.access]\nidle_timeout = 1.0\n")) as srv:
        rt = srv.runtime
        assert rt is not None and rt.modbus is not None
        rt.modbus.frame_timeout = 60.0  # only the idle timeout applies here
        with connect(srv.port) as sock:
            t0 = time.monotonic()  # before the server takes the request as its last
            sock.sendall(adu(1, fc3(11, 1)))
            answers(sock, 1)
            frame = adu(2, fc3(11, 1))
            closed = False
            for i in range(len(frame) - 1):  # never the last byte
                with contextlib.suppress(OSError):
                    sock.sendall(frame[i : i + 1])
                if closed_by_server(sock, 0.2):
                    closed = True
                    break
            waited = time.monotonic() - t0
        assert closed, "still open after 11 bytes over 2.2 s"
        assert 1.0 <= waited < 2.0
        assert rt.modbus.idle_closed == 1


def test_slow_loris_sockets_never_lock_a_client_out() -> None:
    """16 sockets fill ``max_connections`` (16), each sending one byte of a frame every
    2 s. Once their frames are ``STALLED_AFTER`` old, a client that sends requests is
    served within 1 s on every try (it takes the place of the connection whose frame has
    been incomplete longest), and every slow socket is closed once its frame took longer
    than ``FRAME_TIMEOUT``."""
    assert STALLED_AFTER < 2.0 < FRAME_TIMEOUT  # the attack below trips both
    text = "\n[modbus.access]\nmax_connections = 16\n"
    with ServerThread(site(text)) as srv:
        rt = srv.runtime
        assert rt is not None and rt.modbus is not None
        frame = adu(9, fc3(0, 10))
        loris = [connect(srv.port) for _ in range(16)]
        for s in loris:
            s.sendall(frame[:1])
        deadline = time.monotonic() + 5.0
        while len(rt.modbus.connections) < 16:
            assert time.monotonic() < deadline, "the slow sockets were not admitted"
            time.sleep(0.01)
        stop = threading.Event()
        cut: set[int] = set()

        def trickle() -> None:  # one more byte on every slow socket every 2 s
            for i in range(1, len(frame) - 1):
                if stop.wait(2.0):
                    return
                for k, s in enumerate(loris):
                    try:
                        s.sendall(frame[i : i + 1])
                    except OSError:
                        cut.add(k)

        sender = threading.Thread(target=trickle, daemon=True)
        start = time.monotonic()
        sender.start()
        try:
            served = []
            time.sleep(STALLED_AFTER)  # from now on every slow frame counts as stalled
            while time.monotonic() - start < FRAME_TIMEOUT + 2.5:
                t0 = time.monotonic()
                with connect(srv.port, timeout=1.0) as sock:
                    sock.sendall(adu(0x77, fc3(11, 1)))
                    ((tid, _, answer),) = answers(sock, 1)
                elapsed = time.monotonic() - t0
                assert tid == 0x77 and answer[0] == 3
                assert elapsed < 1.0, f"served after {elapsed:.2f} s"
                served.append(elapsed)
                time.sleep(0.5)
            # every slow socket has been closed by the server by now
            for s in loris:
                assert closed_by_server(s, 0.5)
            assert not rt.modbus.connections
            assert rt.modbus.evicted + rt.modbus.frame_timeouts == 16
            assert rt.modbus.evicted >= 1 and rt.modbus.refused_connections == 0
        finally:
            stop.set()
            sender.join(5.0)
            for s in loris:
                s.close()
        assert len(served) >= 10


# -- audit -------------------------------------------------------------------------------------
def test_writes_refused_by_the_request_checks_are_audited_with_their_registers(
    tmp_path: Path,
) -> None:
    text = "\n[audit]\nenabled = true\n"
    with ServerThread(site(text, data_dir=tmp_path)) as srv:
        speed = tag_address(srv, "MAJ_1.Speed")
        bad = {
            "byte count": struct.pack(">BHHB", 16, speed, 2, 3) + bytes(3),
            "count": struct.pack(">BHHB", 16, speed, 124, 248),
            "fc23 write count": struct.pack(">BHHHHB", 23, 0, 1, speed, 0, 0),
            "fc6 short": fc6(speed, 0)[:-1],
            "coils": struct.pack(">BHH", 5, 7, 0xFF00),
            "unit": b"",
        }
        with connect(srv.port) as sock:
            for k, pdu in enumerate(bad.values()):
                unit = 9 if not pdu else UNIT
                sock.sendall(adu(k, pdu or fc16(speed, [0x4120, 0]), unit=unit))
                ((_, _, answer),) = answers(sock, 1)
                assert answer[0] & 0x80
    records = [
        json.loads(line) for line in (tmp_path / "audit.jsonl").read_text("utf-8").splitlines()
    ]
    refused = [r for r in records if r["event"] == "write" and r["result"] == "refused"]
    got = [(r["function_code"], r.get("registers")) for r in refused]
    assert got == [
        (16, f"{speed}+2"),
        (16, f"{speed}+124"),
        (23, f"{speed}+0"),
        (6, f"{speed}+1"),
        (5, None),
        (16, f"{speed}+2"),
    ]
    assert all(r["protocol"] == "modbus" and r["address"] == "127.0.0.1" for r in refused)
    assert "unknown unit id 9" in refused[-1]["reason"]
