"""Write Execute -> DN observed over Modbus, motion-server in realtime mode (2 ms period).

A client writes the rising edge of MSO_1.Execute (FC6), then polls MSO_1's status
register (FC3) until DN is set; the latency runs from just before the write to the read
that shows DN (with EN, which the same scan sets). Execute is then dropped and the client
waits for EN to clear before the next sample, which starts at a random phase of the period.
Target: p99 <= one coarse period + 2 ms.
Usage: ``python bench/write_to_done.py [--samples N]``.
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import RawClient, percentile, start_server, stop_server
from motion_server import config
from motion_server.tagmap import TagType, build_tagmap, encode


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--samples", type=int, default=500)
    p.add_argument(
        "--poll-gap",
        type=float,
        default=0.0,
        help="ms between polls (0: back to back; the client then takes a core of its own)",
    )
    args = p.parse_args()
    tagmap = build_tagmap(config.load())
    period = tagmap.tag("Clock.Period")
    dn, en = tagmap.tag("MSO_1.DN"), tagmap.tag("MSO_1.EN")
    execute, axis = tagmap.tag("MSO_1.Execute"), tagmap.tag("MSO_1.Axis")
    proc, port = start_server(
        [
            "-m",
            "motion_server.cli",
            "run",
            "--clock",
            "realtime",
            "--modbus-port",
            "0",
            "--no-opcua",
        ]
    )
    samples: list[float] = []
    polls = 0
    try:
        c = RawClient(port)
        period_ms = struct_float(c.read(period.address, 2))
        # Axis2: the demo's MC_Power_1 (Enable low) holds Axis1 off
        for k, word in enumerate(encode(TagType.DINT, 2)):
            c.write(axis.address + k, word)
        done = (1 << (dn.bit or 0)) | (1 << (en.bit or 0))
        rng = random.Random(1)
        for _ in range(args.samples):
            t0 = time.perf_counter()
            c.write(execute.address, 1 << (execute.bit or 0))
            while True:
                polls += 1
                # DN stays set after the rung goes false; EN was cleared before this
                # sample, so EN and DN together mark the scan that executed the edge
                reg = c.read(dn.address, 1)[0]
                if reg & done == done:
                    samples.append(time.perf_counter() - t0)
                    break
                if args.poll_gap:
                    time.sleep(args.poll_gap / 1000.0)
            c.write(execute.address, 0)
            while c.read(en.address, 1)[0] >> (en.bit or 0) & 1:
                pass
            # EN just cleared, i.e. a cycle just ran: start the next sample at a random
            # phase of the period, as an HMI's writes are not locked to the cycle
            time.sleep(rng.uniform(0.0, period_ms / 1000.0))
        c.close()
    finally:
        stop_server(proc)
    p50, p99 = percentile(samples, 0.5) * 1e3, percentile(samples, 0.99) * 1e3
    target = period_ms + 2.0
    print(
        f"write Execute -> DN observed, realtime, period {period_ms:.1f} ms, {len(samples)} samples"
    )
    print(
        f"  p50 {p50:.2f} ms   p99 {p99:.2f} ms   max {max(samples) * 1e3:.2f} ms"
        f"   polls/sample {polls / len(samples):.1f}"
    )
    print(f"  p99 / target ({target:.1f} ms = period + 2 ms): {p99 / target:.2f} (target <= 1.00)")
    return 0


def struct_float(regs: list[int]) -> float:
    import struct

    return float(struct.unpack(">f", struct.pack(">2H", *regs))[0])


if __name__ == "__main__":
    sys.exit(main())
