"""A minimal EtherNet/IP client for the tests: raw frames, so a test sees the exact CIP
general status a request gets (pylogix and pycomm3 turn it into words) and can send what
no well-behaved client would."""

from __future__ import annotations

import socket
import struct

REGISTER_SESSION = 0x65
SEND_RR_DATA = 0x6F


def header(command: int, length: int, session: int = 0, context: int = 0) -> bytes:
    return struct.pack("<HHIIQI", command, length, session, 0, context, 0)


def symbolic(*parts: str | int) -> bytes:
    """An EPATH of ANSI symbolic segments (str) and 8/16-bit element segments (int)."""
    out = b""
    for p in parts:
        if isinstance(p, int):
            out += bytes((0x28, p)) if p < 256 else struct.pack("<BBH", 0x29, 0, p)
            continue
        raw = p.encode("ascii")
        out += bytes((0x91, len(raw))) + raw + (b"\x00" if len(raw) % 2 else b"")
    return out


def request(service: int, path: bytes, data: bytes = b"") -> bytes:
    """A Message Router request."""
    return bytes((service, len(path) // 2)) + path + data


class Wire:
    """One TCP connection with a registered session, sending unconnected requests."""

    def __init__(self, port: int, host: str = "127.0.0.1", timeout: float = 5.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.sendall(header(REGISTER_SESSION, 4) + struct.pack("<HH", 1, 0))
        reply = self.recv_frame()
        self.session = struct.unpack_from("<I", reply, 4)[0]

    def close(self) -> None:
        self.sock.close()

    def recv_exact(self, n: int) -> bytes:
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("closed by the server")
            out += chunk
        return out

    def recv_frame(self) -> bytes:
        head = self.recv_exact(24)
        length = struct.unpack_from("<H", head, 2)[0]
        return head + self.recv_exact(length)

    def send_rr(self, mr: bytes) -> bytes:
        """SendRRData with ``mr`` as unconnected data: the Message Router reply."""
        cpf = struct.pack("<IHH", 0, 10, 2) + struct.pack("<HH", 0, 0)
        cpf += struct.pack("<HH", 0xB2, len(mr)) + mr
        self.sock.sendall(header(SEND_RR_DATA, len(cpf), self.session) + cpf)
        reply = self.recv_frame()
        # header 24, interface 4, timeout 2, count 2, null item 4, data item type+len 4
        return reply[40:]

    def cip(
        self, service: int, path: bytes, data: bytes = b""
    ) -> tuple[int, tuple[int, ...], bytes]:
        """(general status, extended status words, reply data) of one request."""
        mr = self.send_rr(request(service, path, data))
        general, size = mr[2], mr[3]
        ext = struct.unpack_from(f"<{size}H", mr, 4)
        return general, ext, mr[4 + 2 * size :]


def forward_open(w: Wire, serial: int) -> int:
    """A class 3 Forward Open to the controller in slot 0 (as pylogix sends it): the
    general status."""
    data = struct.pack(
        "<BBIIHHIBBBBIHIHBB",
        0x0A, 0x0E, 0, 0x20000002 + serial, serial & 0xFFFF, 0x1337, 42, 3, 0, 0, 0,
        2_000_000, 0x43F4, 2_000_000, 0x43F4, 0xA3, 3,
    )  # fmt: skip
    data += bytes((1, 0, 0x20, 2, 0x24, 1))
    return w.cip(0x54, bytes((0x20, 6, 0x24, 1)), data)[0]
