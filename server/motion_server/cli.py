"""``motion-server``: run the server, check a site map, export its tag map."""

from __future__ import annotations

import argparse
import getpass
import logging
import sys
from pathlib import Path

from . import __version__, config
from .launch import setup_logging
from .safety.first_user import FirstUserError, ensure_user
from .safety.retain import RetainError
from .supervisor import Supervisor
from .tagmap import FORMATS, build_tagmap, export

log = logging.getLogger("motion_server")


def _load(path: str | None) -> config.SiteMap:
    try:
        return config.load(path)
    except config.SiteMapError as exc:
        raise SystemExit(f"motion-server: site map error:\n{exc}") from None


def cmd_run(args: argparse.Namespace) -> int:
    site = _load(args.map)
    changes = {
        k: v for k, v in (("host", args.modbus_host), ("port", args.modbus_port)) if v is not None
    }
    if changes:
        try:
            modbus = config.ModbusSection.model_validate(site.modbus.model_dump() | changes)
        except ValueError as exc:
            raise SystemExit(f"motion-server: {exc}") from None
        site = site.model_copy(update={"modbus": modbus})
    if args.opcua_port is not None:
        try:
            opcua = config.OpcUaSection.model_validate(
                site.opcua.model_dump() | {"port": args.opcua_port}
            )
        except ValueError as exc:
            raise SystemExit(f"motion-server: {exc}") from None
        site = site.model_copy(update={"opcua": opcua})
    clock = {k: v for k, v in (("clock", args.clock), ("scale", args.scale)) if v is not None}
    if clock:
        try:
            controller = config.ControllerSection.model_validate(
                site.controller.model_dump() | clock
            )
        except ValueError as exc:
            raise SystemExit(f"motion-server: {exc}") from None
        site = site.model_copy(update={"controller": controller})
    serve_opcua = site.opcua.enabled and not args.no_opcua
    try:
        users = config.opcua_users(site)  # fail early on a broken users secret file
        if serve_opcua:
            users = ensure_user(site.opcua, users)  # none configured: the generated admin
    except (config.SiteMapError, FirstUserError) as exc:
        raise SystemExit(f"motion-server: {exc}") from None
    log.info("OPC UA users: %d", len(users))
    log.info("site map %s", site.source)
    supervisor = Supervisor(
        site,
        args.log_level.upper(),
        fresh=args.fresh,
        modbus=False if args.no_modbus else None,
        opcua=False if args.no_opcua else None,
        users=users if serve_opcua else [],
        ready_file=Path(args.ready_file) if args.ready_file else None,
    )
    try:
        return supervisor.run()
    except RetainError as exc:
        raise SystemExit(
            f"motion-server: {exc}\n(fix or remove the file, or start clean with --fresh)"
        ) from None


def cmd_check(args: argparse.Namespace) -> int:
    site = _load(args.map)
    system = site.build()
    print(
        f"{site.source}: ok: {len(system.ctl.axes)} axes, {len(system.ctl.groups)} groups, "
        f"{len(system.instances)} instruction instances"
    )
    return 0


def cmd_map(args: argparse.Namespace) -> int:
    site = _load(args.map)
    text = export(build_tagmap(site), args.format)
    if args.output:
        Path(args.output).write_text(text, "utf-8")
    else:
        sys.stdout.write(text)
    return 0


def cmd_hash_password(args: argparse.Namespace) -> int:
    """Print the hash of a password read from standard input (first line) or a prompt."""
    from .frontends.opcua_users import hash_password

    if sys.stdin.isatty():
        password = getpass.getpass("password: ")
        if getpass.getpass("again: ") != password:
            raise SystemExit("motion-server: the passwords differ")
    else:
        password = sys.stdin.readline().rstrip("\r\n")
    if not password:
        raise SystemExit("motion-server: empty password")
    print(hash_password(password))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="motion-server", description=__doc__)
    p.add_argument("--version", action="version", version=f"motion-server {__version__}")
    p.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING (default INFO)")
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run the server (the demo map when no MAP is given)")
    run.add_argument("map", nargs="?", help="site map (TOML)")
    run.add_argument(
        "--clock",
        choices=["realtime", "scaled", "manual", "fast"],
        help="override the site map's clock mode",
    )
    run.add_argument(
        "--fresh", action="store_true", help="start clean: ignore the retain file ([retain])"
    )
    run.add_argument("--scale", type=float, help="simulated seconds per real second (scaled)")
    run.add_argument("--modbus-host", help="bind address of Modbus TCP (site map: [modbus] host)")
    run.add_argument(
        "--modbus-port", type=int, help="Modbus TCP port, 0 = ephemeral (site map: [modbus] port)"
    )
    run.add_argument("--no-modbus", action="store_true", help="do not serve Modbus TCP")
    run.add_argument(
        "--opcua-port", type=int, help="OPC UA port, 0 = ephemeral (site map: [opcua] port)"
    )
    run.add_argument("--no-opcua", action="store_true", help="do not serve OPC UA")
    run.add_argument(
        "--ready-file",
        metavar="PATH",
        help="once every front-end listens, write a JSON file there (pid, ports, endpoint); "
        "removed when the server stops",
    )
    run.set_defaults(func=cmd_run)
    mp = sub.add_parser("map", help="export the tag map (Modbus registers, OPC UA nodes)")
    mp.add_argument("map", nargs="?", help="site map (TOML)")
    mp.add_argument(
        "--format",
        choices=FORMATS,
        default="json",
        help="json (default), csv, md, nodeset (OPC UA NodeSet2 XML), kepware (KEPServerEX "
        "tag CSV), ignition (Ignition tag JSON)",
    )
    mp.add_argument("-o", "--output", help="write to this file instead of standard output")
    mp.set_defaults(func=cmd_map)
    hp = sub.add_parser(
        "hash-password",
        help="hash a password (standard input, else a prompt) for [[opcua.users]] password_hash",
    )
    hp.set_defaults(func=cmd_hash_password)
    chk = sub.add_parser("check", help="validate a site map and exit")
    chk.add_argument("map", nargs="?", help="site map (TOML)")
    chk.set_defaults(func=cmd_check)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.log_level)
    result: int = args.func(args)
    return result


if __name__ == "__main__":
    sys.exit(main())
