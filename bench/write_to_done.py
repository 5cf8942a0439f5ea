"""Write Execute -> DN observed over Modbus, motion-server in realtime mode (2 ms period).

A client writes the rising edge of an MSO's Execute (FC6), then polls the MSO's status
register (FC3) until DN is set; the latency runs from just before the write to the read
that shows DN (with EN, which the same scan sets). Execute is then dropped and the client
waits for EN to clear before the next sample, which starts at a random phase of the period.
The server runs as users start it (``motion-server run``: a supervisor, the scan and a
process per protocol). Target: p99 <= one coarse period + 2 ms.

- Default: the demo map, MSO_1 on Axis2, Modbus only.
- ``--opcua-load``: the OPC UA publish load of :mod:`opcua_publish` against the same
  server: its generated map (334 servo axes jogging, served over Modbus and OPC UA),
  MSO_LAT on Axis1. The samples are taken twice in one run, side by side: first with
  the axes jogging and no OPC UA client, then while the subscriber process monitors
  1,000 changing tags at 20 Hz (its notifications/s are printed). Same target for both.

Usage: ``python bench/write_to_done.py [--samples N] [--poll-gap MS] [--opcua-load]``.
"""

from __future__ import annotations

import argparse
import random
import struct
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import opcua_publish
from modbus_client import (
    MODBUS_PORT,
    OPCUA_ENDPOINT,
    RawClient,
    ServerProcess,
    load_average,
    percentile,
)
from motion_server import config
from motion_server.tagmap import Tag, TagMap, TagType, build_tagmap, encode


class Probe:
    """Write -> DN samples of one MSO instance over one Modbus connection."""

    def __init__(self, port: int, tagmap: TagMap, instance: str, poll_gap_ms: float) -> None:
        self.client = RawClient(port)
        self.tagmap = tagmap
        self.dn: Tag = tagmap.tag(f"{instance}.DN")
        self.en: Tag = tagmap.tag(f"{instance}.EN")
        self.execute: Tag = tagmap.tag(f"{instance}.Execute")
        self.axis: Tag = tagmap.tag(f"{instance}.Axis")
        self.poll_gap = poll_gap_ms / 1000.0
        self.period_ms = self.read_real("Clock.Period")
        self.polls = 0
        self.rng = random.Random(1)

    def read_real(self, name: str) -> float:
        tag = self.tagmap.tag(name)
        words = self.client.read(tag.address, 2)
        return float(struct.unpack(">f", struct.pack(">2H", *words))[0])

    def read_udint(self, name: str) -> int:
        tag = self.tagmap.tag(name)
        hi, lo = self.client.read(tag.address, 2)
        return hi << 16 | lo

    def set_axis(self, number: int) -> None:
        self.client.write_many(self.axis.address, encode(TagType.DINT, number))

    def samples(self, n: int) -> list[float]:
        c, dn, en, execute = self.client, self.dn, self.en, self.execute
        done = (1 << (dn.bit or 0)) | (1 << (en.bit or 0))
        out: list[float] = []
        for _ in range(n):
            t0 = time.perf_counter()
            c.write(execute.address, 1 << (execute.bit or 0))
            while True:
                self.polls += 1
                # DN stays set after the rung goes false; EN was cleared before this
                # sample, so EN and DN together mark the scan that executed the edge
                reg = c.read(dn.address, 1)[0]
                if reg & done == done:
                    out.append(time.perf_counter() - t0)
                    break
                if self.poll_gap:
                    time.sleep(self.poll_gap)
            c.write(execute.address, 0)
            while c.read(en.address, 1)[0] >> (en.bit or 0) & 1:
                pass
            # EN just cleared, i.e. a cycle just ran: start the next sample at a random
            # phase of the period, as an HMI's writes are not locked to the cycle
            time.sleep(self.rng.uniform(0.0, self.period_ms / 1000.0))
        return out

    def diagnostics(self) -> tuple[int, int, int]:
        """Overruns, dropped cycles and the cycle count, as of now."""
        return (
            self.read_udint("Diagnostics.Overruns"),
            self.read_udint("Diagnostics.DroppedCycles"),
            self.read_udint("Clock.Cycle"),
        )


def report(name: str, samples: list[float], period_ms: float, polls: int, diag: str) -> None:
    p50, p99 = percentile(samples, 0.5) * 1e3, percentile(samples, 0.99) * 1e3
    target = period_ms + 2.0
    print(f"  {name}: {len(samples)} samples")
    print(
        f"    p50 {p50:.2f} ms   p99 {p99:.2f} ms   max {max(samples) * 1e3:.2f} ms"
        f"   polls/sample {polls / len(samples):.1f}   {diag}"
    )
    print(
        f"    p99 / target ({target:.1f} ms = period + 2 ms): {p99 / target:.2f} (target <= 1.00)"
    )


