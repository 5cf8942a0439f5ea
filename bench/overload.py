"""Overload: one abusive OPC UA client against the scan, Modbus polling and a watchdog.

The server runs as users start it (``motion-server run``: a supervisor, the scan and a
process per protocol) on a small site map: Group1 with Axis1 (virtual, jogging at
100 mm/s) and Axis2, one instance of every instruction type, a communication watchdog
``WD1`` (``[[watchdogs]]``, timeout 0.5 s, fast stop of Group1), anonymous OPC UA
sessions with the viewer role on the None endpoint (loopback), a 2 ms cycle in realtime.

1. A watchdog process writes ``WD1.Heartbeat`` over Modbus every 100 ms (the watchdog
   arms), and 5 poller processes read 20 registers of Axis1 (FC3) every 10 ms each.
   The first seconds give the latency with no abuse.
2. The abuse starts: the watchdog process stops writing the heartbeat, and one anonymous
   OPC UA client sends, one after the other: a Read of 50,000 node ids (the map's
   variables, repeated), a Browse of enough node ids (the map's objects, repeated) for
   30,000 references, a CreateMonitoredItems of 20,000 items (the variables again) on
   one subscription, which it then holds for a few seconds while the server publishes
   to it, and deletes.
3. The watchdog process polls ``WD1.State`` every millisecond from its last heartbeat
   on, back to back from 50 ms before the trip is due. The stop begins in the cycle
   that turns State from 1 (armed) to 2 (stopping): the last read that still showed 1
   was sent before that cycle was published, the first read that shows 2 came back
   after it. So the wall-clock delay from the last heartbeat to the start of the stop
   lies between those two instants; both bounds are printed, counted from the answer
   to the last heartbeat write (the Modbus front-end answers once it has handed the
   write to the scan's queue: the server has the beat) and from its sending.

Measured: dropped cycles and overruns (as a share of the cycles due) during the abuse
(``Diagnostics`` over Modbus), the watchdog's delay, the FC3 latency p50/p99/max before
and during the abuse side by side, how long each abusive request took and what it
returned (status codes), and the CPU of the server's process tree. Targets: 0 dropped
cycles; overruns <= 1 %; the stop begins within the timeout + one cycle (502 ms) of the
last heartbeat; FC3 p99 <= 20 ms during the abuse. With the default ``[opcua]``
operation limits the front-end refuses each request at once (BadTooManyOperations);
``--no-limits`` lifts them (0: no limit) and the message size to 64 MB, so that the
front-end processes all of it, which is the case the scan must ride out.

Usage: ``python bench/overload.py [--reads 50000] [--references 30000] [--items 20000]
[--no-limits]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import math
import select
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import (
    MODBUS_PORT,
    OPCUA_ENDPOINT,
    RawClient,
    ServerProcess,
    TagClient,
    cpu_seconds,
    load_average,
    percentile,
)
from motion_server import config
from motion_server.tagmap import TagMap, build_tagmap

NS_URI = "urn:motion-server:overload"
TIMEOUT = 0.5
PERIOD_MS = 2.0
SPEED = 100.0
HEARTBEAT_EVERY = 0.1
POLLERS = 5
POLL_EVERY = 0.010
POLL_REGISTERS = 20
QUIET_SECONDS = 3.0
HOLD_SECONDS = 3.0
#: targets
MAX_OVERRUN_SHARE = 0.01
MAX_FC3_P99_MS = 20.0

SITE = """
[site]
name = "overload"
namespace_uri = "{ns}"

[controller]
clock = "realtime"
status_log_interval = 0.0

[modbus]
port = 0

