"""``motion-server snapshot`` and ``motion-server comm-fault``: the test bench's commands.

Both act on a running server through its Clock tags, over Modbus TCP, as an admin client
would (the tags are admin-only on OPC UA and Modbus/TCP Security; plain Modbus TCP is
limited by ``[modbus.access]`` only):

- ``snapshot save N`` / ``snapshot restore N``: ``Clock.Snapshot`` = N, then a rising edge
  of ``Clock.SnapshotSave`` / ``SnapshotRestore``; answered once done. A snapshot is named
  by its number (the Clock tags carry numbers);
- ``snapshot list``: the snapshot files of the site map's data directory (no server);
- ``comm-fault delay MS | drop | off [--duration S] [--client-port P]``: the
  ``Clock.Comm...`` tags.

The server is the one of the site map (its Modbus host and port) unless ``--host`` and
``--port`` say otherwise. Every failure is one line on standard error, exit status 1.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import re
from collections.abc import Awaitable, Callable
from typing import Any

from . import config
from .image.layout import ImageLayout
from .scan import snapshots
from .tagmap import build_tagmap, to_dict


def _site(args: argparse.Namespace) -> config.SiteMap:
    try:
        return config.load(args.map)
    except config.SiteMapError as exc:
        raise SystemExit(f"motion-server: {exc}") from None


def _on_server(
    args: argparse.Namespace,
    work: Callable[[Any], Awaitable[str]],
    explain: Callable[[], str | None] | None = None,
) -> int:
    """Run ``work(client)`` against the site map's server; print what it returns. When the
    server refuses, ``explain()`` may say why in one line (else the client's words)."""
    from motion_clients import ClientError, ClientMap, MotionClient

    site = _site(args)
    host = args.host or site.modbus.host
    if host in ("", "0.0.0.0", "::"):
        host = "127.0.0.1"
    port = args.port if args.port is not None else site.modbus.port
    tagmap = ClientMap(to_dict(build_tagmap(site)))

    async def run() -> str:
        async with MotionClient.connect(tagmap, "modbus", host, port, timeout=args.timeout) as mc:
            return await work(mc)

    # pymodbus logs a failed request over several lines; the failure is said in one below
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)

    try:
        print(asyncio.run(run()))
    except ClientError as exc:
        why = explain() if explain is not None else None
        raise SystemExit(f"motion-server: {why or f'{host}:{port}: {exc}'}") from None
    except (OSError, TimeoutError) as exc:
        raise SystemExit(f"motion-server: {host}:{port}: {exc}") from None
    return 0


def cmd_snapshot(args: argparse.Namespace) -> int:
    if args.action == "list":
        site = _site(args)
        for name, info in snapshots.listing(site):
            if isinstance(info, str):
                print(f"{name}  unreadable: {info}")
            else:
                print(
                    f"{name}  cycle {info.get('tick')}  site {info.get('site')}  "
                    f"motion-server {info.get('version')}  saved {info.get('saved')}"
                )
        return 0
    name = args.name or ""
    # ASCII digits only ("²".isdigit() is true), and a number Clock.Snapshot holds (UDINT)
    if not re.fullmatch(r"[0-9]{1,10}", name) or int(name) > 0xFFFFFFFF:
        shown = name if len(name) <= 20 else name[:17] + "..."
        raise SystemExit(
            f"motion-server: snapshot {args.action} {shown!r}: the snapshot's number, "
            "0 to 4294967295"
        )
    number = int(name)
    field = "SnapshotSave" if args.action == "save" else "SnapshotRestore"
    site = _site(args)

    async def work(mc: Any) -> str:
        await mc.write("Clock.Snapshot", number)
        await mc.write(f"Clock.{field}", True)  # answered once done (or refused)
        done = "saved" if args.action == "save" else "restored"
        return f"snapshot {number} {done}: cycle {await _snapshot_cycle(site, number, mc)}"

    def explain() -> str | None:
        """Why the server refused, when this machine can tell (the same checks on the
        same file; the server's log says it in any case)."""
        verb = "saved" if args.action == "save" else "restored"
        try:
            if args.action == "restore":
                snapshots.load(site, ImageLayout(build_tagmap(site)), str(number))
        except snapshots.SnapshotError as exc:
            return f"snapshot {number} not {verb}: {exc}"
        return f"snapshot {number} not {verb}: refused by the server (its log says why)"

    return _on_server(args, work, explain)


async def _snapshot_cycle(site: config.SiteMap, number: int, mc: Any) -> str:
    """The cycle the snapshot was taken at, from its file when this machine can read it
    (the server's clock runs on: a cycle read afterwards is a later one)."""
    try:
        return str(snapshots.header(snapshots.path_of(site, str(number)))["tick"])
    except snapshots.SnapshotError:
        return f"{await mc.cycle()} (read afterwards: the file is not on this machine)"


def cmd_comm_fault(args: argparse.Namespace) -> int:
    mode = {"off": 0, "delay": 1, "drop": 2}[args.kind]
    if args.kind == "delay" and args.ms is None:
        raise SystemExit("motion-server: comm-fault delay MS: the delay in milliseconds")

    async def work(mc: Any) -> str:
        # the fault off first: a change of its parameters re-arms an active fault, and a
        # client port of 0 while answers are dropped would drop this client's answers too
        await mc.write("Clock.CommFault", 0)
        if mode:
            await mc.write_many(
                {
                    "Clock.CommDelay": args.ms or 0,
                    "Clock.CommDuration": round(args.duration * 1000),
                    "Clock.CommClientPort": args.client_port,
                }
            )
            await mc.write("Clock.CommFault", mode)
        return f"communication fault: {args.kind}"

    return _on_server(args, work)


def _server_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--map", help="the server's site map (its Modbus host and port, data dir)")
    p.add_argument("--host", help="Modbus TCP host (default: the site map's)")
    p.add_argument("--port", type=int, help="Modbus TCP port (default: the site map's)")
    p.add_argument("--timeout", type=float, default=30.0, help="seconds per request")


def add_commands(sub: Any) -> None:
    """Add ``snapshot`` and ``comm-fault`` to the subcommands of ``motion-server``."""
    sp = sub.add_parser("snapshot", help="save, restore or list controller snapshots")
    sp.add_argument("action", choices=["save", "restore", "list"])
    sp.add_argument("name", nargs="?", help="snapshot number (save, restore)")
    _server_options(sp)
    sp.set_defaults(func=cmd_snapshot)
    cf = sub.add_parser(
        "comm-fault", help="delay or drop the answers to one client or all (HMI timeouts)"
    )
    cf.add_argument("kind", choices=["delay", "drop", "off"])
    cf.add_argument("ms", nargs="?", type=int, help="delay: milliseconds per answer")
    cf.add_argument(
        "--duration", type=float, default=0.0, help="seconds the fault lasts (0: until off)"
    )
    cf.add_argument(
        "--client-port", type=int, default=0, help="the client's TCP port (0: every client)"
    )
    _server_options(cf)
    cf.set_defaults(func=cmd_comm_fault)
