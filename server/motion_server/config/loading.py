"""Loading site maps: files, the environment, and where every field was written.

:func:`parse` turns TOML text into a validated :class:`~.schema.SiteMap`: the schema, the
cross-field checks, the register layout and the access rules' references. Every problem
becomes one line naming file, line and field (or the environment variable that set the
value); a map with many problems shows the first :data:`MAX_PROBLEM_LINES`. Files are read
with a size limit, and only regular files (``check /dev/zero`` is refused at once).

Settings of the single-table sections can be overridden from the environment (containers,
CI benches): see :func:`environment_settings`. A ``MOTION_SERVER_`` variable that is no
setting is reported by :func:`unknown_variables` (a misspelt one would otherwise be
ignored silently).
"""

from __future__ import annotations

import difflib
import logging
import os
import re
import tomllib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..tagmap.layout import plan_tagmap
from ..tagmap.model import TagMap
from ..textfile import Refusal, TextFileError, read_text_file
from .checks import Problem, duplicates
from .schema import (
    DATA_DIR_ENV,
    DEFAULT_USERS_FILE,
    DEMO_MAP,
    ENV_PREFIX,
    MAP_ENV,
    USERS_FILE_ENV,
    OpcUaUser,
    SiteMap,
    SiteMapError,
    UsersFile,
    _Model,
    default_data_dir,
)

log = logging.getLogger("motion_server.config")

#: ``MOTION_SERVER_`` variables that are not per-setting overrides
OTHER_VARIABLES = (MAP_ENV, USERS_FILE_ENV, DATA_DIR_ENV)
#: a site map or users file larger than this is refused unread (10,000 axes take 0.5 MiB)
MAX_FILE_BYTES = 16 * 2**20
#: a map with more problems shows this many lines, then how many more there are
MAX_PROBLEM_LINES = 20

_KEY = r"""(?:[A-Za-z0-9_-]+|"(?:[^"\\]|\\.)*"|'[^']*')"""
_DOTTED = rf"{_KEY}(?:\s*\.\s*{_KEY})*"
_HEADER = re.compile(rf"^\s*(\[\[?)\s*({_DOTTED})\s*\]\]?\s*(?:#.*)?$")
_ASSIGN = re.compile(rf"^\s*({_DOTTED})\s*=(.*)$")
_KEY_PART = re.compile(_KEY)
_TOML_LINE = re.compile(r"\(at line (\d+), column \d+\)")
_MULTILINE = re.compile(r"\"\"\"|\'\'\'")

Loc = tuple[int | str, ...]


def _key_parts(dotted: str) -> tuple[str, ...]:
    parts = []
    for m in _KEY_PART.finditer(dotted):
        text = m.group(0)
        if text[0] in "\"'":
            text = text[1:-1]
        parts.append(text)
    return tuple(parts)


class _ValueScanner:
    """Follows a TOML value across lines (strings, arrays, inline tables) so that lines
    inside it are not taken for keys, and notes the line of every top-level element of an
    array value (``axes = [ {...}, {...} ]``)."""

    def __init__(self, index: dict[Loc, int], path: Loc) -> None:
        self.index = index
        self.path = path
        self.stack: list[str] = []
        self.multiline: str | None = None
        self.element = -1
        self.expect = False

    @property
    def open(self) -> bool:
        return bool(self.stack) or self.multiline is not None

    def feed(self, text: str, line: int) -> None:
        if not self.open and not any(c in text for c in "[{") and not _MULTILINE.search(text):
            return  # a value on one line (most of them): nothing can stay open
        i, n = 0, len(text)
        while i < n:
            if self.multiline is not None:
                end = text.find(self.multiline, i)
                if end < 0:
                    return
                i = end + 3
                self.multiline = None
                continue
            c = text[i]
            if c == "#":
                return
            if c.isspace() or (c == "," and self.stack != ["["]):
                i += 1
                continue
            if c == ",":
                self.expect = True
                i += 1
                continue
            if self.stack == ["["] and self.expect and c != "]":
                self.element += 1
                self.index.setdefault((*self.path, self.element), line)
                self.expect = False
            if c in "[{":
                self.stack.append(c)
                if self.stack == ["["]:
                    self.expect = True
                i += 1
            elif c in "]}":
                if self.stack:
                    self.stack.pop()
                i += 1
            elif text.startswith(('"""', "'''"), i):
                self.multiline = text[i : i + 3]
                i += 3
            elif c == '"':
                i = _string_end(text, i + 1, escapes=True)
            elif c == "'":
                i = _string_end(text, i + 1, escapes=False)
            else:
                i += 1


