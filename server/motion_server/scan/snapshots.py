"""Snapshots: the whole controller state at a cycle, saved under a name and restored.

The kernel is deterministic: the same inputs at the same cycles give bit-identical
states. So a snapshot keeps what made the state instead of its objects: the retained
payload the scan started from (or none), and every client write applied since (what, by
which client, before which cycle), up to the cycle it was taken at. Restoring builds the
system afresh from the site map, restores the same retained payload and runs the cycles
again with each write applied where it was: the axes, drives, motion processes,
instruction instances (latched operands, outputs, edges), watchdogs and the clock come
out as they were, and the cycles after it give the trace the original gave, value by
value. The Clock tags (mode, step, snapshots, communication faults) are the host's, not
the controller's: they are neither logged nor restored.

Restoring costs about the time the cycles take to run again (as fast as the fast clock),
from the start of the server, or from the snapshot a restore started from: a snapshot of
a server that has run for hours takes minutes to restore.

A snapshot file (``<data_dir>/snapshots/<name>.json``, JSON) carries a format tag, the
server version, the versions of Python, numpy and ruckig (the floating-point results
depend on them), the site name, a digest of everything in the site map that shapes the
controller (axes, groups, instances and their operands, watchdogs, the tag layout) and a
SHA-256 of its body. A file of another format, version, site map or digest, or one that
is corrupt, is refused with one line naming the file and the reason; nothing is changed.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import ruckig

from .. import __version__
from ..config import SiteMap
from ..image.layout import ImageLayout
from ..safety.client import ClientInfo
from ..tagmap.model import Folder
from ..textfile import Refusal, TextFileError, explain, read_text_file

FORMAT = "motion-server-snapshot/1"
#: snapshot names: what a ``Clock.Snapshot`` number spells, or a word of these characters
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
#: the largest snapshot file read
MAX_BYTES = 256 * 2**20


class SnapshotError(RuntimeError):
    """A snapshot that cannot be saved or restored; the message is one line."""


@dataclass(frozen=True)
class Record:
    """A batch of client writes applied before cycle ``tick + 1``."""

    tick: int
    client: ClientInfo
    items: tuple[tuple[str, float], ...]


@dataclass
class InputLog:
    """What made the controller state: the retained payload it started from and the
    client writes applied since (Clock tags excluded)."""

    base: dict[str, Any] | None = None
    records: list[Record] = field(default_factory=list)

    def add(self, tick: int, client: ClientInfo, items: list[tuple[str, float]]) -> None:
        if items:
            self.records.append(Record(tick, client, tuple(items)))


@dataclass(frozen=True)
class Snapshot:
    name: str
    path: Path
    tick: int
    log: InputLog


def logged(tag_folder: Folder) -> bool:
    """Writes to tags of ``tag_folder`` go to the log (the Clock is the host's)."""
    return tag_folder != Folder.CLOCK


def environment() -> dict[str, str]:
    """The versions a snapshot depends on."""
    return {
        "version": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "ruckig": getattr(ruckig, "__version__", "?"),
    }


def site_digest(site: SiteMap, layout: ImageLayout) -> str:
    """A digest of what shapes the controller: axes, groups, instances with their
    operands, watchdogs and the tag layout."""
    shape = {
        "axes": [repr(c) for c in site.axis_configs()],
        "groups": [repr(g) for g in site.group_configs()],
        "instances": [
            [i.type, i.name, sorted((k, repr(v)) for k, v in i.operands.items())]
            for i in site.instances()
        ],
        "watchdogs": [w.model_dump(mode="json") for w in site.watchdogs],
        "layout": layout.fingerprint,
        "retain_axes": list(site.retain.axes),
    }
    if site.cams:  # the initial points (a site without cams keeps its digest)
        shape["cams"] = [repr(c) for c in site.cam_configs()]
    text = json.dumps(shape, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def check_name(name: str) -> str:
    if not NAME.match(name):
        raise SnapshotError(
            f"snapshot name {name!r}: 1 to 64 letters, digits, '_', '.', '-' "
            "(not starting with '_', '.' or '-')"
        )
    return name


def directory(site: SiteMap) -> Path:
    return Path(site.data_dir) / "snapshots"


def path_of(site: SiteMap, name: str) -> Path:
    return directory(site) / f"{check_name(name)}.json"


def _digest(body: dict[str, Any]) -> str:
    text = json.dumps(body, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _client(c: ClientInfo) -> list[Any]:
    return [c.protocol, c.address, c.port, c.connection, c.user, c.role]


def save(site: SiteMap, layout: ImageLayout, name: str, tick: int, log: InputLog) -> Path:
    """Write snapshot ``name`` of the state at ``tick`` (atomically); its path."""
    path = path_of(site, name)
    body = {
        "site": site.site.name,
        "digest": site_digest(site, layout),
        **environment(),
        "tick": tick,
        "saved": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "base": log.base,
        "records": [[r.tick, _client(r.client), [list(i) for i in r.items]] for r in log.records],
    }
    text = json.dumps({"format": FORMAT, "sha256": _digest(body), "body": body})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        raise SnapshotError(f"{path}: cannot write the snapshot: {exc.strerror or exc}") from None
    return path


#: how a snapshot file's refusals read
_REFUSED = {
    Refusal.TOO_LARGE: f"larger than {MAX_BYTES // 2**20} MiB",
    Refusal.NOT_UTF8: "corrupt snapshot (not UTF-8)",
    Refusal.NOT_REGULAR: "not a regular file",
    Refusal.UNREADABLE: "cannot read the snapshot: {reason}",
}


def _read(path: Path) -> str:
    try:
        return read_text_file(path, MAX_BYTES)
    except FileNotFoundError:
        raise SnapshotError(f"{path}: no such snapshot") from None
    except TextFileError as exc:
        raise SnapshotError(f"{path}: {explain(exc, _REFUSED)}") from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number a snapshot may hold")


def header(path: Path) -> dict[str, Any]:
    """The body of a sound snapshot file (checksum checked, shape not yet)."""
    try:
        doc = json.loads(_read(path), parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise SnapshotError(f"{path}: corrupt snapshot ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise SnapshotError(f"{path}: not a {FORMAT} file")
    body = doc.get("body")
    if not isinstance(body, dict) or doc.get("sha256") != _digest(body):
        raise SnapshotError(f"{path}: checksum mismatch: the snapshot is corrupt")
    return body


def load(site: SiteMap, layout: ImageLayout, name: str) -> Snapshot:
    """Snapshot ``name`` of this site, checked (SnapshotError in one line)."""
    path = path_of(site, name)
    body = header(path)
    if body.get("site") != site.site.name:
        theirs, ours = body.get("site"), site.site.name
        raise SnapshotError(f"{path}: a snapshot of site {theirs!r}, not {ours!r}")
    for key, value in environment().items():
        if body.get(key) != value:
            what = "motion-server" if key == "version" else key
            raise SnapshotError(
                f"{path}: made with {what} {body.get(key)}, this server runs {value}"
            )
    if body.get("digest") != site_digest(site, layout):
        raise SnapshotError(
            f"{path}: made for another site map (axes, groups, instances or watchdogs differ)"
        )
    tags = {t.name: t for t in layout.tags}
    try:
        tick = _count(body.get("tick"))
        base = body.get("base")
        if base is not None and not isinstance(base, dict):
            raise ValueError("base is not a table")
        records: list[Record] = []
        last = 0
        for entry in body.get("records", ()):
            at, client, items = entry
            at = _count(at)
            if at < last or at > tick:
                raise ValueError(f"record at cycle {at} out of order")
            last = at
            protocol, address, port, connection, user, role = client
            info = ClientInfo(
                str(protocol), str(address), int(port), int(connection), str(user), str(role)
            )
            pairs: list[tuple[str, float]] = []
            for tag, value in items:
                t = tags.get(tag)
                if t is None or not t.writable or not logged(t.folder):
                    raise ValueError(f"{tag!r} is not a tag a client writes")
                if isinstance(value, bool) or not isinstance(value, int | float):
                    raise ValueError(f"{tag}: {value!r} is not a number")
                if not math.isfinite(float(value)):
                    raise ValueError(f"{tag}: {value!r} is not finite")
                pairs.append((tag, float(value)))
            records.append(Record(at, info, tuple(pairs)))
    except (TypeError, ValueError) as exc:
        raise SnapshotError(f"{path}: malformed snapshot: {exc}") from None
    return Snapshot(name, path, tick, InputLog(base, records))


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"{value!r} is not a cycle count")
    return value


def listing(site: SiteMap) -> list[tuple[str, dict[str, Any] | str]]:
    """Every snapshot file of the site: (name, its header) or (name, why it is unreadable)."""
    out: list[tuple[str, dict[str, Any] | str]] = []
    folder = directory(site)
    if not folder.is_dir():
        return out
    for path in sorted(folder.glob("*.json"), key=lambda p: p.name):
        name = path.stem
        try:
            body = header(path)
            out.append((name, {k: v for k, v in body.items() if k not in ("base", "records")}))
        except SnapshotError as exc:
            out.append((name, str(exc)))
    return out
