"""Fairness: another client's read latency while one Modbus client floods pipelined reads.

The server runs as users start it (``motion-server run`` on the demo map, OPC UA off,
Modbus on an ephemeral port). A polling client reads one register (FC3) every 5 ms, one
request in flight, and records each answer's latency: first alone for ``--seconds``, then
as long again while a flood process sends bursts of ``--burst`` pipelined FC3 requests
(12 bytes each, in one ``sendall``) on its own connection and reads their answers,
back to back. Printed: the poller's latency p50/p99/max alone and under the flood, and
the flood's request rate (the throughput the front-end still gives the abuser).

Run it twice to compare two trees: the server is the ``motion_server`` that
``PYTHONPATH`` finds. Usage: ``python bench/modbus_fairness.py [--seconds 3] [--burst 20000]``.
"""

from __future__ import annotations

import argparse
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import RawClient, ServerProcess

REQUEST = struct.Struct(">HHHBBHH")
ANSWER_BYTES = 11  # MBAP 7 + FC 1 + byte count 1 + one register 2


def flood(port: int, burst: int, seconds: float) -> None:
    """Bursts of pipelined FC3 requests for ``seconds``; prints the requests/s answered."""
    sock = socket.create_connection(("127.0.0.1", port))
    frames = b"".join(REQUEST.pack(i & 0xFFFF, 0, 6, 1, 3, 0, 1) for i in range(burst))
    want = burst * ANSWER_BYTES
    done = 0
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        sock.sendall(frames)
        got = 0
        while got < want:
            chunk = sock.recv(1 << 20)
            if not chunk:
                raise ConnectionError("the server closed the flood's connection")
            got += len(chunk)
        done += burst
    print(f"{done / (time.monotonic() - start):.0f}", flush=True)


def poll(port: int, seconds: float) -> list[float]:
    """Latencies (s) of single FC3 reads, one every 5 ms, for ``seconds``."""
    client = RawClient(port, timeout=30.0)
    out: list[float] = []
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            t0 = time.perf_counter()
            client.read(0, 1)
            out.append(time.perf_counter() - t0)
            time.sleep(0.005)
    finally:
        client.close()
    return out


def line(name: str, samples: list[float]) -> str:
    s = sorted(samples)
    p50 = s[len(s) // 2] * 1e3
    p99 = s[min(len(s) - 1, int(len(s) * 0.99))] * 1e3
    return (
        f"{name:<14} n={len(s):5d}  p50 {p50:8.2f} ms  p99 {p99:8.2f} ms  max {s[-1] * 1e3:8.2f} ms"
    )


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--flood":
        flood(int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--burst", type=int, default=20000)
    args = parser.parse_args()
    server = ServerProcess(["-m", "motion_server.cli", "run", "--no-opcua", "--modbus-port", "0"])
    try:
        alone = poll(server.port, args.seconds)
        flooder = subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--flood",
                str(server.port),
                str(args.burst),
                str(args.seconds + 0.5),
            ],
            stdout=subprocess.PIPE,
            text=True,
        )
        time.sleep(0.25)  # the flood under way
        flooded = poll(server.port, args.seconds)
        out, _ = flooder.communicate(timeout=120)
    finally:
        server.stop()
    print(line("alone", alone))
    print(line("under flood", flooded))
    print(f"flood: {out.strip()} requests/s answered (bursts of {args.burst})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
