"""``motion-server``: run the server, check a site map, export its tag map.

Bad input on the command line or in the environment is one line on standard error and
exit status 1 (2 for a malformed command line), never a traceback.
"""

from __future__ import annotations

import argparse
import getpass
import logging
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from pydantic import ValidationError

from . import __version__, config
from .cli_bench import add_commands
from .config.assembly import RETAIN_HINT, assemble, describe
from .launch import setup_logging
from .safety.first_user import FirstUserError, ensure_user
from .safety.retain import RetainError
from .supervisor import Supervisor
from .tagmap import FORMATS, build_tagmap, export

log = logging.getLogger("motion_server")

LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")
#: the longest password ``hash-password`` reads from standard input
MAX_PASSWORD_BYTES = 4096


def _load(path: str | None) -> config.SiteMap:
    try:
        return config.load(path)
    except config.SiteMapError as exc:
        raise SystemExit(f"motion-server: {exc}") from None


# -- argument types: one line naming the option for a bad value ---------------------------------
def _setting(
    model: type[config.ControllerSection]
    | type[config.ModbusSection]
    | type[config.OpcUaSection]
    | type[config.WebSection],
    name: str,
    convert: Callable[[str], Any],
) -> Callable[[str], Any]:
    """An argparse type checking a value as the site map's field ``name`` of ``model``
    would (one definition of every bound)."""

    def parse(text: str) -> Any:
        try:
            value = convert(text)
            model.model_validate({name: value})
        except ValueError as exc:
            if isinstance(exc, ValidationError):
                reason = exc.errors()[0]["msg"].removeprefix("Value error, ")
            else:
                reason = "not a finite number" if convert is _finite else "not an integer"
            raise argparse.ArgumentTypeError(f"{text!r}: {reason}") from None
        return value

    parse.__name__ = name
    return parse


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(text)
    return value


def _log_level(text: str) -> str:
    level = text.upper()
    if level not in LOG_LEVELS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected one of {', '.join(LOG_LEVELS)}")
    return level


_scale = _setting(config.ControllerSection, "scale", _finite)
_modbus_host = _setting(config.ModbusSection, "host", str)
_modbus_port = _setting(config.ModbusSection, "port", int)
_opcua_port = _setting(config.OpcUaSection, "port", int)
_web_port = _setting(config.WebSection, "port", int)


def site_for_run(site: config.SiteMap, args: argparse.Namespace) -> config.SiteMap:
    """The site map as ``run`` (and ``check``) use it: the options that override its
    settings applied (``--clock``, ``--scale``, ``--modbus-host``, ``--modbus-port``,
    ``--modbus-role``, ``--no-modbus``, ``--opcua-port``, ``--no-opcua``, ``--web-port``,
    ``--no-web``). Messages about
    an overridden field name the option."""
    sections: dict[str, dict[str, Any]] = {
        "controller": {},
        "modbus": {},
        "opcua": {},
        "web": {},
    }
    origins: dict[tuple[str, str], str] = {}
    for section, key, option, value in (
        ("controller", "clock", "--clock", args.clock),
        ("controller", "scale", "--scale", args.scale),
        ("modbus", "host", "--modbus-host", args.modbus_host),
        ("modbus", "port", "--modbus-port", args.modbus_port),
        ("modbus", "enabled", "--no-modbus", False if args.no_modbus else None),
        ("opcua", "port", "--opcua-port", args.opcua_port),
        ("opcua", "enabled", "--no-opcua", False if args.no_opcua else None),
        ("web", "port", "--web-port", getattr(args, "web_port", None)),
        ("web", "enabled", "--no-web", False if getattr(args, "no_web", False) else None),
    ):
        if value is not None:
            sections[section][key] = value
            origins[(section, key)] = f"option {option}"
    if getattr(args, "modbus_role", None) is not None:
        access = site.modbus.access.model_copy(update={"role": args.modbus_role})
        sections["modbus"]["access"] = access
        origins[("modbus", "access")] = "option --modbus-role"
    update = {
        name: getattr(site, name).model_copy(update=changes)
        for name, changes in sections.items()
        if changes
    }
    if not update:
        return site
    out = site.model_copy(update=update)
    out.locate_overrides(origins)
    return out


def cmd_run(args: argparse.Namespace) -> int:
    """Build and check everything exactly as ``check`` does, then serve: the supervisor
    starts the scan and the front-ends in processes of their own."""
    site = site_for_run(_load(args.map), args)
    try:
        assembly = assemble(site, fresh=args.fresh)
    except config.SiteMapError as exc:
        raise SystemExit(f"motion-server: {exc}") from None
    serve_opcua = site.opcua.enabled
    users = assembly.users
    if serve_opcua:
        try:
            users = ensure_user(site.opcua, users)  # none configured: the generated admin
        except FirstUserError as exc:
            raise SystemExit(f"motion-server: {exc}") from None
    log.info("OPC UA users: %d", len(users))
    log.info("site map %s", site.source)
    supervisor = Supervisor(
        site,
        args.log_level,
        fresh=args.fresh,
        # the web view has OPC UA's users (the generated admin only when OPC UA runs:
        # the web view alone creates no files)
        users=users if serve_opcua or site.web.enabled else [],
        ready_file=Path(args.ready_file) if args.ready_file else None,
    )
    try:
        return supervisor.run()
    except RetainError as exc:
        raise SystemExit(f"motion-server: {exc}\n{RETAIN_HINT}") from None


