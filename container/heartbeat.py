"""Read the readiness and heartbeat of a motion-server over Modbus TCP; exit 0 when healthy.

The container HEALTHCHECK, the compose bench client and `make test-container` use it.
The tags (``Diagnostics.Ready``: 1 while the controller runs, 0 while it starts or
stops; ``Diagnostics.Heartbeat``: incremented every cycle) and their register addresses
come from the tag map's JSON export (``motion-server map --format json``, contract
"motion-server-map/1"), never from a constant here. Healthy: the controller says it is
ready (maps without the Ready tag skip this) and the heartbeat, read twice, has increased
in between — or stood still while the server's clock is in manual mode
(``Clock.Mode`` = 1), where cycles only run when a client asks for them.

``--wait SECONDS`` tries again (every half second) until the server is healthy or the
time is up: a client that starts with the server (a compose bench) waits for it this way,
whatever its container engine does with ``depends_on`` conditions. The Modbus port of
``motion-server run`` opens only once the controller runs, so until then the connection
is refused at once.

Without ``--map-json`` the export is produced by running ``motion-server map`` with this
interpreter, which sees the same site map and environment as the server (in the
container: ``MOTION_SERVER_MAP`` and the ``MOTION_SERVER_<SECTION>_<FIELD>`` variables).
That takes seconds (it loads the server's code); ``--map-cache PATH`` keeps the export
and the ports there for the next checks, as long as the site map file and the
``MOTION_SERVER_*`` variables are the same (the image's HEALTHCHECK uses it).

``--opcua-port auto`` (or a port number) also requires the OPC UA port to accept a
connection when the site map serves OPC UA: its front-end builds its address space
after the Modbus one listens, seconds later on a big map.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import socket
import subprocess
import sys
import time
from typing import Any

MAP_FORMAT = "motion-server-map/1"
#: the heartbeat tag: the first of these names the map has (``--tag`` picks another)
HEARTBEAT_TAGS = ("Diagnostics.Heartbeat", "Controller.Heartbeat")
CLOCK_MODE_TAG = "Clock.Mode"
READY_TAG = "Diagnostics.Ready"
#: seconds between two attempts with ``--wait``
RETRY_PAUSE = 0.5


class Unhealthy(Exception):
    """The server could not be reached or does not look alive."""


def load_map(path: str | None) -> dict[str, Any]:
    """The JSON tag map: from a file, or from this interpreter's ``motion-server map``."""
    if path:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    else:
        cmd = [sys.executable, "-m", "motion_server.cli", "map", "--format", "json"]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=False)
        if done.returncode != 0:
            raise Unhealthy(f"motion-server map failed: {done.stderr.strip()}")
        text = done.stdout
    data: dict[str, Any] = json.loads(text)
    if data.get("format") != MAP_FORMAT:
        raise Unhealthy(f"tag map format {data.get('format')!r}, expected {MAP_FORMAT!r}")
    return data


def cache_key() -> str:
    """What the exported map and the default port depend on: this interpreter, the
    ``MOTION_SERVER_*`` variables and the site map file they name (its size and time)."""
    env = sorted((k, v) for k, v in os.environ.items() if k.startswith("MOTION_SERVER_"))
    site = os.environ.get("MOTION_SERVER_MAP", "")
    stamp = ""
    if site:
        try:
            st = os.stat(site)
            stamp = f"{st.st_mtime_ns}:{st.st_size}"
        except OSError:
            stamp = "missing"
    text = json.dumps([sys.executable, env, site, stamp])
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def cached_map_and_ports(path: str) -> tuple[dict[str, Any], tuple[int, int]]:
    """The map export and :func:`site_ports`, from the cache file at ``path`` when it was
    made for the same :func:`cache_key`, else made now and kept there (atomically)."""
    key = cache_key()
    try:
        with open(path, encoding="utf-8") as f:
            cached = json.load(f)
        if cached.get("key") == key and cached["map"].get("format") == MAP_FORMAT:
            modbus, opcua = cached["ports"]
            return cached["map"], (int(modbus), int(opcua))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        pass  # none yet, or unusable: made again
    tag_map, ports = load_map(None), site_ports()
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump({"key": key, "ports": list(ports), "map": tag_map}, f)
        os.replace(tmp, path)
    except OSError:
        pass  # a cache that cannot be written only costs time
    return tag_map, ports


