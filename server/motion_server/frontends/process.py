"""A front-end process: ``python -m motion_server.frontends modbus|opcua|web``.

Started by the supervisor once the scan runs, with its :class:`LaunchSpec` on standard
input: the site map, the shared image (mapped read-only: a front-end cannot change what
the scan published) and its write channel to the scan. It serves one protocol (Modbus TCP
with Modbus/TCP Security, or OPC UA) on its own event loop, so a flood of requests on one
protocol costs that process only: never the motion cycle, never the other protocol.

It tells the supervisor, one JSON line each on standard output, where it listens
(``{"listening": "modbus", "port": 5020, "tls_port": 0}``) and every audit line
(``{"audit": "..."}``: the supervisor owns the audit file), and, once it listens, a beat
(``{"beat": n}``) every :data:`~motion_server.liveness.FRONTEND_BEAT` seconds from a task
of its event loop: a loop that stands still misses it, and the supervisor replaces the
process (:mod:`motion_server.liveness`). End of file on standard input
(the supervisor is gone) or SIGTERM ends it; SIGINT is left to the supervisor.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import itertools
import json
import logging
import os
import signal
import socket
import sys
from typing import Any

from ..config import SiteMap, SiteMapError
from ..config import opcua_users as configured_users
from ..image.buffer import ImageError, ImageReader, map_shared
from ..image.layout import ImageLayout
from ..launch import LaunchSpec, follow_supervisor, setup_logging
from ..liveness import FRONTEND_BEAT
from ..safety.access import AccessPolicy, plain_role
from ..safety.audit import AuditLog
from ..scan.channel import MODBUS, OPCUA, WEB
from ..scheduling import LOAD_WINDOW, MODBUS_RT_PRIORITY, CpuLoad, Policy
from ..tagmap import build_tagmap
from ..tagmap.judge import Judge
from . import modbus as modbus_module
from . import opcua_users
from .link import ScanLink, ScanUnavailable
from .view import ImageView

log = logging.getLogger("motion_server.frontends")

KINDS = {"modbus": MODBUS, "opcua": OPCUA, "web": WEB}
#: connection numbers of the n-th start of a front-end begin at n * this + 1
GENERATION_SPAN = 1_000_000
#: the Modbus front-end's load (% of a core each second) beyond which it leaves the
#: real-time policy until the load is below half of it: a flood of requests must not take
#: a whole core from the rest
MODBUS_OVERLOAD = 75.0


def _say(obj: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(obj, separators=(",", ":")) + "\n")
    sys.stdout.flush()


def view_of(site: SiteMap, spec: LaunchSpec, link: ScanLink, channel: int) -> ImageView:
    """The front-end's image: the shared snapshot (read-only) and its write link."""
    tagmap = build_tagmap(site)
    layout = ImageLayout(tagmap)
    memory = map_shared(spec.image_fd, spec.image_size, writable=False)
    reader = ImageReader(memory, layout.size, layout.fingerprint)
    judge = Judge(tagmap, {a.name: a.counts_per_unit for a in site.axis_configs()})
    return ImageView(layout, reader, judge, link, channel)


