"""Malformed and hostile Modbus traffic against a running server (loopback only).

A campaign of batches, each of one kind of abuse, reproducible from a seed
(``MOTION_FUZZ_SEED``, default 20250131). After every batch: a valid FC3 read on a fresh
connection is answered within 1 s, and the realtime loop has dropped no cycle (a cycle
is dropped only when the loop is later than its catch-up bound, ``max_catch_up``
cycles). At least 10,000 malformed frames per run; ``MOTION_FUZZ_LONG=1`` runs ten times
as many. Counts and post-batch checks are printed (``pytest -s`` shows them).
"""

from __future__ import annotations

import contextlib
import os
import random
import socket
import struct
import time
from collections.abc import Callable, Iterator

import pytest

from motion_server import config
from tests.modbus_support import SITE, ServerThread

SEED = int(os.environ.get("MOTION_FUZZ_SEED", "20250131"))
SCALE = 10 if os.environ.get("MOTION_FUZZ_LONG") else 1
MIN_FRAMES = 10_000 * SCALE
MAX_CONNECTIONS = 8
SERVED = (3, 6, 16, 22, 23)


def realtime_site() -> config.SiteMap:
    text = SITE.format(word_order="big", unit_id=1).replace('clock = "manual"', "")
    text += f"\n[modbus.access]\nmax_connections = {MAX_CONNECTIONS}\nidle_timeout = 5.0\n"
    return config.parse(text, "campaign.toml")


def mbap(tid: int, pdu: bytes, unit: int = 1, length: int | None = None) -> bytes:
    n = len(pdu) + 1 if length is None else length
    return struct.pack(">HHHB", tid, 0, n, unit) + pdu


def read_request(tid: int, address: int = 0, count: int = 1, unit: int = 1) -> bytes:
    return mbap(tid, struct.pack(">BHH", 3, address, count), unit)


# -- generators: each returns one malformed frame (bytes) -----------------------------------
def lying_length(r: random.Random) -> bytes:
    pdu = struct.pack(">BHH", 3, r.randrange(65536), r.randrange(1, 126))
    return mbap(r.randrange(65536), pdu, length=r.choice([0, 1, 2, 3, 7, 200, 65535]))


def truncated(r: random.Random) -> bytes:
    fc = r.choice(SERVED)
    pdu = bytes([fc]) + r.randbytes(r.randrange(0, 12))
    frame = mbap(r.randrange(65536), pdu)
    return frame[: r.randrange(1, len(frame) + 1)]


def oversize(r: random.Random) -> bytes:
    body = r.randbytes(r.randrange(260, 1200))
    return mbap(r.randrange(65536), bytes([16]) + body)


def unknown_function(r: random.Random) -> bytes:
    fc = r.choice([c for c in range(1, 128) if c not in SERVED])
    return mbap(r.randrange(65536), bytes([fc]) + r.randbytes(r.randrange(0, 8)))


def bad_quantity(r: random.Random) -> bytes:
    tid = r.randrange(65536)
    kind = r.randrange(3)
    if kind == 0:  # FC3 count 0 or > 125
        return mbap(tid, struct.pack(">BHH", 3, r.randrange(65536), r.choice([0, 126, 65535])))
    if kind == 1:  # FC16 byte count that disagrees with the quantity
        n = r.randrange(1, 10)
        return mbap(tid, struct.pack(">BHHB", 16, 5000, n, 2 * n + 1) + r.randbytes(2 * n))
    return mbap(tid, struct.pack(">BHHHH", 23, 0, 200, 5000, 0))  # FC23 read count > 125


def unknown_unit(r: random.Random) -> bytes:
    return read_request(r.randrange(65536), 0, 1, unit=r.choice([2, 17, 200, 255]))


def pipelined(r: random.Random) -> bytes:
    return b"".join(read_request(r.randrange(65536), 0, r.randrange(1, 10)) for _ in range(4))