def _string_end(text: str, i: int, escapes: bool) -> int:
    quote = text[i - 1]
    while i < len(text):
        if escapes and text[i] == "\\":
            i += 2
            continue
        if text[i] == quote:
            return i + 1
        i += 1
    return i


def _index(text: str) -> dict[Loc, int]:
    """Field path -> line (1-based) of its assignment or table header, in one pass."""
    index: dict[Loc, int] = {}
    arrays: dict[Loc, int] = {}
    table: Loc = ()
    value: _ValueScanner | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        if value is not None and value.open:
            value.feed(line, number)
            continue
        header = _HEADER.match(line)
        if header:
            parts = _key_parts(header.group(2))
            path: Loc = ()
            for part in parts[:-1]:
                path = (*path, part)
                if path in arrays:
                    path = (*path, arrays[path])
            path = (*path, parts[-1])
            if header.group(1) == "[[":
                index.setdefault(path, number)
                arrays[path] = arrays.get(path, -1) + 1
                path = (*path, arrays[path])
            table = path
            index.setdefault(table, number)
            continue
        assign = _ASSIGN.match(line)
        if assign:
            parts = _key_parts(assign.group(1))
            for k in range(1, len(parts) + 1):
                index.setdefault((*table, *parts[:k]), number)
            value = _ValueScanner(index, (*table, *parts))
            value.feed(assign.group(2), number)
    return index


@dataclass
class Locations:
    """Where the fields of one site map were written: its text, its name, and what
    replaced fields of the file (``(section, field) -> "environment MOTION_SERVER_..."``
    or a command-line option)."""

    text: str
    source: str
    origins: dict[tuple[str, str], str] = field(default_factory=dict)
    _index: dict[Loc, int] | None = field(default=None, compare=False, repr=False)

    def overridden(self, origins: Mapping[tuple[str, str], str]) -> Locations:
        """These locations with more fields set elsewhere (``--modbus-port``, ...)."""
        return Locations(self.text, self.source, {**self.origins, **origins}, self._index)

    def line(self, loc: Sequence[int | str]) -> int:
        """The line of the field, else of the nearest enclosing table or key (1: none)."""
        if self._index is None:
            self._index = _index(self.text)
        key = tuple(loc)
        while key:
            found = self._index.get(key)
            if found is not None:
                return found
            key = key[:-1]
        return 1

    def describe(self, loc: Sequence[int | str], message: str) -> str:
        if len(loc) > 1:
            origin = self.origins.get((str(loc[0]), str(loc[1])))
            if origin:
                return f"{self.source}: {origin}: {message}"
        name = ".".join(str(p) for p in loc) or "(top level)"
        return f"{self.source}:{self.line(loc)}: {name}: {message}"


def problem_lines(
    found: Sequence[Problem], describe: Callable[[Loc, str], str], source: str
) -> str:
    """The message of a :class:`SiteMapError`: one line per problem (``describe`` names
    where), at most :data:`MAX_PROBLEM_LINES` of them, then how many more there are."""
    lines = [describe(loc, msg) for loc, msg in found[:MAX_PROBLEM_LINES]]
    if len(found) > MAX_PROBLEM_LINES:
        lines.append(f"{source}: ... and {len(found) - MAX_PROBLEM_LINES} more problems")
    return "\n".join(lines)


