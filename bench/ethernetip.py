"""EtherNet/IP tag reads against Modbus reads of the same tags, side by side in one run.

``motion-server run`` on the demo map (realtime clock, 2 ms, Modbus and EtherNet/IP
served, OPC UA off). The tags: ActualPosition, CommandPosition, ActualVelocity,
MotionStatus and AxisFault of Axis1..Axis4 (20 tags). One request in flight over one
connection, for ``--seconds`` each, in alternating rounds:

- EtherNet/IP single: Read Tag of one member (``Axis2.ActualPosition``), unconnected
  (SendRRData), from a raw-socket client (what the server can do) and from pylogix
  1.1.6 (connected messaging: what a Python user sees, the client's own cost included);
- Modbus single: FC3 of the same tag's registers (raw-socket client);
- EtherNet/IP multi: the 20 tags in one Multiple Service Packet (raw client, pylogix);
- Modbus multi: the same 20 tags as four FC3 block reads, one per axis (each axis's five
  tags are contiguous), as a Modbus HMI driver reads them.

Prints reads/s (tags/s for the multi-reads), p50 and p99 latency per request, the
scan's overruns and dropped cycles over each window (``Diagnostics`` over Modbus), and
the load average before and after. Target: ≥ 3,000 single reads/s, no overrun.
"""

from __future__ import annotations

import argparse
import os
import socket
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import RawClient, ServerProcess, TagClient, percentile
from motion_server.config import load
from motion_server.tagmap import build_tagmap

ENIP_PORT = r"EtherNet/IP on [\d.]+:(\d+)"
MODBUS_PORT = r"Modbus TCP on [\d.]+:(\d+)"
FIELDS = ("ActualPosition", "CommandPosition", "ActualVelocity", "MotionStatus", "AxisFault")
AXES = ("Axis1", "Axis2", "Axis3", "Axis4")
DEMO = Path(__file__).resolve().parents[1] / "server" / "motion_server" / "data" / "demo.toml"


def symbolic(*parts: str) -> bytes:
    out = b""
    for p in parts:
        raw = p.encode()
        out += bytes((0x91, len(raw))) + raw + (b"\x00" if len(raw) % 2 else b"")
    return out