def garbage(r: random.Random) -> bytes:
    return r.randbytes(r.randrange(1, 300))


GENERATORS: dict[str, Callable[[random.Random], bytes]] = {
    "lying length": lying_length,
    "truncated": truncated,
    "oversize": oversize,
    "unknown function": unknown_function,
    "bad quantity": bad_quantity,
    "unknown unit": unknown_unit,
    "pipelined": pipelined,
    "garbage": garbage,
}


# -- plumbing ---------------------------------------------------------------------------------
def drain(sock: socket.socket) -> int:
    got = 0
    sock.setblocking(False)
    try:
        while chunk := sock.recv(65536):
            got += len(chunk)
    except (BlockingIOError, ConnectionError, OSError):
        pass
    finally:
        sock.setblocking(True)
    return got


def blast(port: int, frames: Iterator[bytes], per_connection: int = 100) -> int:
    """Send frames over successive connections; returns how many were sent."""
    sent = 0
    sock: socket.socket | None = None
    for frame in frames:
        if sock is None or sent % per_connection == 0:
            if sock is not None:
                sock.close()
            sock = socket.create_connection(("127.0.0.1", port), timeout=2)
        try:
            sock.sendall(frame)
        except OSError:  # the server closed a connection it judged hostile: fine
            sock.close()
            sock = socket.create_connection(("127.0.0.1", port), timeout=2)
        sent += 1
        if sent % 20 == 0:
            drain(sock)
    if sock is not None:
        sock.close()
    return sent


def check_alive(srv: ServerThread, label: str) -> float:
    """A valid read on a fresh connection within 1 s; no dropped cycle. Returns seconds."""
    t0 = time.perf_counter()
    with socket.create_connection(("127.0.0.1", srv.port), timeout=1.0) as sock:
        sock.sendall(read_request(0x4242, 0, 10))
        answer = b""
        while len(answer) < 9 + 20:
            chunk = sock.recv(64)
            assert chunk, f"{label}: connection closed instead of an answer"
            answer += chunk
    elapsed = time.perf_counter() - t0
    assert answer[:2] == b"\x42\x42" and answer[7] == 3, f"{label}: bad answer {answer!r}"
    assert elapsed < 1.0, f"{label}: answered after {elapsed:.3f} s"
    rt = srv.runtime
    assert rt is not None
    assert rt.dropped == 0, f"{label}: {rt.dropped} cycles dropped (late beyond catch-up)"
    return elapsed


@pytest.fixture(scope="module")
def server() -> Iterator[ServerThread]:
    with ServerThread(realtime_site()) as srv:
        yield srv


def test_malformed_frame_campaign(server: ServerThread) -> None:
    r = random.Random(SEED)
    total = 0
    batches = 0
    per_batch = 250 * SCALE
    print(f"\nModbus campaign, seed {SEED}, at least {MIN_FRAMES} frames")
    while total < MIN_FRAMES:
        for name, gen in GENERATORS.items():
            sent = blast(server.port, (gen(r) for _ in range(per_batch)))
            total += sent
            batches += 1
            elapsed = check_alive(server, name)
            rt = server.runtime
            assert rt is not None
            print(
                f"batch {batches:3d} {name:17s} {sent:5d} frames; valid read in "
                f"{elapsed * 1000:6.1f} ms; overruns {rt.overruns}, dropped {rt.dropped}"
            )
    print(f"total {total} malformed frames in {batches} batches")
    assert total >= MIN_FRAMES


def test_slow_loris_partial_frames(server: ServerThread) -> None:
    """Connections that dribble a frame byte by byte do not block anybody else."""
    socks = [socket.create_connection(("127.0.0.1", server.port)) for _ in range(4)]
    frame = read_request(1, 0, 2)
    for i in range(len(frame) - 1):  # never the last byte
        for s in socks:
            s.sendall(frame[i : i + 1])
        check_alive(server, f"slow loris byte {i}")
    for s in socks:
        s.close()
    print("\nslow loris: 4 connections x 11 bytes; valid reads answered after each byte")