def find_tag(tag_map: dict[str, Any], name: str) -> dict[str, Any] | None:
    for tag in tag_map["tags"]:
        if tag["name"] == name:
            found: dict[str, Any] = tag
            return found
    return None


def decode(registers: list[int], tag_type: str, word_order: str) -> int | float:
    """A tag value from its holding registers (the project's codec; a BOOL's register as
    a number, its bit picked by the caller)."""
    from motion_clients import codec

    value = codec.decode("UINT" if tag_type == "BOOL" else tag_type, registers, word_order)
    return int(value) if isinstance(value, bool) else value


def encode(value: float, tag_type: str, word_order: str) -> list[int]:
    """Holding registers of a tag value: the inverse of :func:`decode`."""
    from motion_clients import codec

    return codec.encode("UINT" if tag_type == "BOOL" else tag_type, value, word_order)


def site_ports() -> tuple[int, int]:
    """The Modbus port and the OPC UA port (0 when OPC UA is not served) of the site map
    this interpreter sees, with the environment."""
    from motion_server import config

    site = config.load()
    return int(site.modbus.port), int(site.opcua.port) if site.opcua.enabled else 0


class Reader:
    """Reads tags of one tag map from one server."""

    def __init__(self, tag_map: dict[str, Any], host: str, port: int, timeout: float) -> None:
        from pymodbus.client import ModbusTcpClient

        self.map = tag_map
        self.unit = int(tag_map["modbus"].get("unit_id", 1))
        self.word_order = str(tag_map["modbus"].get("word_order", "big"))
        self.where = f"{host}:{port}"
        self.client = ModbusTcpClient(host, port=port, timeout=timeout, retries=1)

    def __enter__(self) -> Reader:
        if not self.client.connect():
            raise Unhealthy(f"cannot connect to Modbus server at {self.where}")
        return self

    def __exit__(self, *exc: object) -> None:
        self.client.close()

    def tag(self, name: str) -> dict[str, Any]:
        found = find_tag(self.map, name)
        if found is None:
            raise Unhealthy(f"the tag map has no {name}")
        return found

    def write(self, name: str, value: float) -> None:
        """Write a whole tag (a BOOL as its register with only its bit set)."""
        tag = self.tag(name)
        bit = tag["modbus"].get("bit")
        value = (int(bool(value)) << int(bit)) if bit is not None else value
        words = encode(value, tag["type"], self.word_order)
        address = int(tag["modbus"]["address"])
        reply = self.client.write_registers(address, words, device_id=self.unit)
        if reply.isError():
            raise Unhealthy(f"writing {name} at register {address}: {reply}")

    def read(self, tag: dict[str, Any]) -> int | float:
        address, count = int(tag["modbus"]["address"]), int(tag["modbus"]["count"])
        reply = self.client.read_holding_registers(address, count=count, device_id=self.unit)
        if reply.isError():
            raise Unhealthy(f"reading {tag['name']} at register {address}: {reply}")
        value = decode(list(reply.registers), tag["type"], self.word_order)
        bit = tag["modbus"].get("bit")
        if bit is not None:
            return (int(value) >> int(bit)) & 1
        return value