class EnipRaw:
    """Unconnected Read Tag over one registered session."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.sendall(struct.pack("<HHIIQIHH", 0x65, 4, 0, 0, 0, 0, 1, 0))
        self.session = struct.unpack_from("<I", self._frame(), 4)[0]

    def _frame(self) -> bytes:
        buf = b""
        while len(buf) < 24:
            buf += self.sock.recv(65536)
        need = 24 + struct.unpack_from("<H", buf, 2)[0]
        while len(buf) < need:
            buf += self.sock.recv(65536)
        return buf

    def call(self, mr: bytes) -> bytes:
        cpf = struct.pack("<IHHHHHH", 0, 10, 2, 0, 0, 0xB2, len(mr)) + mr
        self.sock.sendall(struct.pack("<HHIIQI", 0x6F, len(cpf), self.session, 0, 0, 0) + cpf)
        reply = self._frame()[40:]
        if reply[2] != 0:
            raise RuntimeError(f"CIP status 0x{reply[2]:02X}")
        return reply

    def close(self) -> None:
        self.sock.close()


def read_request(owner: str, field: str) -> bytes:
    path = symbolic(owner, field)
    return bytes((0x4C, len(path) // 2)) + path + b"\x01\x00"


def multi_request(names: list[tuple[str, str]]) -> bytes:
    reqs = [read_request(o, f) for o, f in names]
    n = len(reqs)
    offsets, at = [], 2 + 2 * n
    for r in reqs:
        offsets.append(at)
        at += len(r)
    data = struct.pack(f"<H{n}H", n, *offsets) + b"".join(reqs)
    path = bytes((0x20, 0x02, 0x24, 0x01))
    return bytes((0x0A, len(path) // 2)) + path + data


def measure(call: Callable[[], object], seconds: float) -> tuple[int, list[float]]:
    lat: list[float] = []
    end = time.perf_counter() + seconds
    while True:
        t0 = time.perf_counter()
        if t0 >= end:
            break
        call()
        lat.append(time.perf_counter() - t0)
    return len(lat), lat


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=3.0, help="per measurement (3)")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds (2)")
    ap.add_argument("--no-pylogix", action="store_true", help="raw clients only")
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()}")
    server = ServerProcess(
        [
            "-m", "motion_server.cli", "run", "--clock", "realtime", "--no-opcua",
            "--modbus-port", "0", "--ethernetip-port", "0",
        ],
        ENIP_PORT,
    )  # fmt: skip
    enip_port = server.port
    modbus_port = int(server.wait_for(MODBUS_PORT))
    tagmap = build_tagmap(load(DEMO))
    names = [(a, f) for a in AXES for f in FIELDS]
    tags = TagClient(modbus_port, tagmap)
    diag = TagClient(modbus_port, tagmap)
    one = tagmap.tag("Axis2.ActualPosition")
    blocks = []
    for a in AXES:
        ts = [tagmap.tag(f"{a}.{f}") for f in FIELDS]
        lo = min(t.address for t in ts)
        hi = max(t.address + t.count for t in ts)
        blocks.append((lo, hi - lo))
    raw = EnipRaw(enip_port)
    mb = RawClient(modbus_port)
    single_mr = read_request("Axis2", "ActualPosition")
    multi_mr = multi_request(names)
    cases: list[tuple[str, int, Callable[[], object]]] = [
        ("EtherNet/IP single (raw)", 1, lambda: raw.call(single_mr)),
        ("Modbus single (raw FC3)", 1, lambda: mb.read(one.address, one.count)),
        ("EtherNet/IP 20 tags, 1 packet (raw)", 20, lambda: raw.call(multi_mr)),
        ("Modbus 20 tags, 4 FC3 (raw)", 20, lambda: [mb.read(a, n) for a, n in blocks]),
    ]
    plc = None
    if not args.no_pylogix:
        from pylogix import PLC

        plc = PLC("127.0.0.1", port=enip_port)
        tag_names = [f"{o}.{f}" for o, f in names]
        cases.insert(
            1, ("EtherNet/IP single (pylogix)", 1, lambda: plc.Read("Axis2.ActualPosition"))
        )
        cases.insert(4, ("EtherNet/IP 20 tags (pylogix)", 20, lambda: plc.Read(tag_names)))
    results: dict[str, list[tuple[int, list[float]]]] = {c[0]: [] for c in cases}
    windows: dict[str, list[list[int]]] = {c[0]: [] for c in cases}
    watched = ("Diagnostics.Overruns", "Diagnostics.DroppedCycles", "Clock.Cycle")
    for _ in range(args.rounds):
        for label, _, call in cases:
            call()  # warm
            before = [int(diag.read(n)) for n in watched]
            results[label].append(measure(call, args.seconds))
            after = [int(diag.read(n)) for n in watched]
            windows[label].append([b - a for a, b in zip(before, after, strict=True)])
    heads = ("req/s", "tags/s", "p50 ms", "p99 ms", "overruns", "dropped", "cycles")
    print(f"{'case':40}" + "".join(f"{h:>10}" for h in heads))
    for label, per, _ in cases:
        count = sum(n for n, _ in results[label])
        lat = [x for _, ls in results[label] for x in ls]
        secs = args.seconds * args.rounds
        ov = sum(w[0] for w in windows[label])
        dr = sum(w[1] for w in windows[label])
        cy = sum(w[2] for w in windows[label])
        p50, p99 = percentile(lat, 0.50) * 1e3, percentile(lat, 0.99) * 1e3
        print(
            f"{label:40}{count / secs:10.0f}{per * count / secs:10.0f}"
            f"{p50:10.3f}{p99:10.3f}{ov:10d}{dr:10d}{cy:10d}"
        )
    raw.close()
    mb.close()
    tags.close()
    diag.close()
    if plc is not None:
        plc.Close()
    server.stop()
    print(f"load average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