def test_connection_flood_past_the_limit(server: ServerThread) -> None:
    rt = server.runtime
    assert rt is not None and rt.modbus is not None
    before = rt.modbus.refused_connections
    flood = []
    for _ in range(MAX_CONNECTIONS * 4):
        with contextlib.suppress(OSError):
            flood.append(socket.create_connection(("127.0.0.1", server.port), timeout=1))
    deadline = time.monotonic() + 2
    while rt.modbus.refused_connections - before < MAX_CONNECTIONS * 3 - 1:
        assert time.monotonic() < deadline, "the server did not refuse the flood"
        time.sleep(0.01)
    assert len(rt.modbus.connections) <= MAX_CONNECTIONS
    for s in flood:
        s.close()
    deadline = time.monotonic() + 2
    while rt.modbus.connections and time.monotonic() < deadline:
        time.sleep(0.01)
    check_alive(server, "after the flood")
    print(f"\nflood: {len(flood)} connections, {rt.modbus.refused_connections - before} refused")


# -- regressions for upstream pymodbus crash reports ----------------------------------------
def exchange(port: int, data: bytes, want: int) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=2) as sock:
        sock.sendall(data)
        answer = b""
        while len(answer) < want:
            chunk = sock.recv(256)
            if not chunk:
                break
            answer += chunk
        return answer


def test_exception_reply_carries_the_function_code_and_transaction_id(
    server: ServerThread,
) -> None:
    # an unknown function code: answer FC | 0x80 with the request's transaction id
    answer = exchange(server.port, mbap(0x1234, bytes([0x41])), 9)
    assert answer[:2] == b"\x12\x34"
    assert answer[7] == 0x41 | 0x80 and answer[8] == 1
    # a served function code refused by us (read outside the map): exception 02
    answer = exchange(server.port, read_request(0xBEEF, 65000, 1), 9)
    assert answer[:2] == b"\xbe\xef" and answer[7] == 0x83 and answer[8] == 2


def test_truncated_pdus_do_not_kill_the_connection_or_the_server(server: ServerThread) -> None:
    # FC16 whose byte count promises more data than sent; FC3 with a 1-byte body
    for pdu in (struct.pack(">BHHB", 16, 5000, 4, 8) + b"\x00\x01", bytes([3, 0])):
        exchange(server.port, mbap(7, pdu), 9)
        check_alive(server, f"truncated {pdu.hex()}")


def test_the_receive_buffer_stays_bounded(server: ServerThread) -> None:
    rt = server.runtime
    assert rt is not None and rt.modbus is not None
    with socket.create_connection(("127.0.0.1", server.port), timeout=2) as sock:
        # a header promising 65535 bytes (more than an ADU can hold: the server closes
        # the connection), then 1 MB that never completes a frame
        sock.sendall(struct.pack(">HHHB", 1, 0, 65535, 1))
        chunk = b"\x00" * 4096
        closed = False
        for _ in range(256):
            try:
                sock.sendall(chunk)
            except (BrokenPipeError, ConnectionResetError):
                closed = True
                break
            sizes = [len(h.recv_buffer) for h in rt.modbus.connections.values()]
            assert max(sizes, default=0) <= 4096 + 600
        time.sleep(0.05)  # let the server read what is in flight (bounded, not a timing)
        sizes = [len(h.recv_buffer) for h in rt.modbus.connections.values()]
        assert max(sizes, default=0) <= 4096 + 600
        if not closed:  # the sends fitted in the socket buffers: the close comes as EOF
            sock.settimeout(2.0)
            with contextlib.suppress(ConnectionResetError):
                assert sock.recv(1024) == b"", "no Modbus answer to a header of 65535"
    check_alive(server, "after 1 MB without a frame")
