"""Soak: 5 Modbus and 5 OPC UA clients against the real server for a given duration.

    python bench/soak.py --duration 1200     # 20 minutes (CI: --duration 120)

The server runs as users start it: ``motion-server run`` on a site map written to a
temporary directory (realtime clock, 2 ms cycles), a supervisor with the scan and one
process per protocol. A jog on Axis1 and a gear on Axis2 (started over Modbus) run the
whole time; the clients run in two child processes of this one, one per protocol. Per
protocol: four clients stay connected (Modbus: FC3 reads of a status block and an
operand write every 50 reads; OPC UA: a secure session with a subscription and reads),
one connects, reads and disconnects in a loop.

Reported, each summed over the server's process tree (the supervisor and its children):
resident memory after warm-up (a quarter of the run) and at the end (growth target
< 10 %), and open file descriptors before the clients and after they left (must be back
to baseline). Then, read over Modbus from ``Diagnostics``: cycles, overruns, dropped
cycles (must be 0), the longest cycle, front-end restarts (must be 0); client errors
(must be 0) and server log errors (ERROR or Traceback lines in its standard error:
must be 0). Exit status 1 if a target is missed.

The count of asyncio tasks that earlier versions reported is gone: the server is no
longer one asyncio process (the scan has no event loop; each front-end has its own), so
the descriptors of the whole tree are what shows a leaked connection.
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing as mp
import shutil
import struct
import sys
import tempfile
import time
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from modbus_client import MODBUS_PORT, OPCUA_ENDPOINT, ServerProcess, TagClient, open_fds, rss_kib
from motion_server import config
from motion_server.frontends.opcua_users import hash_password
from motion_server.tagmap import build_tagmap

USER, PASSWORD = "soak", "soak-password"
SITE = """
data_dir = "{data}"
[site]
name = "soak"
[controller]
clock = "realtime"
status_log_interval = 0.0
[modbus]
port = 0
[opcua]
port = 0
data_dir = "{data}/opcua"
publish_rate_hz = 20.0
[[opcua.users]]
name = "{user}"
role = "operator"
password_hash = "{hash}"
[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Axis1", "Axis2"]
[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0
[[axes]]
name = "Axis2"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0
[instructions]
every_type = true
"""


# -- clients (child process) ---------------------------------------------------------------
def modbus_read(port: int, address: int, count: int) -> None:
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 3, address, count))
        got = b""
        while len(got) < 9 + 2 * count:
            chunk = s.recv(4096)
            if not chunk:
                raise ConnectionError("closed")
            got += chunk
        if got[7] != 3:
            raise RuntimeError(f"exception {got[7:9].hex()}")


async def modbus_client(port: int, until: float, status: int, speed: int, reconnect: bool) -> int:
    from pymodbus.client import AsyncModbusTcpClient

    errors = 0
    if reconnect:
        while time.monotonic() < until:
            try:
                await asyncio.to_thread(modbus_read, port, status, 20)
            except Exception:
                errors += 1
            await asyncio.sleep(0.05)
        return errors
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=5)
    if not await client.connect():
        raise ConnectionError(f"Modbus client: cannot connect to port {port}")
    n = 0
    while time.monotonic() < until:
        rr = await client.read_holding_registers(status, count=20, device_id=1)
        errors += rr.isError()
        n += 1
        if n % 50 == 0:  # an operand write: MAJ_1.Speed (REAL, big word order)
            hi, lo = struct.unpack(">HH", struct.pack(">f", 10.0 + n % 7))
            wr = await client.write_registers(speed, [hi, lo], device_id=1)
            errors += wr.isError()
        await asyncio.sleep(0.02)
    client.close()
    return errors


async def opcua_client(endpoint: str, data: Path, until: float, k: int, reconnect: bool) -> int:
    from asyncua import Client, ua
    from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

    async def connect() -> Client:
        c = Client(endpoint, timeout=10)
        c.application_uri = "urn:motion-server:soak"
        cert, key = await c.setup_self_signed_certificate(
            data / f"client{k}-key.pem", data / f"client{k}-cert.der"
        )
        await c.set_security(SecurityPolicyBasic256Sha256, str(cert), str(key))
        c.set_user(USER)
        c.set_password(PASSWORD)
        await c.connect()
        return c

    errors = 0
    ns_uri = "urn:motion-server:soak"

    class Sink:
        def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
            pass

    if reconnect:
        while time.monotonic() < until:
            try:
                c = await connect()
                ns = await c.get_namespace_index(ns_uri)
                await c.get_node(ua.NodeId("Clock.Cycle", ns)).read_value()
                await c.disconnect()
            except Exception:
                errors += 1
            await asyncio.sleep(0.2)
        return errors
    c = await connect()
    ns = await c.get_namespace_index(ns_uri)
    sub = await c.create_subscription(100, Sink())
    nodes = [c.get_node(ua.NodeId(n, ns)) for n in ("Axes.Axis1.CommandPosition", "Clock.Cycle")]
    await sub.subscribe_data_change(nodes)
    while time.monotonic() < until:
        try:
            await nodes[1].read_value()
        except Exception:
            errors += 1
        await asyncio.sleep(0.1)
    await c.disconnect()
    return errors


def run_clients(args: dict[str, Any], protocol: str, out: Any) -> None:
    """The five clients of one protocol (a process per protocol: an OPC UA handshake's
    cryptography, done on the event loop, must not delay the Modbus clients' connects)."""
    import logging

    logging.getLogger("asyncua").setLevel(logging.ERROR)

    async def main() -> list[int]:
        until = time.monotonic() + args["duration"]
        data = Path(args["data"])
        if protocol == "modbus":
            jobs = [
                modbus_client(args["modbus"], until, args["status"], args["speed"], k == 0)
                for k in range(5)
            ]
        else:
            jobs = [opcua_client(args["endpoint"], data, until, k, k == 0) for k in range(5)]
        return list(await asyncio.gather(*jobs, return_exceptions=False))

    try:
        out.put((protocol, asyncio.run(main())))
    except Exception as exc:
        out.put((protocol, repr(exc)))


# -- server and report -----------------------------------------------------------------------
def wait_for_servo(tags: TagClient, axis: str, timeout: float = 5.0) -> None:
    """Poll until ``axis`` is in Servo Control (AxisState 2), as an HMI waits for MSO."""
    end = time.monotonic() + timeout
    while int(tags.read(f"{axis}.AxisState")) != 2:
        if time.monotonic() > end:
            raise RuntimeError(f"{axis} was not enabled within {timeout:g} s")
        time.sleep(0.01)


def start_motion(tags: TagClient) -> None:
    """MSO on Axis1 and Axis2, a jog on Axis1 (10 mm/s), Axis2 geared to it (0.5). Each
    axis is enabled before it is commanded: MAG_1 scans before MSO_1, so a MAG edge that
    reached the same cycle as MSO's would find Axis2 off (ERR 5)."""
    for name, value in [("MSO_1.Axis", 1), ("MAJ_1.Axis", 1), ("MAJ_1.Speed", 10.0)]:
        tags.write(name, value)
    tags.write("MSO_1.Execute", True)
    wait_for_servo(tags, "Axis1")
    tags.write("MSO_1.Axis", 2)
    tags.write("MSO_1.Execute", False)
    time.sleep(0.05)
    tags.write("MSO_1.Execute", True)
    wait_for_servo(tags, "Axis2")
    tags.write("MAJ_1.Execute", True)
    for name, value in [("MAG_1.SlaveAxis", 2), ("MAG_1.MasterAxis", 1), ("MAG_1.Ratio", 0.5)]:
        tags.write(name, value)
    tags.write("MAG_1.Execute", True)
    time.sleep(1.0)
    jog, gear = tags.read("Axis1.CommandVelocity"), tags.read("Axis2.CommandVelocity")
    if abs(float(jog) - 10.0) > 1e-3 or abs(float(gear) - 5.0) > 1e-3:
        raise RuntimeError(f"the motion did not start: Axis1 {jog}, Axis2 {gear} units/s")


def diagnostics(tags: TagClient) -> dict[str, float]:
    names = ["Overruns", "DroppedCycles", "MaxCycleTime", "FrontendRestarts"]
    out = {n: float(tags.read(f"Diagnostics.{n}")) for n in names}
    out["Cycle"] = float(tags.read("Clock.Cycle"))
    return out


def log_errors(text: str) -> list[str]:
    return [line for line in text.splitlines() if " ERROR " in line or "Traceback" in line]


def soak(duration: float) -> int:
    data = Path(tempfile.mkdtemp(prefix="soak-"))
    text = SITE.format(data=data, user=USER, hash=hash_password(PASSWORD, n=2**10))
    site = data / "soak.toml"
    site.write_text(text)
    tagmap = build_tagmap(config.parse(text, str(site)))
    server = ServerProcess(
        ["-m", "motion_server.cli", "run", str(site)], MODBUS_PORT, log=data / "server.log"
    )
    try:
        endpoint = server.wait_for(OPCUA_ENDPOINT)
        tags = TagClient(server.port, tagmap, timeout=10)
        start_motion(tags)
        # the server closes a Modbus connection idle for idle_timeout (60 s): a new one
        # reads the diagnostics at the end
        tags.close()
        base_fds = open_fds(server.pid)
        ctx = mp.get_context("spawn")
        out = ctx.Queue()
        args = {
            "duration": duration,
            "data": str(data),
            "modbus": server.port,
            "endpoint": endpoint,
            "status": tagmap.tag("Axis1.CommandPosition").address,
            "speed": tagmap.tag("MAJ_1.Speed").address,
        }
        procs = [
            ctx.Process(target=run_clients, args=(args, protocol, out), daemon=True)
            for protocol in ("modbus", "opcua")
        ]
        t0 = time.monotonic()
        for proc in procs:
            proc.start()
        warm = max(duration / 4, 10.0)
        time.sleep(warm)
        rss_warm = rss_kib(server.pid)
        samples = [rss_warm]
        while alive := [proc.sentinel for proc in procs if proc.is_alive()]:
            wait(alive, min(30.0, duration / 10))
            samples.append(rss_kib(server.pid))
        results = dict(out.get(True, 60) for _ in procs)
        rss_end = rss_kib(server.pid)
        for proc in procs:
            proc.join(10)
            proc.close()
        out.close()
        out.join_thread()
        time.sleep(3.0)  # connections close, sessions end
        end_fds = open_fds(server.pid)
        tags = TagClient(server.port, tagmap, timeout=10)
        diag = diagnostics(tags)
        tags.close()
        processes = len(server.tree())
    finally:
        code = server.stop()
    errors = log_errors(server.log())
    growth = (rss_end - rss_warm) / rss_warm * 100
    by_modbus, by_opcua = results.get("modbus", "no result"), results.get("opcua", "no result")
    result: list[int] | str
    if isinstance(by_modbus, list) and isinstance(by_opcua, list):
        result = by_modbus + by_opcua
        client_errors = sum(result)
    else:
        result = f"Modbus clients: {by_modbus}; OPC UA clients: {by_opcua}"
        client_errors = -1
    print(
        f"soak {duration:.0f} s (wall {time.monotonic() - t0:.0f} s), 5 Modbus + 5 OPC UA "
        f"clients; server: {processes} processes"
    )
    print(
        f"memory (RSS of the process tree): {rss_warm / 1024:.1f} MiB after {warm:.0f} s "
        f"warm-up, {rss_end / 1024:.1f} MiB at the end: {growth:+.1f} % (target < 10 %)"
    )
    print(f"memory samples (MiB): {' '.join(f'{s / 1024:.1f}' for s in samples)}")
    print(
        f"file descriptors (process tree): {len(base_fds)} before, {len(end_fds)} after "
        "the clients left"
    )
    extra = sorted(set(end_fds.values()) - set(base_fds.values()))
    if extra:
        print(f"   new: {extra[:20]}")
    print(
        f"cycles {diag['Cycle']:.0f}, overruns {diag['Overruns']:.0f} "
        f"({diag['Overruns'] / max(diag['Cycle'] + diag['DroppedCycles'], 1) * 100:.1f} %), "
        "dropped "
        f"{diag['DroppedCycles']:.0f}, max cycle {diag['MaxCycleTime']:.0f} us, front-end "
        f"restarts {diag['FrontendRestarts']:.0f}"
    )
    print(f"client errors: {result}; server log errors: {len(errors)}; server exit code {code}")
    for line in errors[:10]:
        print("  ", line[:200])
    ok = (
        growth < 10.0
        and len(end_fds) <= len(base_fds)
        and diag["DroppedCycles"] == 0
        and diag["FrontendRestarts"] == 0
        and client_errors == 0
        and not errors
        and code == 0
    )
    if ok:
        shutil.rmtree(data, ignore_errors=True)
    else:
        print(f"the server's site map and log are kept in {data}")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=120.0, help="seconds (default 120)")
    sys.exit(soak(p.parse_args().duration))


if __name__ == "__main__":
    main()
