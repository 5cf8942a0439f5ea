"""100-register reads: motion-server (kernel running at 2 ms, realtime) vs a bare pymodbus
server with the same registers, side by side in one run; prints the ratio (target >= 1.0).

motion-server runs as users start it (``motion-server run``: a supervisor, the scan and
the Modbus front-end, each a process of its own); the bare server is one process. One
client sends FC3 requests back to back (one in flight) and the two servers are measured
in alternating rounds so that machine noise falls on both. Besides the overall ratio it
prints the median of the per-round ratios and each server's CPU time per request (from
/proc, summed over its process tree: for motion-server the supervisor, the scan's cycles
and the front-end), which a busy machine disturbs less.
Usage: ``python bench/modbus_throughput.py [--requests N] [--clock manual]``.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import (
    RawClient,
    cpu_by_role,
    load_average,
    percentile,
    start_server,
    stop_server,
)


def bare_server() -> None:
    """A pymodbus server with the demo map's register blocks and no action hook."""
    from pymodbus.server import ModbusTcpServer
    from pymodbus.simulator import SimDevice

    from motion_server import config
    from motion_server.frontends.modbus import sim_data
    from motion_server.tagmap import build_tagmap

    logging.basicConfig(level=logging.INFO)

    async def main() -> None:
        server = ModbusTcpServer(
            [SimDevice(id=1, simdata=sim_data(build_tagmap(config.load())))],
            address=("127.0.0.1", 0),
        )
        await server.serve_forever(background=True)
        port = server.transport.sockets[0].getsockname()[1]  # type: ignore[attr-defined]
        logging.getLogger("bare").info("Modbus TCP on 127.0.0.1:%d", port)
        await server.serving

    asyncio.run(main())


def measure(
    pid: int, port: int, address: int, count: int, n: int
) -> tuple[list[float], dict[str, float]]:
    """Latencies of ``n`` reads and the CPU seconds of each process of the server's tree
    meanwhile (by role: the supervisor, the scan, the front-end)."""
    client = RawClient(port)
    for _ in range(50):  # warm-up
        client.read(address, count)
    out = []
    cpu0 = cpu_by_role(pid)
    for _ in range(n):
        t0 = time.perf_counter()
        client.read(address, count)
        out.append(time.perf_counter() - t0)
    cpu = {k: v - cpu0.get(k, 0.0) for k, v in cpu_by_role(pid).items()}
    client.close()
    return out, cpu


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--requests", type=int, default=8000, help="requests per server (total)")
    p.add_argument("--rounds", type=int, default=10)
    p.add_argument("--address", type=int, default=1000, help="first register (default: Axis1)")
    p.add_argument(
        "--clock",
        default="realtime",
        choices=["realtime", "manual"],
        help="motion-server clock: realtime (kernel at 2 ms, the target) or manual (idle)",
    )
    p.add_argument("--bare-server", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.bare_server:
        bare_server()
        return 0
    count = 100
    print(f"load average before: {load_average()}")
    ms, ms_port = start_server(
        [
            "-m",
            "motion_server.cli",
            "run",
            "--clock",
            args.clock,
            "--modbus-port",
            "0",
            "--no-opcua",
        ]
    )
    bare, bare_port = start_server([__file__, "--bare-server"])
    names = ("motion-server", "bare pymodbus")
    servers = {names[0]: (ms.pid, ms_port), names[1]: (bare.pid, bare_port)}
    results: dict[str, list[float]] = {n: [] for n in names}
    cpu: dict[str, dict[str, float]] = {n: {} for n in names}
    round_ratios = []
    try:
        per_round = args.requests // args.rounds
        for _ in range(args.rounds):
            rate = {}
            for name in names:
                samples, used = measure(*servers[name], args.address, count, per_round)
                results[name] += samples
                for k, v in used.items():
                    cpu[name][k] = cpu[name].get(k, 0.0) + v
                rate[name] = len(samples) / sum(samples)
            round_ratios.append(rate[names[0]] / rate[names[1]])
    finally:
        stop_server(ms)
        stop_server(bare)
    rates = {}
    print(
        f"FC3 reads of {count} registers from {args.address}, one request in flight, "
        f"{args.requests} per server, motion-server clock {args.clock}"
    )
    per_request: dict[str, float] = {}
    for name, samples in results.items():
        rates[name] = len(samples) / sum(samples)
        per_request[name] = sum(cpu[name].values()) / len(samples)
        print(
            f"  {name:14s} {rates[name]:8.0f} req/s   p50 {percentile(samples, 0.5) * 1e6:6.0f} us"
            f"   p99 {percentile(samples, 0.99) * 1e6:6.0f} us"
            f"   server CPU {per_request[name] * 1e6:5.0f} us/request"
        )
    parts = ", ".join(
        f"{k} {v / len(results[names[0]]) * 1e6:.0f}" for k, v in sorted(cpu[names[0]].items())
    )
    print(f"  motion-server CPU per request by process (us): {parts}")
    ratio = rates[names[0]] / rates[names[1]]
    median = sorted(round_ratios)[len(round_ratios) // 2]
    cpu_ratio = per_request[names[1]] / per_request[names[0]]
    print(f"  ratio motion-server / bare pymodbus: {ratio:.2f} (target >= 1.0)")
    print(f"  median of {len(round_ratios)} per-round ratios: {median:.2f}")
    print(f"  CPU per request, bare / motion-server (process tree): {cpu_ratio:.2f}")
    print(f"load average after: {load_average()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
