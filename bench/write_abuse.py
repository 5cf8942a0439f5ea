"""Write abuse: operator clients toggling the heaviest instructions as fast as they can.

The server runs as users start it (``motion-server run``, Modbus only) on a map of 256
virtual axes in one group at a 1 ms period in real time. Each of 4 operator clients owns
an MAJ, an MAM, an MC_GearInPos, an MAH, an MGS (fast stop of the group) and an MGSR, and
toggles their triggers (FC6: 1, then 0) one after the other, one request in flight, as
fast as the server answers, for ``--seconds``. Meanwhile a reader polls 20 registers
(FC3) every 10 ms, and a heartbeat client writes ``WD1.Heartbeat`` every 100 ms (the
watchdog, 0.5 s, fast stop of the group) until 2 s before the end; then it times the trip
as ``overload.py`` does (the bounds between the last read that showed the watchdog armed
and the first that showed it stopping, counted from the answer to the last beat).

Before the abuse every axis is enabled and jogging, so the stops have work to do.
Measured over the abuse: overruns as a share of the cycles due, dropped cycles, the longest
cycle (``Diagnostics.MaxCycleTime``), the writes/s the clients got through, the reader's
p50/p99/max and the watchdog's delay. ``--base DIR`` runs the same against the code in
DIR (a checkout's ``server`` directory, through ``PYTHONPATH``) first, and prints both
side by side. Targets (issue 25): overruns <= 0.1 %, the stop within timeout + 1 cycle.

Usage: ``python bench/write_abuse.py [--seconds 30] [--base OLD/server]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import (
    MODBUS_PORT,
    RawClient,
    ServerProcess,
    TagClient,
    load_average,
    percentile,
)
from motion_server import config
from motion_server.tagmap import build_tagmap

AXES = 256
CLIENTS = 4
PERIOD_MS = 1.0
TIMEOUT = 0.5
HEARTBEAT_EVERY = 0.1
POLL_EVERY = 0.010
#: seconds the helpers get to start before the abuse does
STARTUP = 8.0
#: (instance prefix, type, operands of client c)
HEAVY = [
    ("MAJ", "MAJ", lambda c: f"Axis = {c}, Speed = 50.0, AccelRate = 1000.0, DecelRate = 1000.0"),
    (
        "MAM",
        "MAM",
        lambda c: (
            f"Axis = {64 + c}, Position = 5.0, MoveType = 1, Speed = 50.0, "
            "AccelRate = 1000.0, DecelRate = 1000.0"
        ),
    ),
    (
        "GIP",
        "MC_GearInPos",
        lambda c: (
            f"Master = {c}, Slave = {128 + c}, MasterSyncPosition = 100.0, SlaveSyncPosition = 50.0"
        ),
    ),
    ("MAH", "MAH", lambda c: f"Axis = {192 + c}"),
    ("MGS", "MGS", lambda c: "Group = 1, StopMode = 1"),
    ("MGSR", "MGSR", lambda c: "Group = 1"),
]


def site_text(budget: int | None = None) -> str:
    """The site map; ``budget``: its ``write_budget`` (the default when None)."""
    line = "" if budget is None else f"write_budget = {budget}\n"
    out = [
        '[site]\nname = "write_abuse"\n',
        f'[controller]\nclock = "realtime"\nstatus_log_interval = 0.0\n{line}',
        "[modbus]\nport = 0\naxis_base = 1000\ninstruction_base = 40000\n",
        "[opcua]\nenabled = false\n",
        f'[[groups]]\nname = "Group1"\ncoarse_update_period_ms = {PERIOD_MS}\naxes = ['
        + ", ".join(f'"Axis{k}"' for k in range(1, AXES + 1))
        + "]\n",
    ]
    for k in range(1, AXES + 1):
        out.append(
            f'[[axes]]\nname = "Axis{k}"\ntype = "virtual"\nmax_velocity = 2000.0\n'
            "max_acceleration = 10000.0\nmax_deceleration = 10000.0\n"
        )
    out.append("[instructions]\nevery_type = false\n")
    out.append('[[instructions.instances]]\nname = "MSO_ALL"\ntype = "MSO"\n')
    out.append(
        '[[instructions.instances]]\nname = "MAJ_ALL"\ntype = "MAJ"\n'
        "operands = { Speed = 20.0, AccelRate = 1000.0, DecelRate = 1000.0 }\n"
    )
    for c in range(1, CLIENTS + 1):
        for prefix, kind, operands in HEAVY:
            out.append(
                f'[[instructions.instances]]\nname = "{prefix}_{c}"\ntype = "{kind}"\n'
                f"operands = {{ {operands(c)} }}\n"
            )
    out.append(
        f'[[watchdogs]]\nname = "WD1"\ntimeout = {TIMEOUT}\ngroup = "Group1"\n'
        'stop_mode = "fast_stop"\n'
    )
    return "\n".join(out)


def tags_of(site_file: str) -> Any:
    return build_tagmap(config.parse(Path(site_file).read_text(), site_file))


# -- helper processes -------------------------------------------------------------------------
def wait_until(start: float) -> None:
    time.sleep(max(0.0, start - time.monotonic()))


def toggler(port: int, site_file: str, client: int, start: float, until: float, only: str) -> None:
    """Toggle the client's heavy instructions (those named in ``only``, comma-separated)
    from ``start`` until ``until`` (monotonic); one JSON line."""
    tagmap = tags_of(site_file)
    raw = RawClient(port, timeout=30)
    triggers = []
    for prefix in only.split(","):
        tag = tagmap.tag(f"{prefix}_{client}.Execute")
        triggers.append((tag.address, 1 << (tag.bit or 0)))
    writes = errors = 0
    late = max(0.0, time.monotonic() - start)
    wait_until(start)
    while time.monotonic() < until:
        for address, bit in triggers:
            for value in (bit, 0):
                try:
                    raw.write(address, value)
                    writes += 1
                except (OSError, RuntimeError):
                    errors += 1
    print(json.dumps({"writes": writes, "errors": errors, "late": late}), flush=True)


def reader(port: int, address: int, start: float, until: float) -> None:
    raw = RawClient(port, timeout=30)
    samples: list[float] = []
    wait_until(start)
    next_at = time.monotonic()
    while time.monotonic() < until:
        time.sleep(max(0.0, next_at - time.monotonic()))
        t0 = time.monotonic()
        raw.read(address, 20)
        samples.append(time.monotonic() - t0)
        next_at += POLL_EVERY
    print(json.dumps({"samples": samples}), flush=True)


def heartbeat(port: int, site_file: str, stop_at: float) -> None:
    """Beat until ``stop_at``, then time the trip (see the module)."""
    tags = TagClient(port, tags_of(site_file), timeout=30)
    beat = 0
    sent = acked = 0.0
    while time.monotonic() < stop_at:
        beat += 1
        sent = time.monotonic()
        tags.write("WD1.Heartbeat", beat)
        acked = time.monotonic()
        time.sleep(HEARTBEAT_EVERY)
    last_armed, first_stopping, state = acked, 0.0, 1
    while time.monotonic() < sent + 30.0:
        t0 = time.monotonic()
        state = int(tags.read("WD1.State"))
        t1 = time.monotonic()
        if state != 1:
            first_stopping = t1
            break
        last_armed = t0
        if t1 - acked < TIMEOUT - 0.05:
            time.sleep(0.001)
    print(
        json.dumps(
            {
                "after_ack": [last_armed - acked, first_stopping - acked],
                "after_send": [last_armed - sent, first_stopping - sent],
                "state": state,
            }
        ),
        flush=True,
    )


def helper(*args: str, env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, __file__, *args], stdout=subprocess.PIPE, text=True, env=env
    )


def result(proc: subprocess.Popen[str]) -> dict[str, Any]:
    out, _ = proc.communicate(timeout=300)
    data: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    return data


# -- one run ----------------------------------------------------------------------------------
def diagnostics(tags: TagClient) -> dict[str, float]:
    return {
        f: float(tags.read(f"Diagnostics.{f}"))  # type: ignore[arg-type]
        for f in ("Overruns", "DroppedCycles", "MaxCycleTime")
    } | {"Cycle": float(tags.read("Clock.Cycle"))}  # type: ignore[arg-type]


def setup(tags: TagClient) -> None:
    """Every axis enabled, then jogging."""
    for name in ("MSO_ALL", "MAJ_ALL"):
        for k in range(1, AXES + 1):
            tags.write(f"{name}.Axis", k)
            tags.write(f"{name}.Execute", True)
            time.sleep(0.003)  # a cycle sees the rising edge
            tags.write(f"{name}.Execute", False)
            time.sleep(0.003)  # and one the falling edge: else the next one is lost


def run(
    label: str,
    pythonpath: str,
    seconds: float,
    tmp: Path,
    clients: int = CLIENTS,
    budget: int | None = None,
    only: str = ",".join(p for p, _, _ in HEAVY),
) -> dict[str, Any]:
    env = dict(os.environ, PYTHONPATH=pythonpath)
    site = tmp / f"{label.replace(' ', '_')}.toml"
    site.write_text(site_text(budget))
    saved = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = pythonpath
    try:
        server = ServerProcess(
            ["-m", "motion_server.cli", "run", str(site)], MODBUS_PORT, log=site.with_suffix(".log")
        )
    finally:
        if saved is None:
            del os.environ["PYTHONPATH"]
        else:
            os.environ["PYTHONPATH"] = saved
    port = server.port
    try:
        tagmap = tags_of(str(site))
        tags = TagClient(port, tagmap, timeout=30)
        setup(tags)
        time.sleep(0.5)
        # the helpers start (imports, the tag map) before the abuse does
        start = time.monotonic() + STARTUP
        until = start + seconds
        hb = helper("heartbeat", str(port), str(site), str(until - 2.0), env=env)
        togglers = [
            helper("toggler", str(port), str(site), str(c), str(start), str(until), only, env=env)
            for c in range(1, clients + 1)
        ]
        address = tagmap.tag("Axis1.ActualPosition").address
        rd = helper("reader", str(port), str(address), str(start), str(until), env=env)
        wait_until(start)
        before = diagnostics(tags)
        writes = [result(p) for p in togglers]
        wait_until(until)
        elapsed = time.monotonic() - start
        after = diagnostics(tags)
        late = max((w["late"] for w in writes), default=0.0)
        if late:
            print(f"  ({label}: a client started {late:.1f} s late)", flush=True)
        reads = result(rd)["samples"]
        wd = result(hb)
        tags.close()
    finally:
        server.stop()
    cycles = after["Cycle"] - before["Cycle"]
    dropped = after["DroppedCycles"] - before["DroppedCycles"]
    overruns = after["Overruns"] - before["Overruns"]
    due = cycles + dropped
    return {
        "label": label,
        "due": due,
        "overruns": overruns,
        "share": overruns / due if due else 0.0,
        "dropped": dropped,
        "max_cycle_us": after["MaxCycleTime"],
        "writes_s": sum(w["writes"] for w in writes) / elapsed if writes else 0.0,
        "errors": sum(w["errors"] for w in writes),
        "p50": percentile(reads, 0.5) * 1000,
        "p99": percentile(reads, 0.99) * 1000,
        "max": max(reads) * 1000,
        "wd": wd,
    }


def show(r: dict[str, Any]) -> str:
    lo, hi = r["wd"]["after_ack"]
    stop = f"{lo * 1000:.1f}–{hi * 1000:.1f} ms" if hi > 0 else "not seen"
    return (
        f"| {r['label']} | {r['share'] * 100:.2f} % ({r['overruns']:.0f} of {r['due']:.0f}) "
        f"| {r['dropped']:.0f} | {r['max_cycle_us'] / 1000:.2f} ms | {r['writes_s']:.0f} "
        f"| {r['p50']:.2f} / {r['p99']:.2f} / {r['max']:.1f} ms | {stop} |"
    )


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] in ("toggler", "reader", "heartbeat"):
        kind, args = sys.argv[1], sys.argv[2:]
        if kind == "toggler":
            toggler(int(args[0]), args[1], int(args[2]), float(args[3]), float(args[4]), args[5])
        elif kind == "reader":
            reader(int(args[0]), int(args[1]), float(args[2]), float(args[3]))
        else:
            heartbeat(int(args[0]), args[1], float(args[2]))
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--base", help="the server directory of the code to compare with")
    parser.add_argument("--clients", type=int, default=CLIENTS, help="0: the idle reference")
    parser.add_argument("--budget", type=int, nargs="*", default=[], help="write_budget values")
    parser.add_argument(
        "--only",
        default=",".join(p for p, _, _ in HEAVY),
        help="the instructions toggled (comma-separated: MAJ,MAM,GIP,MAH,MGS,MGSR)",
    )
    parser.add_argument("--logs", help="keep the site maps and the servers' logs in this directory")
    args = parser.parse_args()
    here = str(Path(__file__).resolve().parent.parent / "server")
    print(f"load average before: {load_average()}", flush=True)
    results = []
    with tempfile.TemporaryDirectory(prefix="write-abuse-") as scratch:
        tmp = args.logs or scratch  # the site maps and the servers' logs
        Path(tmp).mkdir(parents=True, exist_ok=True)
        runs: list[tuple[str, str, int | None]] = []
        if args.base:
            runs.append(("base", args.base, None))
        runs.append(("budget (default)", here, None))
        runs += [(f"budget {b}", here, b) for b in args.budget]
        for label, path, budget in runs:
            results.append(
                run(label, path, args.seconds, Path(tmp), args.clients, budget, args.only)
            )
            print(show(results[-1]), flush=True)
    print(f"load average after: {load_average()}")
    print(
        "| code | overruns (of cycles due) | dropped | longest cycle | writes/s | "
        "reader p50 / p99 / max | watchdog stop after the last beat |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in results:
        print(show(r))
    print(f"targets: overruns <= 0.1 %; stop within {TIMEOUT * 1000 + PERIOD_MS:.0f} ms")


if __name__ == "__main__":
    main()