def read_text(path: str | Path, what: str = "site map") -> str:
    """The text of a regular file of at most :data:`MAX_FILE_BYTES`, as UTF-8;
    :class:`SiteMapError` naming the file otherwise. Never blocks on a FIFO or a device."""
    p = Path(path)
    try:
        return read_text_file(p, MAX_FILE_BYTES)
    except FileNotFoundError as exc:
        raise SiteMapError(f"{p}: cannot read {what}: {exc.strerror}") from None
    except TextFileError as exc:
        mib = MAX_FILE_BYTES // 2**20
        if exc.refusal == Refusal.NOT_UTF8:
            raise SiteMapError(f"{p}:{exc.line}: {what} is not UTF-8 text") from None
        if exc.refusal == Refusal.TOO_LARGE:
            size = f"{exc.size} bytes, " if exc.size else ""
            reason = f"{size}more than {mib} MiB"
        elif exc.refusal == Refusal.NOT_REGULAR:
            reason = "not a regular file"
        else:
            reason = exc.reason
        raise SiteMapError(f"{p}: cannot read {what}: {reason}") from None


def _toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        found = _TOML_LINE.search(str(exc))
        where = f"{source}:{found.group(1)}" if found else source
        raise SiteMapError(f"{where}: invalid TOML: {exc}") from None
    except RecursionError:
        raise SiteMapError(f"{source}: invalid TOML: arrays or tables nested too deeply") from None


def _validation_problems(exc: ValidationError) -> list[Problem]:
    return [(tuple(e["loc"]), e["msg"].removeprefix("Value error, ")) for e in exc.errors()]


def parse(text: str, source: str = "<memory>", environ: Mapping[str, str] | None = None) -> SiteMap:
    """Validate a site map text; ``environ`` settings (see :func:`environment_settings`)
    replace the TOML values before validation, so every check sees them."""
    data = _toml(text, source)
    if "data_dir" not in data:  # never the working directory (see default_data_dir)
        site_table = data.get("site")
        name = site_table.get("name", "site") if isinstance(site_table, dict) else "site"
        data["data_dir"] = default_data_dir(name, os.environ if environ is None else environ)
    overrides = environment_settings(environ or {})
    for (section, key), (_, value) in overrides.items():
        table = data.setdefault(section, {})
        if isinstance(table, dict):
            table[key] = value
    where = Locations(text, source, {k: f"environment {var}" for k, (var, _) in overrides.items()})
    try:
        site = SiteMap.model_validate({**data, "source": source})
    except ValidationError as exc:
        found = _validation_problems(exc)
    except RecursionError:
        raise SiteMapError(f"{source}: arrays or tables nested too deeply") from None
    else:
        site._locator = where
        found = static_problems(site)
    if found:
        raise SiteMapError(problem_lines(found, where.describe, source))
    return site


def static_problems(site: SiteMap) -> list[Problem]:
    """Everything wrong with a site map that needs no file, port or clock: the schema's
    cross-field checks, then the register layout and the access rules' references."""
    found = site.problems()
    if found:
        return found
    tagmap, found = plan_tagmap(site)
    return found + access_problems(site, tagmap)


def access_problems(site: SiteMap, tagmap: TagMap) -> list[Problem]:
    """Entries of ``[modbus.access]`` rules that name no writable tag of the map."""
    out: list[Problem] = []
    for ri, rule in enumerate(site.modbus.access.rules):
        for entry in rule.write:
            if re.fullmatch(r"\s*\d+\s*-\s*\d+\s*", entry):
                continue
            tags = tagmap.named(entry)
            where = ("modbus", "access", "rules", ri, "write")
            if not tags:
                out.append((where, f"{entry!r} names no folder, owner or tag of the tag map"))
            elif not any(t.writable for t in tags):
                out.append((where, f"{entry!r} names no writable tag"))
    return out


def _sections() -> Iterable[tuple[str, type[_Model]]]:
    for section, info in SiteMap.model_fields.items():
        model = info.annotation
        if isinstance(model, type) and issubclass(model, _Model):
            yield section, model