[opcua]
port = 0
data_dir = "{data}"
allow_anonymous = true
anonymous_role = "viewer"
allow_none_endpoint = true
{limits}
[[groups]]
name = "Group1"
coarse_update_period_ms = {period}
axes = ["Axis1", "Axis2"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[[axes]]
name = "Axis2"
type = "servo"
max_velocity = 1000.0
max_acceleration = 20000.0
max_deceleration = 20000.0

[instructions]
every_type = true

[[watchdogs]]
name = "WD1"
timeout = {timeout}
group = "Group1"
stop_mode = "fast_stop"
"""


#: ``--no-limits``: no operation limit or per-session quota, messages up to 64 MB
NO_LIMITS = """max_nodes_per_read = 0
max_nodes_per_browse = 0
max_monitored_items_per_call = 0
max_monitored_items_per_session = 0
max_chunk_count = 1024
max_message_size = 67108864
"""


def site_text(data_dir: Path, limits: bool = True) -> str:
    return SITE.format(
        ns=NS_URI,
        data=data_dir,
        period=PERIOD_MS,
        timeout=TIMEOUT,
        limits="" if limits else NO_LIMITS,
    )


# -- helper processes -------------------------------------------------------------------------
def stdin_has_line(timeout: float) -> bool:
    ready, _, _ = select.select([sys.stdin], [], [], timeout)
    return bool(ready)


def poller(port: int, address: int) -> None:
    """FC3 of POLL_REGISTERS registers every POLL_EVERY s until a line on stdin; prints
    READY once connected, then at the end one JSON line: [[monotonic start, latency s],
    ...] and the error count."""
    client = RawClient(port, timeout=10)
    client.read(address, POLL_REGISTERS)
    print("READY", flush=True)
    samples: list[tuple[float, float]] = []
    errors = 0
    next_at = time.monotonic()
    while not stdin_has_line(max(0.0, next_at - time.monotonic())):
        t0 = time.monotonic()
        try:
            client.read(address, POLL_REGISTERS)
        except (OSError, RuntimeError):
            errors += 1
            client.close()
            client = RawClient(port, timeout=10)
        samples.append((t0, time.monotonic() - t0))
        next_at = max(next_at + POLL_EVERY, time.monotonic())
    print(json.dumps({"samples": samples, "errors": errors}), flush=True)


def watchdog(port: int, site_file: str) -> None:
    """Heartbeat every HEARTBEAT_EVERY s until a line on stdin; then poll WD1.State every
    millisecond, back to back from 50 ms before the trip is due, until it leaves 1
    (armed). Prints one JSON line."""
    text = Path(site_file).read_text()
    tags = TagClient(port, build_tagmap(config.parse(text, site_file)), timeout=10)
    beat = 0
    sent = acked = 0.0
    while True:
        beat += 1
        sent = time.monotonic()
        tags.write("WD1.Heartbeat", beat)
        acked = time.monotonic()
        if beat == 3:
            print("ARMED" if tags.read("WD1.State") == 1 else "NOT ARMED", flush=True)
        if stdin_has_line(HEARTBEAT_EVERY):
            break
    last_armed = acked  # the earliest bound until a read shows the watchdog still armed
    first_stopping = 0.0
    state = 1
    reads = 0
    give_up = sent + 30.0
    while time.monotonic() < give_up:
        t0 = time.monotonic()
        state = int(tags.read("WD1.State"))
        t1 = time.monotonic()
        reads += 1
        if state != 1:
            first_stopping = t1
            break
        last_armed = t0
        if t1 - acked < TIMEOUT - 0.05:
            time.sleep(0.001)  # back to back from 50 ms before the trip is due
    print(
        json.dumps(
            {
                "beats": beat,
                "last_beat_sent": sent,
                "last_beat_acked": acked,
                "last_armed_read_sent": last_armed,
                "first_stopping_read_back": first_stopping,
                "state": state,
                "reads": reads,
                "trips": int(tags.read("WD1.Trips")),
            }
        ),
        flush=True,
    )


def helper(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, __file__, *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )


def finish(proc: subprocess.Popen[str]) -> dict[str, Any]:
    """Close the helper's stdin (its signal to stop) and read its JSON line."""
    out, _ = proc.communicate("stop\n", timeout=120)
    result: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    return result


# -- the abusive client -----------------------------------------------------------------------
def describe(codes: Counter[str]) -> str:
    return ", ".join(f"{n} {name}" for name, n in codes.most_common())


async def abuse(
    endpoint: str,
    tagmap: TagMap,
    args: argparse.Namespace,
    ready: Callable[[], Awaitable[None]],
) -> list[dict[str, Any]]:
    """Connect and prepare, await ``ready()`` (the abuse starts), then send the requests
    one after the other; per request: what, how long, what came back."""
    from asyncua import Client, ua

    logging.getLogger("asyncua").setLevel(logging.ERROR)
    out: list[dict[str, Any]] = []
    client = Client(endpoint, timeout=600, watchdog_intervall=3600)
    await client.connect()
    try:
        ns = await client.get_namespace_index(NS_URI)
        variables = [ua.NodeId(t.node_id, ns) for t in tagmap.tags]
        objects = sorted({t.node_id.rsplit(".", 1)[0] for t in tagmap.tags})
        object_ids = [ua.NodeId(n, ns) for n in objects]

        def describe_browse(node: Any) -> Any:
            bd = ua.BrowseDescription()
            bd.NodeId = node
            bd.BrowseDirection = ua.BrowseDirection.Both
            bd.ReferenceTypeId = ua.NodeId(ua.ObjectIds.References)
            bd.IncludeSubtypes = True
            bd.NodeClassMask = 0
            bd.ResultMask = 63  # everything
            return bd

        def browse_params(nodes: list[Any]) -> Any:
            params = ua.BrowseParameters()
            params.View = ua.ViewDescription()
            params.RequestedMaxReferencesPerNode = 0
            params.NodesToBrowse = [describe_browse(n) for n in nodes]
            return params

        # an ordinary browse first: how many references one pass over the objects gives
        probe = await client.uaclient.browse(browse_params(object_ids))
        per_pass = sum(len(r.References) for r in probe)
        passes = math.ceil(args.references / max(per_pass, 1))
        browse_nodes = (object_ids * passes)[: len(object_ids) * passes]
        print(
            f"abusive client connected: {len(variables)} variables, {len(object_ids)} objects "
            f"({per_pass} references per pass over them)",
            flush=True,
        )

        async def timed(what: str, call: Any) -> Any:
            t0 = time.monotonic()
            entry: dict[str, Any] = {"what": what, "start": t0}
            try:
                result = await call
                entry["ok"] = True
            except Exception as exc:  # a refusal is a result to report
                result = None
                entry["ok"] = False
                entry["error"] = f"{type(exc).__name__}: {str(exc)[:200]}"
            entry["seconds"] = time.monotonic() - t0
            out.append(entry)
            print(f"  {what}: {entry['seconds']:.2f} s", flush=True)
            return result

        await ready()  # the abuse starts now: the heartbeat stops

        params = ua.ReadParameters()
        for k in range(args.reads):
            rv = ua.ReadValueId()
            rv.NodeId = variables[k % len(variables)]
            rv.AttributeId = ua.AttributeIds.Value
            params.NodesToRead.append(rv)
        values = await timed(f"Read of {args.reads} node ids", client.uaclient.read(params))
        if values is not None:
            out[-1]["result"] = describe(Counter(v.StatusCode.name for v in values))

        results = await timed(
            f"Browse of {len(browse_nodes)} node ids (about {per_pass * passes} references)",
            client.uaclient.browse(browse_params(browse_nodes)),
        )
        if results is not None:
            refs = sum(len(r.References) for r in results)
            codes = Counter(r.StatusCode.name for r in results)
            more = sum(1 for r in results if r.ContinuationPoint)
            out[-1]["result"] = f"{refs} references; {describe(codes)}; {more} continuation points"

        notifications = [0]

        class Count:
            def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
                notifications[0] += 1

        sub = await client.create_subscription(1000.0, Count())
        nodes = [client.get_node(variables[k % len(variables)]) for k in range(args.items)]
        # one CreateMonitoredItems request with every item (asyncua's subscription sends
        # them in one, and routes the notifications by its client handles)
        created = await timed(
            f"CreateMonitoredItems of {args.items} items",
            sub.subscribe_data_change(nodes, queuesize=1, sampling_interval=100.0),
        )
        if created is not None:
            kinds = Counter(
                "Good" if isinstance(c, int) else getattr(c, "name", str(c)) for c in created
            )
            out[-1]["result"] = describe(kinds)
        t0 = time.monotonic()
        await asyncio.sleep(HOLD_SECONDS)
        out.append(
            {
                "what": f"holding the {args.items} items for {HOLD_SECONDS:.0f} s",
                "start": t0,
                "seconds": time.monotonic() - t0,
                "ok": True,
                "result": f"{notifications[0]} notifications received",
            }
        )
        await timed("DeleteSubscriptions", sub.delete())
    finally:
        try:
            await asyncio.wait_for(client.disconnect(), 60)
        except Exception as exc:
            print(f"  disconnect: {type(exc).__name__}", flush=True)
    return out


# -- the run ----------------------------------------------------------------------------------
def latency_line(name: str, samples: list[float]) -> str:
    if not samples:
        return f"{name}: no samples"
    ms = [s * 1000 for s in samples]
    return (
        f"{name}: {len(ms)} reads, p50 {percentile(ms, 0.5):.2f} ms, "
        f"p99 {percentile(ms, 0.99):.2f} ms, max {max(ms):.2f} ms"
    )


def diagnostics(tags: TagClient) -> dict[str, float]:
    names = ["Overruns", "DroppedCycles", "MaxCycleTime", "ScanLoad", "FrontendRestarts"]
    out = {n: float(tags.read(f"Diagnostics.{n}")) for n in names}
    out["Cycle"] = float(tags.read("Clock.Cycle"))
    return out


def start_jog(tags: TagClient) -> None:
    for name, value in [("MSO_1.Axis", 1), ("MAJ_1.Axis", 1), ("MAJ_1.Speed", SPEED)]:
        tags.write(name, value)
    for name in ("MSO_1.Execute", "MAJ_1.Execute"):
        tags.write(name, False)
        time.sleep(0.05)
        tags.write(name, True)
        time.sleep(0.05)
    deadline = time.monotonic() + 10
    while abs(float(tags.read("Axis1.CommandVelocity")) - SPEED) > 1e-3:
        if time.monotonic() > deadline:
            raise RuntimeError("Axis1 does not jog")
        time.sleep(0.05)


def run(args: argparse.Namespace) -> int:
    print(f"load average before: {load_average()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-overload-") as d:
        tmp = Path(d)
        text = site_text(tmp / "opcua-data", limits=not args.no_limits)
        print(
            "OPC UA operation limits: "
            + ("lifted (--no-limits)" if args.no_limits else "the defaults"),
            flush=True,
        )
        site = tmp / "overload.toml"
        site.write_text(text)
        tagmap = build_tagmap(config.parse(text, str(site)))
        server = ServerProcess(
            ["-m", "motion_server.cli", "run", str(site)], MODBUS_PORT, log=tmp / "server.log"
        )
        helpers: list[subprocess.Popen[str]] = []
        try:
            endpoint = server.wait_for(OPCUA_ENDPOINT)
            port = server.port
            tags = TagClient(port, tagmap, timeout=30)
            start_jog(tags)
            wd = helper("--watchdog", str(port), str(site))
            helpers.append(wd)
            assert wd.stdout is not None
            if wd.stdout.readline().strip() != "ARMED":
                raise RuntimeError("the watchdog did not arm")
            axis1 = min(t.address for t in tagmap.tags if t.owner == "Axis1")
            pollers = [helper("--poller", str(port), str(axis1)) for _ in range(POLLERS)]
            helpers += pollers
            for p in pollers:
                assert p.stdout is not None
                if p.stdout.readline().strip() != "READY":
                    raise RuntimeError("a poller did not start")
            marks: dict[str, Any] = {}

            async def ready() -> None:
                marks["quiet"] = time.monotonic()  # the abusive client is connected
                await asyncio.sleep(QUIET_SECONDS)
                marks["diag"] = diagnostics(tags)
                marks["cpu"] = cpu_seconds(server.pid)
                marks["start"] = time.monotonic()
                assert wd.stdin is not None
                wd.stdin.write("stop\n")  # the last heartbeat
                wd.stdin.flush()

            requests = asyncio.run(abuse(endpoint, tagmap, args, ready))
            end = time.monotonic()
            cpu = (cpu_seconds(server.pid) - marks["cpu"]) / (end - marks["start"])
            diag_end = diagnostics(tags)
            polled = [finish(p) for p in pollers]
            wd_result = finish(wd)
            tags.close()
            alive = server.proc.poll() is None
        finally:
            for p in helpers:
                if p.poll() is None:
                    p.kill()
            code = server.stop()
        log = server.log()
    errors = [
        line for line in log.splitlines() if " ERROR " in line or line.startswith("Traceback")
    ]
    start = marks["start"]
    before = [lat for p in polled for t, lat in p["samples"] if marks["quiet"] <= t < start]
    during = [lat for p in polled for t, lat in p["samples"] if start <= t <= end]
    d0 = marks["diag"]
    cycles = diag_end["Cycle"] - d0["Cycle"]
    overruns = diag_end["Overruns"] - d0["Overruns"]
    dropped = diag_end["DroppedCycles"] - d0["DroppedCycles"]
    share = overruns / max(cycles + dropped, 1.0)  # late among those due (dropped are late)

    print(f"\nabuse: {end - start:.1f} s of wall time, the requests one after the other")
    for r in requests:
        outcome = r.get("result", "") if r["ok"] else f"refused: {r['error']}"
        print(f"  {r['what']}: {r['seconds']:.2f} s; {outcome}")
    print(
        f"scan during the abuse: {cycles + dropped:.0f} cycles due, overruns {overruns:.0f} = "
        f"{share * 100:.2f} % (target <= {MAX_OVERRUN_SHARE * 100:.0f} %), dropped "
        f"{dropped:.0f} (target 0); max cycle time {diag_end['MaxCycleTime']:.0f} us, "
        f"scan load {diag_end['ScanLoad']:.1f} %, front-end restarts "
        f"{diag_end['FrontendRestarts'] - d0['FrontendRestarts']:.0f}"
    )
    print(f"server CPU during the abuse: {cpu * 100:.0f} % of a core (process tree)")
    limit = (TIMEOUT * 1000) + PERIOD_MS
    if wd_result["first_stopping_read_back"]:
        # from the answer to the last heartbeat: the Modbus front-end answers a write once
        # it has handed it to the scan's queue, so the server has the beat by then
        acked = wd_result["last_beat_acked"]
        lo = (wd_result["last_armed_read_sent"] - acked) * 1000
        hi = (wd_result["first_stopping_read_back"] - acked) * 1000
        trip = wd_result["last_beat_acked"] - wd_result["last_beat_sent"]
        verdict = "met" if hi <= limit else ("missed" if lo > limit else "not shown")
        print(
            f"watchdog: the stop began {lo:.1f} to {hi:.1f} ms after the last heartbeat was "
            f"taken (target <= {limit:.0f} ms: {verdict}); {lo + trip * 1000:.1f} to "
            f"{hi + trip * 1000:.1f} ms after it was sent (round trip {trip * 1000:.2f} ms); "
            f"state {wd_result['state']}, trips {wd_result['trips']}, {wd_result['reads']} "
            "state reads"
        )
    else:
        print(
            f"watchdog: no stop seen within 30 s of the last heartbeat (state "
            f"{wd_result['state']}): target missed"
        )
    print(
        f"Modbus FC3, {POLLERS} clients, {POLL_REGISTERS} registers every "
        f"{POLL_EVERY * 1000:.0f} ms each:"
    )
    print("  " + latency_line("before the abuse", before))
    print("  " + latency_line("during the abuse", during))
    p99 = percentile(during, 0.99) * 1000 if during else float("inf")
    print(
        f"  p99 during / target ({MAX_FC3_P99_MS:.0f} ms): {p99 / MAX_FC3_P99_MS:.2f} "
        f"(target <= 1.00); client errors {sum(p['errors'] for p in polled)}"
    )
    print(
        f"server: {'up' if alive else 'DOWN'} after the abuse, exit code {code}; "
        f"{len(errors)} ERROR/Traceback lines in its log"
    )
    for line in errors[:10]:
        print("  ", line[:200])
    print(f"load average after: {load_average()}")
    return 0


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--poller":
        poller(int(sys.argv[2]), int(sys.argv[3]))
        return 0
    if len(sys.argv) > 1 and sys.argv[1] == "--watchdog":
        watchdog(int(sys.argv[2]), sys.argv[3])
        return 0
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reads", type=int, default=50_000, help="node ids in the Read")
    p.add_argument("--references", type=int, default=30_000, help="references to browse")
    p.add_argument("--items", type=int, default=20_000, help="monitored items to create")
    p.add_argument(
        "--no-limits",
        action="store_true",
        help="lift the OPC UA operation limits so that the front-end processes every request",
    )
    return run(p.parse_args())


if __name__ == "__main__":
    sys.exit(main())
