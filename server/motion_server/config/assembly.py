"""Assembly: everything ``motion-server run`` builds before it serves, built and checked in
one place, so that ``motion-server check`` builds exactly the same.

:func:`assemble` takes a validated :class:`~.schema.SiteMap` (from :func:`.loading.load`,
with any command-line overrides applied) and returns an :class:`Assembly`: the motion
system with the retained state restored, the tag map, the watchdogs, the Modbus access
policy and the OPC UA users. On the way it checks what only the host can tell: that the
data directories and the audit and retain files can be written, that the TLS files load,
and that every listening address can be bound (each is bound and closed again; the
directories and files it had to create are removed). Every failure is a
:class:`~.schema.SiteMapError` of one line per problem, naming file, line and field (or
the environment variable or option that set the field); nothing else escapes.
"""

from __future__ import annotations

import contextlib
import errno
import os
import socket
import ssl
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

from ..instructions import MotionSystem
from ..kernel import ConfigError, MotionError
from ..safety import retain
from ..safety.access import AccessPolicy, plain_role
from ..safety.watchdog import Watchdog
from ..tagmap.layout import plan_tagmap
from ..tagmap.model import TagMap
from .checks import Problem
from .loading import access_problems, opcua_users, problem_lines
from .schema import OpcUaUser, SiteMap, SiteMapError

#: appended to a refused retain file: how to get going again
RETAIN_HINT = "fix or remove the file, or start clean with --fresh"


@dataclass
class Assembly:
    """What ``run`` serves: built from one site map, checked, not yet running."""

    site: SiteMap
    #: the controller and the instruction instances, with the retained state restored
    system: MotionSystem
    tagmap: TagMap
    #: the communication watchdogs (``[[watchdogs]]``) by name, bound to ``system``
    watchdogs: dict[str, Watchdog]
    #: the Modbus access policy (``[modbus.access]``)
    access: AccessPolicy
    #: the OPC UA users: the site map's, overridden by the users secret file's
    users: list[OpcUaUser]
    #: the audit log file (``[audit]``), None when off
    audit_path: Path | None
    #: the retain file (``[retain]``), None when off
    retain_path: Path | None
    #: whether a retain file was restored into ``system``
    restored: bool = False
    #: what the restore skipped (axes or operands the map no longer has)
    retain_notes: list[str] = field(default_factory=list)


def assemble(
    site: SiteMap,
    environ: Mapping[str, str] | None = None,
    *,
    fresh: bool = False,
    probe: bool = True,
) -> Assembly:
    """Build and check everything the site map describes; raise :class:`SiteMapError`.

    ``environ`` (default ``os.environ``) names the users secret file; ``fresh`` ignores
    the retain file (``run --fresh``); ``probe=False`` skips the checks of directories,
    files and ports (tests that build many systems in one process).
    """
    found = site.problems()
    if found:
        _refuse(site, found)
    tagmap, found = plan_tagmap(site)
    found += access_problems(site, tagmap)
    if found:
        _refuse(site, found)
    try:
        system = site.build()
        watchdogs = {w.name: Watchdog(w, system.ctl) for w in site.watchdogs}
    except (ConfigError, MotionError, KeyError, ValueError) as exc:
        raise SiteMapError(site.located((), f"cannot build the system: {exc}")) from None
    users = opcua_users(site, environ)
    access = AccessPolicy(site.modbus.access, tagmap, plain_role(site, bool(users)))
    audit_path = _in_data_dir(site, site.audit.path) if site.audit.enabled else None
    retain_path = retain.retain_path(site) if site.retain.enabled else None
    if probe:
        found = _directory_problems(site, audit_path, retain_path) + _tls_problems(site)
        found += port_problems(site)
        if found:
            _refuse(site, found)
    out = Assembly(site, system, tagmap, watchdogs, access, users, audit_path, retain_path)
    if retain_path is not None and not fresh:
        try:
            payload = retain.load(retain_path, site.site.name)
            if payload is not None:
                out.retain_notes = retain.restore(system, payload, retain_path)
                out.restored = True
        except retain.RetainError as exc:
            raise SiteMapError(f"{exc} ({RETAIN_HINT})") from None
    return out


def _refuse(site: SiteMap, found: list[Problem]) -> NoReturn:
    raise SiteMapError(problem_lines(found, site.located, site.source))


def _in_data_dir(site: SiteMap, name: str) -> Path:
    path = Path(name)
    return path if path.is_absolute() else Path(site.data_dir) / path


# -- directories and files -------------------------------------------------------------------
@contextlib.contextmanager
def _made(directory: Path) -> Iterator[None]:
    """Create ``directory`` and its missing parents, as the server would, and remove
    what was created afterwards."""
    created: list[Path] = []
    missing = []
    p = directory
    while not p.exists():
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    try:
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
        yield
    finally:
        for d in reversed(created):
            with contextlib.suppress(OSError):
                d.rmdir()