def window(before: tuple[int, int, int], after: tuple[int, int, int]) -> str:
    overruns, dropped, cycles = (a - b for a, b in zip(after, before, strict=True))
    due = cycles + dropped  # a dropped cycle was due, and is counted late (an overrun)
    share = overruns / max(due, 1) * 100
    return f"overruns {overruns} of {due} cycles due ({share:.2f} %), dropped {dropped}"


def demo(args: argparse.Namespace) -> None:
    tagmap = build_tagmap(config.load())
    server = ServerProcess(
        [
            "-m",
            "motion_server.cli",
            "run",
            "--clock",
            "realtime",
            "--modbus-port",
            "0",
            "--no-opcua",
        ],
        MODBUS_PORT,
    )
    try:
        probe = Probe(server.port, tagmap, "MSO_1", args.poll_gap)
        probe.set_axis(2)  # Axis2: the demo's MC_Power_1 (Enable low) holds Axis1 off
        before = probe.diagnostics()
        samples = probe.samples(args.samples)
        after = probe.diagnostics()
        probe.client.close()
    finally:
        server.stop()
    print(f"write Execute -> DN observed, realtime, period {probe.period_ms:.1f} ms, demo map")
    report("no other client", samples, probe.period_ms, probe.polls, window(before, after))


def with_opcua_load(args: argparse.Namespace) -> None:
    with tempfile.TemporaryDirectory(prefix="bench-wtd-") as d:
        tmp = Path(d)
        text = opcua_publish.site_map(args.axes, tmp / "opcua-data", modbus=True)
        site = tmp / "bench-opcua.toml"
        site.write_text(text)
        tagmap = build_tagmap(config.parse(text, str(site)))
        server = ServerProcess(
            ["-m", "motion_server.cli", "run", str(site)], MODBUS_PORT, log=tmp / "server.log"
        )
        try:
            endpoint = server.wait_for(OPCUA_ENDPOINT)
            t = time.perf_counter()
            opcua_publish.start_jogs(server.port, tagmap, args.axes)
            print(f"{args.axes} axes jogging after {time.perf_counter() - t:.1f} s", flush=True)
            probe = Probe(server.port, tagmap, "MSO_LAT", args.poll_gap)
            before = probe.diagnostics()
            quiet = probe.samples(args.samples)
            quiet_polls, probe.polls = probe.polls, 0
            quiet_diag = window(before, probe.diagnostics())

            monitored = opcua_publish.monitored_tags(args.axes)
            sub = opcua_publish.run_subscriber(endpoint, monitored, 3.0, 0.0, tmp)
            opcua_publish.subscriber_ready(sub, "motion-server")
            time.sleep(3.0)  # the subscriber's warm-up: it counts from now on
            before = probe.diagnostics()
            loaded = probe.samples(args.samples)
            loaded_diag = window(before, probe.diagnostics())
            notif = opcua_publish.subscriber_count(sub)
            probe.client.close()
        finally:
            server.stop()
    period = probe.period_ms
    print(
        f"write Execute -> DN observed over Modbus, realtime, period {period:.1f} ms, "
        f"{args.axes} axes jogging"
    )
    report("no OPC UA client", quiet, period, quiet_polls, quiet_diag)
    report(
        f"OPC UA subscriber: {len(monitored)} tags, {notif:.0f} notifications/s",
        loaded,
        period,
        probe.polls,
        loaded_diag,
    )
    q99, l99 = percentile(quiet, 0.99), percentile(loaded, 0.99)
    print(f"  p99 with the OPC UA load / without: {l99 / q99:.2f}")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=500)
    p.add_argument(
        "--poll-gap",
        type=float,
        default=0.0,
        help="ms between polls (0: back to back; the client then takes a core of its own)",
    )
    p.add_argument(
        "--opcua-load",
        action="store_true",
        help="run opcua_publish.py's load (334 jogging axes, 1,000 monitored tags) as well",
    )
    p.add_argument("--axes", type=int, default=334, help="jogging axes with --opcua-load")
    args = p.parse_args()
    print(f"load average before: {load_average()}")
    if args.opcua_load:
        with_opcua_load(args)
    else:
        demo(args)
    print(f"load average after: {load_average()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
