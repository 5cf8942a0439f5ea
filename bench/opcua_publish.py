"""OPC UA publishing under load: motion-server vs a bare asyncua server, side by side.

- **motion-server**, run as users start it (``motion-server run``: a supervisor, the scan
  and one front-end per protocol, each a process of its own): a generated site map of
  ``--axes`` (default 334) servo axes, all jogging at 123.4567 mm/s (started one by one
  over Modbus, which is served for that set-up only, by retriggering one MSO and one MAJ
  instance with another Axis operand), at a 2 ms cycle in realtime. At a constant speed
  three analog tags of every axis change at every publishing pass (CommandPosition,
  ActualPosition, PositionError: the drive's quantised following error); the velocities
  do not, so the subscriber watches those three: 1,000 tags. Published at the default
  20 Hz.
- **bare asyncua**: 1,000 Double variables that a loop rewrites with ``Node.write_value``
  at the same 20 Hz (the naive pattern), plus Execute/EN/DN variables that the loop
  handles like an MSO: it reads Execute each pass and sets EN and DN on its rising edge.

Each server runs in processes of its own; both on the None endpoint with anonymous
sessions (loopback), so the comparison is about publishing, not cryptography. While one
subscriber process (its own process too) counts the notifications of 1,000 monitored
items (queue size 1) at a 100 ms publishing interval, this process measures the latency
from writing ``Execute`` = true to reading EN and DN both true (after having read EN
false once Execute was written false), with a random phase before each write.

It prints, per server: notifications/s delivered, write -> DN p50/p99/max, and the CPU
of the server's process tree (the sum over the supervisor and its children, in % of
one core); for motion-server also Diagnostics.Overruns (late cycles, as a share of the
cycles due in the window: those run and those dropped) and DroppedCycles (beyond the
``max_catch_up`` = 50 late cycles the scan runs back to back). Targets: overruns <=
0.1 % of cycles, write -> DN p99 <= 10 ms, notifications/s >= 9,650 (what the
single-process server delivered; at most 10,000 can be), 0 dropped cycles; the ratio to
the naive server is printed too.

:mod:`write_to_done` imports the site map, the jog start and the subscriber from here to
run this load while it measures Modbus latency.

Usage: ``python bench/opcua_publish.py [--axes 334] [--seconds 20] [--rounds 1]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import random
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import (
    MODBUS_PORT,
    OPCUA_ENDPOINT,
    ServerProcess,
    TagClient,
    cpu_seconds,
    load_average,
    percentile,
)
from motion_server import config
from motion_server.tagmap import TagMap, build_tagmap

#: the analog tags of a jogging axis that change at every pass (constant speed)
ANALOG = ("CommandPosition", "ActualPosition", "PositionError")
TAGS = 1000
SPEED = 123.4567
NS_URI = "urn:motion-server:bench-opcua"
PUBLISHING_INTERVAL_MS = 100.0
#: targets (the single-process server delivered about 9,650 notifications/s)
MAX_OVERRUN_SHARE = 0.001
MAX_P99_MS = 10.0
MIN_NOTIFICATIONS = 9650.0
#: asyncua clients disconnect when a server-state read takes longer than this (default
#: 1 s): the naive server, busy rewriting its variables, misses that under this load
WATCHDOG_S = 60.0


# -- the site map ---------------------------------------------------------------------------
def site_map(
    axes: int,
    data_dir: Path,
    publish_hz: float = 20.0,
    chunk: int = 100,
    modbus: bool = False,
) -> str:
    """A site map with ``axes`` servo axes, MSO_1 and MAJ_1 to start them, and MSO_LAT (on
    Axis1, already on: MSO on an enabled axis does nothing but set DN) for the latency.
    ``modbus``: serve Modbus TCP too (on an ephemeral port)."""
    out = [
        f'[site]\nname = "bench_opcua"\nnamespace_uri = "{NS_URI}"\n',
        '[controller]\nclock = "realtime"\nstatus_log_interval = 0.0\n',
        f"[modbus]\nenabled = {str(modbus).lower()}\nport = 0\naxis_base = 1000\n"
        "instruction_base = 40000\n",
        f'[opcua]\nport = 0\ndata_dir = "{data_dir}"\nallow_anonymous = true\n'
        'anonymous_role = "operator"\nallow_none_endpoint = true\n'
        f"publish_rate_hz = {publish_hz}\nchunk_size = {chunk}\n",
        '[[groups]]\nname = "Group1"\ncoarse_update_period_ms = 2.0\naxes = ['
        + ", ".join(f'"Axis{k}"' for k in range(1, axes + 1))
        + "]\n",
    ]
    for k in range(1, axes + 1):
        out.append(
            f'[[axes]]\nname = "Axis{k}"\ntype = "servo"\nmax_velocity = 2000.0\n'
            "max_acceleration = 10000.0\nmax_deceleration = 10000.0\n"
        )
    out.append("[instructions]\nevery_type = false\n")
    out.append('[[instructions.instances]]\nname = "MSO_1"\ntype = "MSO"\n')
    out.append(
        '[[instructions.instances]]\nname = "MAJ_1"\ntype = "MAJ"\n'
        f"operands = {{ Speed = {SPEED}, AccelRate = 10000.0, DecelRate = 10000.0 }}\n"
    )
    out.append(
        '[[instructions.instances]]\nname = "MSO_LAT"\ntype = "MSO"\noperands = { Axis = 1 }\n'
    )
    return "\n".join(out)


# -- the bare asyncua server (its own process) ----------------------------------------------
def bare_server(port: int, count: int, publish_hz: float) -> None:
    """asyncua with ``count`` Double variables rewritten naively at ``publish_hz``."""
    import logging

    from asyncua import Server, ua

    logging.basicConfig(level=logging.WARNING)

    async def main() -> None:
        server = Server()
        await server.init()
        server.set_endpoint(f"opc.tcp://127.0.0.1:{port}/")
        server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        ns = await server.register_namespace(NS_URI)
        folder = await server.nodes.objects.add_folder(ua.NodeId("Bare", ns), "Bare")
        nodes = [
            await folder.add_variable(ua.NodeId(f"Bare.V{i}", ns), f"V{i}", 0.0)
            for i in range(count)
        ]
        execute = await folder.add_variable(ua.NodeId("Bare.Execute", ns), "Execute", False)
        await execute.set_writable()
        en = await folder.add_variable(ua.NodeId("Bare.EN", ns), "EN", False)
        dn = await folder.add_variable(ua.NodeId("Bare.DN", ns), "DN", False)
        async with server:
            print(f"BARE on opc.tcp://127.0.0.1:{port}/", file=sys.stderr, flush=True)
            period = 1.0 / publish_hz
            loop = asyncio.get_running_loop()
            deadline = loop.time()
            last = False
            n = 0
            while True:
                rung = bool(await execute.read_value())
                if rung and not last:
                    await en.write_value(True)
                    await dn.write_value(True)
                elif not rung and last:
                    await en.write_value(False)
                last = rung
                n += 1
                for i, node in enumerate(nodes):
                    await node.write_value(float(n * 1000 + i))
                deadline += period
                now = loop.time()
                if deadline < now:
                    deadline = now  # behind: run back to back, never catch up
                await asyncio.sleep(deadline - now)

    asyncio.run(main())


# -- the subscriber (its own process) -------------------------------------------------------
def subscriber(endpoint: str, node_ids: list[str], warmup: float, seconds: float) -> None:
    """Subscribe to ``node_ids`` (queue size 1, PUBLISHING_INTERVAL_MS); print one JSON
    line with the notifications counted during ``seconds`` after ``warmup`` (``seconds``
    <= 0: until standard input closes)."""
    from asyncua import Client, ua

    class Count:
        def __init__(self) -> None:
            self.n = 0

        def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
            self.n += 1

        def status_change_notification(self, status: Any) -> None:
            print(f"subscription status: {status}", file=sys.stderr, flush=True)

    async def main() -> None:
        client = Client(endpoint, timeout=30, watchdog_intervall=WATCHDOG_S)
        async with client:
            ns = await client.get_namespace_index(NS_URI)
            count = Count()
            sub = await client.create_subscription(PUBLISHING_INTERVAL_MS, count)
            nodes = [client.get_node(ua.NodeId(n, ns)) for n in node_ids]
            await sub.subscribe_data_change(nodes, queuesize=1)
            print("READY", flush=True)
            await asyncio.sleep(warmup)
            n0, t0 = count.n, time.perf_counter()
            if seconds > 0:
                await asyncio.sleep(seconds)
            else:
                await asyncio.get_running_loop().run_in_executor(None, sys.stdin.read)
            n1, t1 = count.n, time.perf_counter()
            print(json.dumps({"notifications": n1 - n0, "seconds": t1 - t0}), flush=True)
            await sub.delete()

    asyncio.run(main())


# -- the orchestrator -----------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def start(args: list[str], log: Path, pattern: str = MODBUS_PORT) -> ServerProcess:
    """Start a server process (standard error to ``log``); ``.found``: what ``pattern``
    matched first (motion-server's Modbus port, the bare server's endpoint)."""
    return ServerProcess(args, pattern, log=log)


async def probe_latency(
    endpoint: str, prefix: str, seconds: float, start_after: float
) -> list[float]:
    """Write → EN and DN latencies (s) of the instance at ``prefix`` during ``seconds``."""
    from asyncua import Client, ua

    async with Client(endpoint, timeout=30, watchdog_intervall=WATCHDOG_S) as client:
        ns = await client.get_namespace_index(NS_URI)
        execute = client.get_node(ua.NodeId(f"{prefix}.Execute", ns))
        bits = [ua.NodeId(f"{prefix}.EN", ns), ua.NodeId(f"{prefix}.DN", ns)]

        async def read_bits() -> tuple[bool, bool]:
            params = ua.ReadParameters()
            for nid in bits:
                rv = ua.ReadValueId()
                rv.NodeId = nid
                rv.AttributeId = ua.AttributeIds.Value
                params.NodesToRead.append(rv)
            values = await client.uaclient.read(params)
            return bool(values[0].Value.Value), bool(values[1].Value.Value)

        async def write(value: bool) -> None:
            await execute.write_value(ua.DataValue(ua.Variant(value, ua.VariantType.Boolean)))

        await asyncio.sleep(start_after)
        samples: list[float] = []
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            await write(False)
            while (await read_bits())[0]:
                await asyncio.sleep(0.001)
            await asyncio.sleep(random.uniform(0.0, 0.05))  # a random phase
            t0 = time.perf_counter()
            await write(True)
            while (await read_bits()) != (True, True):
                await asyncio.sleep(0.001)
            samples.append(time.perf_counter() - t0)
        return samples


async def read_values(endpoint: str, node_ids: list[str]) -> list[Any]:
    from asyncua import Client, ua

    async with Client(endpoint, timeout=30, watchdog_intervall=WATCHDOG_S) as client:
        ns = await client.get_namespace_index(NS_URI)
        return [await client.get_node(ua.NodeId(n, ns)).read_value() for n in node_ids]


def start_jogs(port: int, tagmap: TagMap, axes: int) -> None:
    """MSO_1 then MAJ_1 on every axis in turn, over Modbus (set-up only). Each level of
    Execute is written once the image shows that the scan took the previous one: a scan
    that runs late applies every write that waited in one cycle, which would merge a
    false and a true into no edge at all. Then check that every axis jogs."""
    tags = TagClient(port, tagmap, timeout=30)

    def until(name: str, value: bool) -> None:
        give_up = time.monotonic() + 30
        while tags.read(name) != value:
            if time.monotonic() > give_up:
                raise RuntimeError(f"{name} did not become {value}")

    try:
        for k in range(1, axes + 1):
            for name in ("MSO_1", "MAJ_1"):
                tags.write(f"{name}.Axis", k)
                tags.write(f"{name}.Execute", False)
            for name in ("MSO_1", "MAJ_1"):
                until(f"{name}.EN", False)
            for name in ("MSO_1", "MAJ_1"):
                tags.write(f"{name}.Execute", True)
                until(f"{name}.EN", True)  # the cycle that saw the edge
                if tags.read(f"{name}.ER"):
                    raise RuntimeError(f"{name} on Axis{k}: ERR {tags.read(f'{name}.ERR')}")
        time.sleep(0.1)
        slow = [
            k
            for k in range(1, axes + 1)
            if abs(float(tags.read(f"Axis{k}.CommandVelocity")) - SPEED) > 1e-3
        ]
        if slow:
            raise RuntimeError(f"axes {slow[:10]} do not jog")
    finally:
        tags.close()


def run_subscriber(
    endpoint: str, node_ids: list[str], warmup: float, seconds: float, tmp: Path
) -> subprocess.Popen[str]:
    """The subscriber process; ``seconds`` <= 0: it counts until its stdin is closed.
    Its first line is READY once its monitored items exist; its last, the count."""
    ids = tmp / "node_ids.json"
    ids.write_text(json.dumps(node_ids))
    return subprocess.Popen(
        [sys.executable, __file__, "--subscriber", endpoint, str(ids), str(warmup), str(seconds)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )


def subscriber_ready(sub: subprocess.Popen[str], name: str) -> None:
    assert sub.stdout is not None
    if sub.stdout.readline().strip() != "READY":
        raise RuntimeError(f"{name}: the subscriber did not start")


def subscriber_count(sub: subprocess.Popen[str]) -> float:
    """Notifications per second the subscriber counted (closes its stdin first)."""
    out, _ = sub.communicate(timeout=120)
    counted = json.loads(out.strip().splitlines()[-1])
    return float(counted["notifications"] / counted["seconds"])


def monitored_tags(axes: int) -> list[str]:
    """The node ids the subscriber monitors on the generated map (TAGS of them)."""
    return [f"Axes.Axis{k}.{f}" for k in range(1, axes + 1) for f in ANALOG][:TAGS]


def measure(
    name: str,
    endpoint: str,
    pid: int,
    node_ids: list[str],
    prefix: str,
    seconds: float,
    tmp: Path,
) -> dict[str, Any]:
    warmup = 3.0
    sub = run_subscriber(endpoint, node_ids, warmup, seconds, tmp)
    subscriber_ready(sub, name)
    cpu0, t0 = cpu_seconds(pid), time.perf_counter()
    lat = asyncio.run(probe_latency(endpoint, prefix, seconds, warmup))
    notif_per_s = subscriber_count(sub)
    cpu = (cpu_seconds(pid) - cpu0) / (time.perf_counter() - t0)
    return {
        "server": name,
        "notif_per_s": notif_per_s,
        "samples": len(lat),
        "p50_ms": percentile(lat, 0.50) * 1000,
        "p99_ms": percentile(lat, 0.99) * 1000,
        "max_ms": max(lat) * 1000,
        "cpu": cpu,
    }


DIAGNOSTICS = [
    "Diagnostics.Overruns",
    "Diagnostics.DroppedCycles",
    "Clock.Cycle",
    "Diagnostics.ScanLoad",
    "Diagnostics.CycleTime",
]


def bench_motion_server(args: argparse.Namespace, tmp: Path) -> dict[str, Any]:
    axes, seconds = args.axes, args.seconds
    site = tmp / "bench-opcua.toml"
    text = site_map(axes, tmp / "opcua-data", args.publish_hz, args.chunk, modbus=True)
    site.write_text(text)
    server = start(["-m", "motion_server.cli", "run", str(site)], tmp / "motion-server.log")
    try:
        endpoint = server.wait_for(OPCUA_ENDPOINT)
        t = time.perf_counter()
        start_jogs(server.port, build_tagmap(config.parse(text, str(site))), axes)
        print(f"{axes} axes jogging after {time.perf_counter() - t:.1f} s", flush=True)
        before = asyncio.run(read_values(endpoint, DIAGNOSTICS))
        result = measure(
            "motion-server",
            endpoint,
            server.pid,
            monitored_tags(axes),
            "Instructions.MSO_LAT",
            seconds,
            tmp,
        )
        after = asyncio.run(read_values(endpoint, DIAGNOSTICS))
        result["overruns"] = after[0] - before[0]
        result["dropped"] = after[1] - before[1]
        result["cycles"] = after[2] - before[2]
        result["scan_load"] = after[3]
        result["cycle_us"] = after[4]
        result["processes"] = len(server.tree())
        return result
    finally:
        server.stop()


def bench_bare(args: argparse.Namespace, tmp: Path) -> dict[str, Any]:
    seconds = args.seconds
    count = min(args.axes * len(ANALOG), TAGS)
    port = _free_port()
    server = start(
        [__file__, "--bare", str(port), str(count), str(args.publish_hz)],
        tmp / "bare.log",
        r"BARE on (opc\.tcp://[\d.]+:\d+/)",
    )
    try:
        nodes = [f"Bare.V{i}" for i in range(count)]
        result = measure("bare asyncua", server.found, server.pid, nodes, "Bare", seconds, tmp)
        result["processes"] = len(server.tree())
        return result
    finally:
        server.stop()


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--bare":
        bare_server(int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]))
        return
    if len(sys.argv) > 1 and sys.argv[1] == "--subscriber":
        ids = json.loads(Path(sys.argv[3]).read_text())
        subscriber(sys.argv[2], ids, float(sys.argv[4]), float(sys.argv[5]))
        return
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--axes", type=int, default=334, help="jogging axes (3 analog tags each)")
    p.add_argument("--seconds", type=float, default=20.0, help="measured window per server")
    p.add_argument("--rounds", type=int, default=1, help="alternating rounds")
    p.add_argument(
        "--publish-hz", type=float, default=20.0, help="server update rate (both servers)"
    )
    p.add_argument(
        "--chunk", type=int, default=100, help="motion-server's [opcua] chunk_size (its default)"
    )
    args = p.parse_args()
    count = min(args.axes * len(ANALOG), TAGS)
    print(f"load average before: {load_average()}")
    results: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="bench-opcua-") as d:
        tmp = Path(d)
        for _ in range(args.rounds):
            for bench in (bench_motion_server, bench_bare):
                results.append(bench(args, tmp))
                print(json.dumps(results[-1]), flush=True)
    print(
        f"{count} analog tags changing, servers updating at {args.publish_hz:g} Hz "
        f"(motion-server chunk {args.chunk}), subscriber "
        f"at {PUBLISHING_INTERVAL_MS:.0f} ms (queue 1): at most "
        f"{count * 1000 / PUBLISHING_INTERVAL_MS:.0f} notifications/s"
    )
    for r in results:
        extra = ""
        if "overruns" in r:
            share = r["overruns"] / max(r["cycles"] + r["dropped"], 1)
            extra = (
                f"\n{'':>16}overruns {r['overruns']} in {r['cycles'] + r['dropped']} cycles = "
                f"{share * 100:.3f} % (target <= {MAX_OVERRUN_SHARE * 100:.1f} %), "
                f"dropped {r['dropped']} (target 0); at the end: scan load "
                f"{r['scan_load']:.0f} %, last cycle {r['cycle_us']:.0f} us"
            )
        print(
            f"{r['server']:>14}: {r['notif_per_s']:8.0f} notif/s; write -> DN p50 "
            f"{r['p50_ms']:6.1f} ms, p99 {r['p99_ms']:6.1f} ms, max {r['max_ms']:6.1f} ms "
            f"({r['samples']} samples); server CPU {r['cpu'] * 100:.0f} % of a core "
            f"({r['processes']} processes){extra}"
        )
    ours = [r for r in results if r["server"] == "motion-server"]
    bare = [r for r in results if r["server"] != "motion-server"]
    ours_rate = sum(r["notif_per_s"] for r in ours) / len(ours)
    ratio = sum(r["notif_per_s"] for r in ours) / max(sum(r["notif_per_s"] for r in bare), 1.0)
    p99 = max(r["p99_ms"] for r in ours)
    print(
        f"motion-server: {ours_rate:.0f} notifications/s (target >= {MIN_NOTIFICATIONS:.0f}); "
        f"write -> DN p99 {p99:.1f} ms (target <= {MAX_P99_MS:.0f} ms)"
    )
    print(f"notifications/s ratio motion-server / bare: {ratio:.2f} (single-process server: ~6)")
    print(f"load average after: {load_average()}")


if __name__ == "__main__":
    main()
