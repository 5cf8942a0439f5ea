"""Soak: 5 Modbus and 5 OPC UA clients against one server for a given duration.

    python bench/soak.py --duration 1200     # 20 minutes (CI: --duration 120)

The server runs in this process (realtime clock, 2 ms cycles) with a jog on Axis1 and a
gear on Axis2 running the whole time; the clients run in a child process so that the
server's memory is measured alone. Per protocol: four clients stay connected (Modbus:
FC3 reads of a status block and an operand write every 50 reads; OPC UA: a secure
session with a subscription and reads), one connects, reads and disconnects in a loop.

Reported: resident memory after warm-up (a quarter of the run) and at the end (growth
target < 10 %), open file descriptors and asyncio tasks before the clients and after they
left (must be back to baseline), overruns and dropped cycles (missed deadlines: dropped
must be 0), client errors and server log errors (must be 0). Exit status 1 if a target
is missed.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import multiprocessing as mp
import os
import struct
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from motion_server import config
from motion_server.frontends.opcua_users import hash_password
from motion_server.runtime import Runtime

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


def rss_kib() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def open_fds() -> dict[str, str]:
    """This process's open descriptors but pipes (number -> target). The server's are
    sockets and files; pipes here are the bench's multiprocessing plumbing."""
    out = {}
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):
            target = os.readlink(f"/proc/self/fd/{fd}")
            if not target.startswith("pipe:"):
                out[fd] = target
    return out


class ErrorCount(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(f"{record.name}: {record.getMessage()[:200]}")


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
    await client.connect()
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


def run_clients(args: dict[str, Any], out: Any) -> None:
    logging.getLogger("asyncua").setLevel(logging.ERROR)

    async def main() -> list[int]:
        until = time.monotonic() + args["duration"]
        data = Path(args["data"])
        jobs = [
            modbus_client(args["modbus"], until, args["status"], args["speed"], k == 0)
            for k in range(5)
        ]
        jobs += [opcua_client(args["endpoint"], data, until, k, k == 0) for k in range(5)]
        return list(await asyncio.gather(*jobs, return_exceptions=False))

    try:
        out.put(asyncio.run(main()))
    except Exception as exc:
        out.put(repr(exc))


# -- server and report -----------------------------------------------------------------------
async def soak(duration: float) -> int:
    errors_log = ErrorCount()
    logging.getLogger().addHandler(errors_log)
    logging.getLogger().setLevel(logging.WARNING)
    data = Path(tempfile.mkdtemp(prefix="soak-"))
    text = SITE.format(data=data, user=USER, hash=hash_password(PASSWORD, n=2**10))
    site = config.parse(text, "soak.toml")
    rt = Runtime(site)
    server = asyncio.create_task(rt.serve())
    await rt.ready.wait()
    assert rt.modbus is not None and rt.opcua is not None
    img = rt.image
    for name, value in [("MSO_1.Axis", 1), ("MAJ_1.Axis", 1), ("MAJ_1.Speed", 10.0)]:
        img.write(name, value)
    img.write("MSO_1.Execute", True)
    await asyncio.sleep(0.1)
    img.write("MSO_1.Axis", 2)
    img.write("MSO_1.Execute", False)
    await asyncio.sleep(0.05)
    img.write("MSO_1.Execute", True)
    img.write("MAJ_1.Execute", True)
    for name, value in [("MAG_1.SlaveAxis", 2), ("MAG_1.MasterAxis", 1), ("MAG_1.Ratio", 0.5)]:
        img.write(name, value)
    img.write("MAG_1.Execute", True)
    await asyncio.sleep(1.0)
    base_fds, base_tasks = open_fds(), len(asyncio.all_tasks())
    ctx = mp.get_context("spawn")
    out = ctx.Queue()
    args = {
        "duration": duration,
        "data": str(data),
        "modbus": rt.modbus.port,
        "endpoint": rt.opcua.endpoint,
        "status": rt.tagmap.tag("Axis1.CommandPosition").address,
        "speed": rt.tagmap.tag("MAJ_1.Speed").address,
    }
    proc = ctx.Process(target=run_clients, args=(args, out), daemon=True)
    t0 = time.monotonic()
    proc.start()
    warm = max(duration / 4, 10.0)
    await asyncio.sleep(warm)
    rss_warm = rss_kib()
    samples = [rss_warm]
    while proc.is_alive():
        await asyncio.sleep(min(30.0, duration / 10))
        samples.append(rss_kib())
    result = await asyncio.to_thread(out.get, True, 60)
    rss_end = rss_kib()
    proc.join(10)
    proc.close()  # the bench's own descriptors (process sentinel, queue pipe) go too
    out.close()
    out.join_thread()
    await asyncio.sleep(3.0)  # connections close, sessions time out
    end_fds, end_tasks = open_fds(), len(asyncio.all_tasks())
    rt.request_stop()
    await server
    growth = (rss_end - rss_warm) / rss_warm * 100
    client_errors = sum(result) if isinstance(result, list) else -1
    print(
        f"soak {duration:.0f} s (wall {time.monotonic() - t0:.0f} s), 5 Modbus + 5 OPC UA clients"
    )
    print(
        f"memory: {rss_warm / 1024:.1f} MiB after {warm:.0f} s warm-up, "
        f"{rss_end / 1024:.1f} MiB at the end: {growth:+.1f} % (target < 10 %)"
    )
    print(f"memory samples (MiB): {' '.join(f'{s / 1024:.1f}' for s in samples)}")
    extra = sorted(set(end_fds.values()) - set(base_fds.values()))
    print(f"file descriptors: {len(base_fds)} before, {len(end_fds)} after the clients left")
    if extra:
        print(f"   new: {extra}")
    print(f"asyncio tasks: {base_tasks} before, {end_tasks} after the clients left")
    print(
        f"cycles {rt.cycle_count}, overruns {rt.overruns}, dropped {rt.dropped}, "
        f"max cycle {rt.max_cycle_time * 1e6:.0f} us"
    )
    print(
        f"Modbus refused connections {rt.modbus.refused_connections}; "
        f"OPC UA writes {rt.opcua.writes}, refused {rt.opcua.refused}"
    )
    print(f"client errors: {result}; server log errors: {len(errors_log.records)}")
    for line in errors_log.records[:10]:
        print("  ", line)
    ok = (
        growth < 10.0
        and len(end_fds) <= len(base_fds)
        and end_tasks <= base_tasks
        and rt.dropped == 0
        and client_errors == 0
        and not errors_log.records
    )
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=120.0, help="seconds (default 120)")
    sys.exit(asyncio.run(soak(p.parse_args().duration)))


if __name__ == "__main__":
    main()
