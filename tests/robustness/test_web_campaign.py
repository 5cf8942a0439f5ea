"""Hostile input on the web view's port (loopback only), against ``motion-server run``
with the realtime clock: random bytes, truncated and oversized request lines and headers,
bodies whose length lies, garbage after a WebSocket upgrade, and hundreds of connections
held open without a byte. After each batch a valid request on a fresh connection is
answered; at the end the scan has dropped no cycle and went on counting, and the web
process's memory is flat. Reproducible from ``MOTION_FUZZ_SEED``."""

from __future__ import annotations

import os
import random
import socket
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_server.testing import MotionServer

SEED = int(os.environ.get("MOTION_FUZZ_SEED", "20261128"))


@pytest.fixture(scope="module")
def srv(tmp_path_factory: pytest.TempPathFactory) -> Iterator[MotionServer]:
    server = MotionServer.start(
        tmp_path_factory.mktemp("web-campaign"), clock="realtime", opcua=False, web=True
    )
    try:
        yield server
    finally:
        server.finish()


def port(srv: MotionServer) -> int:
    return int(srv.web_url.rsplit(":", 1)[1].strip("/"))


def web_pid(srv: MotionServer) -> int:
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().split(b"\0")
            stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if b"motion_server.frontends" in cmd and b"web" in cmd and int(stat[1]) == srv.pid:
            return int(entry.name)
    raise AssertionError("no web front-end process")


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


def answered(srv: MotionServer) -> None:
    """A valid request on a fresh connection is answered within 2 s."""
    with urllib.request.urlopen(srv.web_url + "api/session", timeout=2.0) as r:
        assert r.status == 200


def send(p: int, data: bytes, read: bool = True) -> None:
    with socket.create_connection(("127.0.0.1", p), timeout=2.0) as s:
        try:
            s.sendall(data)
            if read:
                s.settimeout(0.3)
                s.recv(4096)
        except OSError:
            pass  # the server may close or reset: that is an answer


def test_malformed_requests_never_take_the_view_down(srv: MotionServer) -> None:
    rng = random.Random(SEED)
    p = port(srv)
    before = srv.read_many(["Clock.Cycle", "Diagnostics.DroppedCycles"])
    pid = web_pid(srv)
    base = rss_kib(pid)
    valid = b"GET /api/session HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    post = (
        b"POST /api/write HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        b"Content-Length: %d\r\n\r\n"
    )
    cases: list[bytes] = [
        b"\x00" * 64,
        b"GET",
        b"GET / HTTP/9.9\r\n\r\n",
        b"GET /" + b"a" * 70_000 + b" HTTP/1.1\r\nHost: x\r\n\r\n",
        b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX: " + b"b" * 70_000 + b"\r\n\r\n",
        post % 10_000_000 + b"{}",  # a length far beyond the body and the bound
        post % 5 + b"{" * 50,  # a body longer than it says
        post % 2 + b"\xff\xfe",  # not JSON
        b"GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        b"Sec-WebSocket-Key: AAAAAAAAAAAAAAAAAAAAAA==\r\nSec-WebSocket-Version: 13\r\n\r\n"
        + bytes(rng.randrange(256) for _ in range(512)),
    ]
    for _ in range(200):
        cut = rng.randrange(1, len(valid))
        cases.append(valid[:cut])
        cases.append(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 600))))
    for n, data in enumerate(cases):
        send(p, data, read=n % 8 == 0)
        if n % 50 == 0:
            answered(srv)
    answered(srv)
    time.sleep(0.5)
    after = srv.read_many(["Clock.Cycle", "Diagnostics.DroppedCycles"])
    assert after["Diagnostics.DroppedCycles"] == before["Diagnostics.DroppedCycles"]
    assert after["Clock.Cycle"] > before["Clock.Cycle"]
    assert web_pid(srv) == pid, "the web process was restarted"
    assert rss_kib(pid) - base < 8 * 1024, "memory grows with malformed requests"


def test_connections_held_open_do_not_starve_a_new_client(srv: MotionServer) -> None:
    p = port(srv)
    pid = web_pid(srv)
    before = srv.read_many(["Clock.Cycle", "Diagnostics.DroppedCycles"])
    idle: list[socket.socket] = []
    try:
        for n in range(300):
            s = socket.create_connection(("127.0.0.1", p), timeout=2.0)
            if n % 2:  # half of them start a request and never finish it
                s.sendall(b"GET /api/session HTTP/1.1\r\nHost: 127.0.0.1\r\n")
            idle.append(s)
        answered(srv)
    finally:
        for s in idle:
            s.close()
    answered(srv)
    after = srv.read_many(["Clock.Cycle", "Diagnostics.DroppedCycles"])
    assert after["Diagnostics.DroppedCycles"] == before["Diagnostics.DroppedCycles"]
    assert after["Clock.Cycle"] > before["Clock.Cycle"]
    assert web_pid(srv) == pid, "the web process was restarted"