def directory_problem(directory: Path) -> str | None:
    """Why the server could not keep files in ``directory`` (None: it can)."""
    try:
        with _made(directory):
            if not directory.is_dir():
                return f"{directory} is not a directory"
            fd, name = tempfile.mkstemp(dir=directory, prefix=".motion-server-check-")
            os.close(fd)
            os.unlink(name)
    except (OSError, ValueError) as exc:
        return f"cannot create a file in {directory}: {_reason(exc)}"
    return None


def file_problem(path: Path) -> str | None:
    """Why the server could not append to (or create) the file ``path`` (None: it can)."""
    try:
        if path.exists() or path.is_symlink():
            if not path.is_file():
                return f"{path} is not a regular file"
            with open(path, "ab"):
                pass
            return None
    except (OSError, ValueError) as exc:
        return f"cannot write {path}: {_reason(exc)}"
    return directory_problem(path.parent)


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc)


def _directory_problems(
    site: SiteMap, audit_path: Path | None, retain_path: Path | None
) -> list[Problem]:
    out: list[Problem] = []
    checks: list[tuple[tuple[str, ...], Path, bool]] = []
    if audit_path is not None:
        checks.append((("audit", "path"), audit_path, True))
    if retain_path is not None:
        checks.append((("retain", "path"), retain_path, True))
    if site.opcua.enabled:
        checks.append((("opcua", "data_dir"), Path(site.opcua.data_dir), False))
    tls = site.modbus.tls
    if site.modbus.enabled and tls.enabled and not tls.cert_file:
        checks.append((("modbus", "tls", "data_dir"), Path(tls.data_dir), False))
    for loc, path, is_file in checks:
        problem = file_problem(path) if is_file else directory_problem(path)
        if problem:
            out.append((loc, problem))
    return out


def _tls_problems(site: SiteMap) -> list[Problem]:
    """The Modbus/TCP Security files load as the server will load them."""
    tls = site.modbus.tls
    if not (site.modbus.enabled and tls.enabled):
        return []
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    if tls.cert_file:
        try:
            ctx.load_cert_chain(tls.cert_file, tls.key_file, password=lambda: b"")
        except (OSError, ssl.SSLError, ValueError) as exc:
            return [(("modbus", "tls", "cert_file"), f"cannot load certificate and key: {exc}")]
    try:
        ctx.load_verify_locations(cafile=tls.ca_file)
    except (OSError, ssl.SSLError, ValueError) as exc:
        return [(("modbus", "tls", "ca_file"), f"cannot load {tls.ca_file}: {_reason(exc)}")]
    return []


# -- listening addresses -----------------------------------------------------------------------
def listeners(site: SiteMap) -> list[tuple[tuple[str, ...], str, int, str]]:
    """(field, host, port, what) of every socket ``run`` listens on."""
    out: list[tuple[tuple[str, ...], str, int, str]] = []
    mb, tls = site.modbus, site.modbus.tls
    if mb.enabled and not (tls.enabled and tls.tls_only):
        out.append((("modbus", "port"), mb.host, mb.port, "Modbus TCP"))
    if mb.enabled and tls.enabled:
        out.append((("modbus", "tls", "port"), mb.host, tls.port, "Modbus/TCP Security"))
    if site.opcua.enabled:
        out.append((("opcua", "port"), site.opcua.host, site.opcua.port, "OPC UA"))
    return out


def port_problems(site: SiteMap) -> list[Problem]:
    """Bind and listen on every address ``run`` will serve (all at once, so that two
    front-ends on one port clash here too), then close them again."""
    out: list[Problem] = []
    with contextlib.ExitStack() as stack:
        for loc, host, port, what in listeners(site):
            family = socket.AF_INET6 if ":" in host else socket.AF_INET
            sock = stack.enter_context(socket.socket(family, socket.SOCK_STREAM))
            # as asyncio's servers do: a port in TIME_WAIT is no obstacle, a listener is
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind((host, port))
                sock.listen(1)
            except OSError as exc:
                out.append((loc, f"{what} cannot listen on {_endpoint(host, port)}: {_why(exc)}"))
    return out


def _endpoint(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def _why(exc: OSError) -> str:
    if exc.errno == errno.EADDRINUSE:
        return "the port is in use"
    if exc.errno == errno.EADDRNOTAVAIL:
        return "not an address of this host"
    if exc.errno == errno.EACCES:
        return "permission denied (ports below 1024 need privileges)"
    return exc.strerror or str(exc)


def describe(assembly: Assembly) -> str:
    """The one-line summary ``check`` prints."""
    system, site = assembly.system, assembly.site
    parts: list[Any] = [
        f"{len(system.ctl.axes)} axes",
        f"{len(system.ctl.groups)} groups",
        f"{len(system.instances)} instruction instances",
        f"{len(assembly.tagmap)} tags",
    ]
    if assembly.watchdogs:
        parts.append(f"{len(assembly.watchdogs)} watchdogs")
    if assembly.restored:
        parts.append("retained state restored")
    return f"{site.source}: ok: {', '.join(parts)}"