async def serve(kind: str, spec: LaunchSpec) -> int:
    site = spec.site_map()
    channel = KINDS[kind]
    first = spec.generation * GENERATION_SPAN + 1
    modbus_module._connection_numbers = itertools.count(first)
    opcua_users._connection_numbers = itertools.count(first)
    layout_print = ImageLayout(build_tagmap(site)).fingerprint
    link = ScanLink(socket.socket(fileno=spec.channels[channel]), channel, layout_print)
    try:
        await link.connect()
        view = view_of(site, spec, link, channel)
    except (ScanUnavailable, ImageError) as exc:
        log.error("%s front-end: %s", kind, exc)
        return 3
    audit = None
    if site.audit.enabled:
        audit = AuditLog(sink=lambda line: _say({"audit": line}), cycle=lambda: view.tick)
        view.observers.append(audit.accepted)
    frontend: Any
    if kind == "modbus":
        cfg = site.modbus
        try:
            has_users = bool(configured_users(site))
        except SiteMapError as exc:  # read by the supervisor a moment ago: assume users
            log.warning("modbus front-end: %s", exc)
            has_users = True
        policy = AccessPolicy(cfg.access, view.map, plain_role(site, has_users))
        frontend = modbus_module.ModbusFrontend(
            view, cfg.host, cfg.port, cfg.unit_id, policy, audit, cfg.tls
        )
    elif kind == "web":
        frontend = _web_frontend(view, site, spec, audit)
    else:
        from .opcua import OpcUaFrontend

        frontend = OpcUaFrontend(view, site.opcua, spec.opcua_users(), audit=audit)
    try:
        await frontend.start()
    except (OSError, RuntimeError) as exc:
        # a port in use or an address not on this host (asyncio names the address), a host
        # name that does not resolve (socket.gaierror names nothing), a file (TLS)
        if isinstance(exc, socket.gaierror):
            reason = f"{exc.strerror or exc} ({_where(site, kind)})"
        elif isinstance(exc, OSError):
            where = f": {exc.filename}" if exc.filename else ""
            reason = f"{exc.strerror or exc}{where}"
        else:
            reason = f"{exc} ({_where(site, kind)})"
        log.error("%s front-end cannot serve: %s", kind, reason)
        _say({"failed": kind, "reason": reason})
        return 3
    # the start-up heap (asyncua's address space above all) is never scanned again: a
    # full collection over it would stall this front-end's requests for a long moment
    gc.collect()
    gc.freeze()
    if kind == "modbus":
        tls_port = frontend.tls_port if frontend.tls_server is not None else 0
        port = frontend.port if frontend.server is not None else 0
        _say({"listening": kind, "port": port, "tls_port": tls_port})
    elif kind == "web":
        _say({"listening": kind, "port": frontend.port, "url": frontend.url})
    else:
        _say({"listening": kind, "port": frontend.port, "endpoint": frontend.endpoint})
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    loop.add_signal_handler(signal.SIGTERM, stop.set)

    def lifeline() -> None:  # standard input: end of file when the supervisor is gone
        try:
            data = os.read(sys.stdin.fileno(), 4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            loop.remove_reader(sys.stdin.fileno())
            stop.set()

    loop.add_reader(sys.stdin.fileno(), lifeline)
    tasks = [asyncio.create_task(_watch_link(link, stop)), asyncio.create_task(_beat())]
    if kind == "modbus":
        tasks.append(asyncio.create_task(_follow_policy(modbus_policy())))
    try:
        await stop.wait()
    finally:
        for task in tasks:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await frontend.stop()
        link.close()
    return 0


def _web_frontend(view: ImageView, site: SiteMap, spec: LaunchSpec, audit: Any) -> Any:
    """The web view, reading the scan's trend ring when the supervisor made one."""
    from ..image.trend import RingError, RingReader, map_ring
    from . import web
    from .web_stream import TrendHub

    web._connection_numbers = itertools.count(spec.generation * GENERATION_SPAN + 1)
    ring = None
    if spec.trend_fd >= 0:
        try:
            ring = RingReader(map_ring(spec.trend_fd, spec.trend_size))
        except RingError as exc:
            log.error("web front-end: %s: no trends", exc)
    return web.WebFrontend(view, site, spec.opcua_users(), audit, TrendHub(ring))


def _where(site: SiteMap, kind: str) -> str:
    cfg = site.modbus if kind == "modbus" else site.web if kind == "web" else site.opcua
    return f"{cfg.host}:{cfg.port}"


async def _watch_link(link: ScanLink, stop: asyncio.Event) -> None:
    """A front-end without its scan serves nothing true: stop when the link breaks."""
    while not link.broken:
        await asyncio.sleep(0.5)
    stop.set()


async def _beat() -> None:
    """Tell the supervisor that the event loop runs."""
    for n in itertools.count(1):
        await asyncio.sleep(FRONTEND_BEAT)
        _say({"beat": n})


def modbus_policy() -> Policy:
    """Real-time below the scan (:data:`~motion_server.scheduling.MODBUS_RT_PRIORITY`):
    a PLC's write and its polls of DN come before the OPC UA front-end's bulk work."""
    return Policy("Modbus front-end", MODBUS_RT_PRIORITY, MODBUS_OVERLOAD, recover=True)


async def _follow_policy(policy: Policy) -> None:
    cpu = CpuLoad()
    policy.follow(True, 0.0)
    while True:
        await asyncio.sleep(LOAD_WINDOW)
        policy.follow(True, cpu.sample())


def main() -> int:
    kind = sys.argv[1] if len(sys.argv) > 1 else ""
    if kind not in KINDS:
        print("usage: python -m motion_server.frontends modbus|opcua|web", file=sys.stderr)
        return 2
    spec = LaunchSpec.read(sys.stdin.buffer)
    follow_supervisor(spec)
    setup_logging(spec.log_level)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return asyncio.run(serve(kind, spec))
