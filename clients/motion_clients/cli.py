"""``motion-client``: drive a motion-server by tag name.

    motion-client read Axis2.ActualPosition MAG_1          (an owner name: all its tags)
    motion-client write MAG_1.Ratio=0.5 MAG_1.Direction=SAME
    motion-client trigger MAG_1 SlaveAxis=2 MasterAxis=1 Ratio=0.5
    motion-client watch Axis1 Axis2.ActualPosition         (Ctrl-C to stop)
    motion-client trace Axis1.CommandPosition Axis1.CommandVelocity -o jog.csv --seconds 2
    motion-client plot jog.csv -o jog.png
    motion-client step 500                                 (manual clock)

The tag map comes from ``--map`` (a JSON export, or a site map TOML run through
``motion-server map``); without it, from ``motion-server map`` on the demo site.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from collections.abc import Awaitable, Callable
from pathlib import Path

from . import __version__
from .backend import BACKENDS, ClientError
from .client import MotionClient, TriggerTimeout
from .plot import plot_trace
from .tagmap import ClientMap, MapError
from .trace import Recorder, Trace

Command = Callable[[argparse.Namespace, MotionClient], Awaitable[int]]


def _pairs(items: list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise SystemExit(f"motion-client: expected NAME=VALUE, got {item!r}")
        out[name.strip()] = value
    return out


async def cmd_read(args: argparse.Namespace, mc: MotionClient) -> int:
    tags = mc.map.expand(args.tags)
    values = await mc.backend.read(tags)
    for tag, value in zip(tags, values, strict=True):
        print(f"{tag.name} = {tag.label(value)}")
    return 0


async def cmd_write(args: argparse.Namespace, mc: MotionClient) -> int:
    await mc.write_many(_pairs(args.assignments))
    return 0


async def cmd_trigger(args: argparse.Namespace, mc: MotionClient) -> int:
    operands = _pairs(args.operands)
    try:
        out = await mc.trigger(
            args.instance, timeout=args.timeout, until=tuple(args.until or ()), **operands
        )
    except TriggerTimeout as exc:
        print(f"timeout: {exc}", file=sys.stderr)
        return 2
    print(out)
    return 0 if out.ok else 1


async def cmd_watch(args: argparse.Namespace, mc: MotionClient) -> int:
    tags = mc.map.expand(args.tags)
    width = max(len(t.name) for t in tags)
    tty = sys.stdout.isatty()
    n = 0
    while args.count == 0 or n < args.count:
        values = await mc.backend.read(tags)
        lines = [f"{t.name:<{width}}  {t.label(v)}" for t, v in zip(tags, values, strict=True)]
        cycle = await mc.cycle()
        header = f"motion-client watch  {mc.backend.protocol}://{mc.backend.host}:{mc.backend.port}"
        text = "\n".join([f"{header}  cycle {cycle}", *lines])
        # a terminal is redrawn in place; a pipe gets one block per refresh
        sys.stdout.write(("\x1b[H\x1b[2J" if tty else "") + text + "\n" + ("" if tty else "\n"))
        sys.stdout.flush()
        n += 1
        if args.count == 0 or n < args.count:
            await asyncio.sleep(args.interval)
    return 0


async def cmd_trace(args: argparse.Namespace, mc: MotionClient) -> int:
    rec = Recorder(mc, [t.name for t in mc.map.expand(args.tags)])
    await rec.sample()
    await rec.run(args.seconds, every=args.every)
    path = rec.trace.write_csv(args.output)
    print(f"{path}: {len(rec.trace)} samples of {len(rec.tags)} tags")
    return 0


async def cmd_step(args: argparse.Namespace, mc: MotionClient) -> int:
    await mc.step(args.cycles)
    print(f"cycle {await mc.cycle()}")
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    trace = Trace.read_csv(args.trace)
    out = args.output or str(Path(args.trace).with_suffix(".png"))
    print(plot_trace(trace, out, title=args.title or Path(args.trace).stem))
    return 0


COMMANDS: dict[str, Command] = {
    "read": cmd_read,
    "write": cmd_write,
    "trigger": cmd_trigger,
    "watch": cmd_watch,
    "trace": cmd_trace,
    "step": cmd_step,
}


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="motion-client", description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    p.add_argument("--version", action="version", version=f"motion-client {__version__}")
    p.add_argument("--map", help="tag map: JSON export, or site map TOML (default: demo)")
    p.add_argument("--protocol", choices=sorted({*BACKENDS, "opcua"}), default="modbus")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, help="server port (default: the protocol's)")
    p.add_argument("--user", help="OPC UA user name")
    p.add_argument("--password", help="OPC UA password")
    p.add_argument("--security", default="Basic256Sha256", help="OPC UA: Basic256Sha256 or None")
    p.add_argument("--cert-dir", help="OPC UA: folder of the client certificate")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("read", help="read tags (an owner name reads all its tags)")
    r.add_argument("tags", nargs="+")
    w = sub.add_parser("write", help="write TAG=VALUE (enum names accepted)")
    w.add_argument("assignments", nargs="+")
    t = sub.add_parser("trigger", help="run an instruction: operands, trigger, wait, outcome")
    t.add_argument("instance")
    t.add_argument("operands", nargs="*", help="OPERAND=VALUE")
    t.add_argument("--timeout", type=float, default=5.0, help="seconds (simulated if manual)")
    t.add_argument("--until", action="append", help="wait for this output instead (repeat)")
    wa = sub.add_parser("watch", help="live values, refreshed in the terminal")
    wa.add_argument("tags", nargs="+")
    wa.add_argument("--interval", type=float, default=0.2, help="seconds between refreshes")
    wa.add_argument("--count", type=int, default=0, help="refreshes (0: until Ctrl-C)")
    tr = sub.add_parser("trace", help="sample tags to CSV against simulated time")
    tr.add_argument("tags", nargs="+")
    tr.add_argument("-o", "--output", required=True, help="CSV file")
    tr.add_argument("--seconds", type=float, default=1.0, help="simulated seconds to record")
    tr.add_argument("--every", type=int, default=5, help="cycles between samples")
    st = sub.add_parser("step", help="run N cycles (manual clock) or wait for them")
    st.add_argument("cycles", type=int)
    pl = sub.add_parser("plot", help="PNG of position and velocity from a trace CSV")
    pl.add_argument("trace")
    pl.add_argument("-o", "--output", help="PNG file (default: the trace's name .png)")
    pl.add_argument("--title")
    return p


def _check_names(args: argparse.Namespace, tagmap: ClientMap) -> None:
    """Tag names and values checked against the map before connecting: a typo is told
    (with the nearest name) even when the server is not there."""
    if args.command in ("read", "watch", "trace"):
        tagmap.expand(args.tags)
    elif args.command == "write":
        for name, value in _pairs(args.assignments).items():
            tagmap.tag(name).coerce(value)
    elif args.command == "trigger":
        tagmap.owned_by(args.instance)
        for name, value in _pairs(args.operands).items():
            tagmap.tag(f"{args.instance}.{name}").coerce(value)


async def _run(args: argparse.Namespace, tagmap: ClientMap) -> int:
    opts = {"user": args.user, "password": args.password, "security": args.security}
    opts["cert_dir"] = args.cert_dir
    async with MotionClient.connect(tagmap, args.protocol, args.host, args.port, **opts) as mc:
        return await COMMANDS[args.command](args, mc)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.command == "plot":
            return cmd_plot(args)
        tagmap = ClientMap.load(args.map)
        _check_names(args, tagmap)
        return asyncio.run(_run(args, tagmap))
    except (ClientError, MapError, KeyError, ValueError, OSError) as exc:
        print(f"motion-client: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
