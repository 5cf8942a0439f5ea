"""Shared by the Modbus benchmarks: a minimal blocking Modbus TCP client on a raw socket
(so that the client costs little next to the server) and server start-up helpers."""

from __future__ import annotations

import os
import re
import socket
import struct
import subprocess
import sys
import time


class RawClient:
    """FC3 / FC6 over one TCP connection, one request in flight."""

    def __init__(self, port: int, unit: int = 1) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.unit = unit
        self.tid = 0

    def _call(self, pdu: bytes, answer: int) -> bytes:
        self.tid = (self.tid + 1) & 0xFFFF
        self.sock.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, self.unit) + pdu)
        want = 7 + answer
        buf = b""
        while len(buf) < 9:
            buf += self.sock.recv(4096)
        if buf[7] & 0x80:
            raise RuntimeError(f"Modbus exception {buf[8]}")
        while len(buf) < want:
            buf += self.sock.recv(4096)
        return buf[7:want]

    def read(self, address: int, count: int) -> list[int]:
        pdu = self._call(struct.pack(">BHH", 3, address, count), 2 + 2 * count)
        return list(struct.unpack(f">{count}H", pdu[2:]))

    def write(self, address: int, value: int) -> None:
        self._call(struct.pack(">BHH", 6, address, value), 5)

    def close(self) -> None:
        self.sock.close()


def start_server(
    args: list[str], pattern: str = r"Modbus TCP on [\d.]+:(\d+)"
) -> tuple[subprocess.Popen[str], int]:
    """Start a server process and return it with the port it logged."""
    proc = subprocess.Popen([sys.executable, *args], stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    deadline = time.monotonic() + 30
    for line in proc.stderr:
        m = re.search(pattern, line)
        if m:
            return proc, int(m.group(1))
        if time.monotonic() > deadline:
            break
    proc.kill()
    raise RuntimeError("the server did not report its port")


def stop_server(proc: subprocess.Popen[str]) -> None:
    proc.terminate()
    try:
        proc.wait(30)
    except subprocess.TimeoutExpired:
        proc.kill()


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(samples: list[float], q: float) -> float:
    s = sorted(samples)
    return s[min(len(s) - 1, int(q * len(s)))]