def check(
    reader: Reader, interval: float, require_increase: bool, names: tuple[str, ...] = HEARTBEAT_TAGS
) -> str:
    """Check readiness, then read the heartbeat twice ``interval`` apart; a message when
    healthy, else raise."""
    heartbeat = next((tag for n in names if (tag := find_tag(reader.map, n))), None)
    if heartbeat is None:
        raise Unhealthy(f"the tag map has no {' or '.join(names)}")
    ready = find_tag(reader.map, READY_TAG)
    if ready is not None and not reader.read(ready):
        raise Unhealthy(f"{READY_TAG} is 0 at {reader.where}: the controller starts or stops")
    name = heartbeat["name"]
    first = reader.read(heartbeat)
    time.sleep(interval)
    second = reader.read(heartbeat)
    if second > first:
        return f"{name} {first} -> {second} at {reader.where}"
    mode_tag = find_tag(reader.map, CLOCK_MODE_TAG)
    manual = False
    if mode_tag is not None:
        manual = reader.read(mode_tag) == mode_tag.get("enum", {}).get("MANUAL", 1)
    if manual and not require_increase:
        return f"{name} {second} at {reader.where} (manual clock)"
    raise Unhealthy(f"{name} did not increase: {first} -> {second} at {reader.where}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--host", default="127.0.0.1", help="server address (default 127.0.0.1)")
    p.add_argument("--port", type=int, help="Modbus port (default: the site map's)")
    p.add_argument(
        "--opcua-port",
        default="",
        help="also require this OPC UA port to accept a connection; 'auto': the site "
        "map's when it serves OPC UA (default: not checked)",
    )
    p.add_argument("--map-json", help="tag map JSON export (default: run motion-server map)")
    p.add_argument(
        "--map-cache",
        metavar="PATH",
        help="without --map-json: keep the export (and the default port) in this file",
    )
    p.add_argument("--interval", type=float, default=0.5, help="seconds between the reads")
    p.add_argument("--timeout", type=float, default=3.0, help="Modbus request timeout (s)")
    p.add_argument(
        "--require-increase",
        action="store_true",
        help="fail when the heartbeat stands still, even in manual clock mode",
    )
    p.add_argument("--tag", help=f"heartbeat tag (default: {' or '.join(HEARTBEAT_TAGS)})")
    p.add_argument(
        "--wait",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="try again until healthy, for at most this long (default 0: one attempt)",
    )
    p.add_argument("--quiet", action="store_true", help="print nothing when healthy")
    args = p.parse_args(argv)
    try:  # the map and the ports do not depend on the server: found once
        auto = args.opcua_port == "auto"
        if args.map_cache and not args.map_json:
            tag_map, (port, opcua_port) = cached_map_and_ports(args.map_cache)
        else:
            tag_map = load_map(args.map_json)
            need = args.port is None or auto
            port, opcua_port = site_ports() if need else (args.port, 0)
        if args.port is not None:
            port = args.port
        if not auto:
            opcua_port = int(args.opcua_port or 0)
    except Exception as exc:
        print(f"unhealthy: {exc}", file=sys.stderr)
        return 1
    give_up = time.monotonic() + args.wait
    attempts = 0
    while True:
        attempts += 1
        try:
            message = attempt(args, tag_map, port, opcua_port)
            break
        except Exception as exc:  # a health check reports, it never shows a traceback
            if time.monotonic() + RETRY_PAUSE > give_up:
                tried = f" (after {attempts} attempts in {args.wait:g} s)" if args.wait else ""
                print(f"unhealthy: {exc}{tried}", file=sys.stderr)
                return 1
            time.sleep(RETRY_PAUSE)
    if not args.quiet:
        print(f"healthy: {message}")
    return 0


def attempt(args: argparse.Namespace, tag_map: dict[str, Any], port: int, opcua_port: int) -> str:
    """One health check with the command-line settings; raises when unhealthy."""
    with Reader(tag_map, args.host, port, args.timeout) as reader:
        names = (args.tag,) if args.tag else HEARTBEAT_TAGS
        message = check(reader, args.interval, args.require_increase, names)
    if opcua_port:
        check_listening(args.host, opcua_port, args.timeout)
        message += f", OPC UA port {opcua_port} listening"
    return message


def check_listening(host: str, port: int, timeout: float) -> None:
    """:class:`Unhealthy` unless ``host:port`` accepts a TCP connection."""
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise Unhealthy(f"OPC UA port {host}:{port} does not accept connections ({exc})") from None


if __name__ == "__main__":
    sys.exit(main())