def cmd_check(args: argparse.Namespace) -> int:
    """Build everything ``run`` builds before it serves, then say so in one line."""
    site = site_for_run(_load(args.map), args)
    try:
        assembly = assemble(site, fresh=args.fresh)
    except config.SiteMapError as exc:
        raise SystemExit(f"motion-server: {exc}") from None
    for note in assembly.retain_notes:
        log.warning("retain: %s", note)
    print(describe(assembly))
    return 0


def cmd_map(args: argparse.Namespace) -> int:
    site = _load(args.map)
    text = export(build_tagmap(site), args.format)
    if args.output:
        try:
            Path(args.output).write_text(text, "utf-8")
        except (OSError, ValueError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise SystemExit(f"motion-server: cannot write {args.output}: {reason}") from None
    else:
        sys.stdout.write(text)
    return 0


def read_password() -> str:
    """A password from a prompt (twice) or the first line of standard input."""
    if sys.stdin.isatty():
        password = getpass.getpass("password: ")
        if getpass.getpass("again: ") != password:
            raise SystemExit("motion-server: the passwords differ")
        return password
    stream = getattr(sys.stdin, "buffer", None)
    try:
        # bytes when standard input has them (a pipe, a file): decoded strictly here
        raw = stream.readline(MAX_PASSWORD_BYTES + 3) if stream else sys.stdin.readline()
        line = raw.decode("utf-8") if isinstance(raw, bytes) else raw
    except UnicodeDecodeError:
        raise SystemExit("motion-server: the password on standard input is not UTF-8") from None
    password = line.rstrip("\r\n")
    if len(password.encode("utf-8", "surrogatepass")) > MAX_PASSWORD_BYTES:
        raise SystemExit(f"motion-server: a password is at most {MAX_PASSWORD_BYTES} bytes")
    return password


def cmd_hash_password(args: argparse.Namespace) -> int:
    """Print the hash of a password read from standard input (first line) or a prompt."""
    from .safety.passwords import hash_password

    password = read_password()
    if not password:
        raise SystemExit("motion-server: empty password")
    print(hash_password(password))
    return 0


class UsageError(SystemExit):
    """A malformed command line: exit status 2, its one line already on standard error
    (``str()`` gives the line too)."""

    def __init__(self, message: str) -> None:
        super().__init__(2)
        self.message = message

    def __str__(self) -> str:
        return self.message


class _Parser(argparse.ArgumentParser):
    """Errors in one line (argparse prints the usage first)."""

    def error(self, message: str) -> NoReturn:
        line = f"{self.prog}: error: {message} (see {self.prog} --help)"
        sys.stderr.write(line + "\n")
        raise UsageError(line)


def _run_options(p: argparse.ArgumentParser) -> None:
    """The options that shape what ``run`` builds (``check`` takes them too)."""
    p.add_argument("map", nargs="?", help="site map (TOML)")
    p.add_argument(
        "--clock",
        choices=["realtime", "scaled", "manual", "fast"],
        help="override the site map's clock mode",
    )
    p.add_argument(
        "--fresh", action="store_true", help="start clean: ignore the retain file ([retain])"
    )
    p.add_argument(
        "--scale", type=_scale, help="simulated seconds per real second (scaled), 0.1 to 100"
    )
    p.add_argument(
        "--modbus-host", type=_modbus_host, help="bind address of Modbus TCP ([modbus] host)"
    )
    p.add_argument(
        "--modbus-port",
        type=_modbus_port,
        help="Modbus TCP port, 0 = ephemeral (site map: [modbus] port)",
    )
    p.add_argument(
        "--modbus-role",
        choices=("viewer", "operator", "admin"),
        help="what plain Modbus TCP clients may write ([modbus.access] role; default: admin "
        "without users or TLS roles, else operator)",
    )
    p.add_argument("--no-modbus", action="store_true", help="do not serve Modbus TCP")
    p.add_argument(
        "--opcua-port", type=_opcua_port, help="OPC UA port, 0 = ephemeral (site map: [opcua] port)"
    )
    p.add_argument("--no-opcua", action="store_true", help="do not serve OPC UA")
    p.add_argument(
        "--web-port",
        type=_web_port,
        help="web view port, 0 = ephemeral (site map: [web] port)",
    )
    p.add_argument("--no-web", action="store_true", help="do not serve the web view")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="motion-server", description=__doc__)
    p.add_argument("--version", action="version", version=f"motion-server {__version__}")
    p.add_argument(
        "--log-level",
        type=_log_level,
        default="INFO",
        help="DEBUG, INFO, WARNING, ERROR (default INFO)",
    )
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run the server (the demo map when no MAP is given)")
    _run_options(run)
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
    chk = sub.add_parser(
        "check",
        help="build everything run builds (system, tag map, users, files, ports), then exit",
    )
    _run_options(chk)
    chk.set_defaults(func=cmd_check)
    add_commands(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.log_level)
    result: int = args.func(args)
    return result


if __name__ == "__main__":
    sys.exit(main())