def environment_settings(environ: Mapping[str, str]) -> dict[tuple[str, str], tuple[str, str]]:
    """``MOTION_SERVER_<SECTION>_<FIELD>`` variables: (section, field) -> (variable, value).

    Every field of a single-table section (``[site]``, ``[controller]``, ``[modbus]``, ...)
    can be set this way, e.g. ``MOTION_SERVER_MODBUS_HOST=0.0.0.0`` in a container or
    ``MOTION_SERVER_CONTROLLER_CLOCK=manual`` on a test bench. The values are validated like
    the TOML ones; an invalid one is a :class:`SiteMapError` naming the variable.
    """
    found: dict[tuple[str, str], tuple[str, str]] = {}
    for section, model in _sections():
        for name in model.model_fields:
            var = f"{ENV_PREFIX}{section}_{name}".upper()
            if var in environ:
                found[(section, name)] = (var, environ[var])
    return found


def setting_variables() -> list[str]:
    """Every ``MOTION_SERVER_`` variable the server reads."""
    names = [
        f"{ENV_PREFIX}{section}_{name}".upper()
        for section, model in _sections()
        for name in model.model_fields
    ]
    return [*names, *OTHER_VARIABLES]


def unknown_variables(environ: Mapping[str, str]) -> list[str]:
    """One warning for every ``MOTION_SERVER_`` variable that the server does not read
    (a misspelt setting), with the nearest known name."""
    known = setting_variables()
    out = []
    for var in sorted(environ):
        if var.startswith(ENV_PREFIX) and var not in known:
            near = difflib.get_close_matches(var, known, n=1, cutoff=0.75)
            hint = f" (did you mean {near[0]}?)" if near else ""
            out.append(f"environment {var} is not a motion-server setting; ignored{hint}")
    return out


def load(path: str | Path | None = None, environ: Mapping[str, str] | None = None) -> SiteMap:
    """Load a site map file, or (``path`` None) the file named by ``MOTION_SERVER_MAP``,
    else the embedded demo map, with the settings of the environment (``environ``,
    default ``os.environ``) applied. Unknown ``MOTION_SERVER_`` variables are logged as
    warnings."""
    env = os.environ if environ is None else environ
    for warning in unknown_variables(env):
        log.warning("%s", warning)
    if path is None and env.get(MAP_ENV):
        path = env[MAP_ENV]
    if path is None:
        text = resources.files("motion_server").joinpath("data", DEMO_MAP).read_text("utf-8")
        return parse(text, f"<embedded {DEMO_MAP}>", env)
    return parse(read_text(path), str(path), env)


def users_file_path(environ: Mapping[str, str] | None = None) -> Path | None:
    """The users secret file: ``$MOTION_SERVER_USERS_FILE``, else
    ``/run/secrets/motion_server_users`` when it exists, else None."""
    env = os.environ if environ is None else environ
    named = env.get(USERS_FILE_ENV)
    if named:
        return Path(named)
    default = Path(DEFAULT_USERS_FILE)
    return default if default.is_file() else None


def load_users_file(path: str | Path) -> list[OpcUaUser]:
    """The ``[[users]]`` of a users secret file; :class:`SiteMapError` naming file, line
    and field (never the hash itself) when it cannot be used."""
    p = Path(path)
    text = read_text(p, "users file")
    data = _toml(text, str(p))
    where = Locations(text, str(p))
    try:
        parsed = UsersFile.model_validate(data)
    except ValidationError as exc:
        found = [
            (loc, "not a password hash (motion-server hash-password prints one)")
            if loc and loc[-1] == "password_hash" and not msg.startswith("unusable")
            else (loc, msg)
            for loc, msg in _validation_problems(exc)
        ]
        raise SiteMapError(problem_lines(found, where.describe, str(p))) from None
    except RecursionError:
        raise SiteMapError(f"{p}: arrays or tables nested too deeply") from None
    problems = duplicates([u.name for u in parsed.users], ("users",), "name")
    if problems:
        raise SiteMapError(problem_lines(problems, where.describe, str(p)))
    return parsed.users


def opcua_users(site: SiteMap, environ: Mapping[str, str] | None = None) -> list[OpcUaUser]:
    """The site map's OPC UA users, overridden by name by those of the users secret file."""
    users = {u.name: u for u in site.opcua.users}
    path = users_file_path(environ)
    if path is not None:
        users |= {u.name: u for u in load_users_file(path)}
    return list(users.values())
