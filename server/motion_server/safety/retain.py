"""Retentive memory: what survives a restart, like a controller's retained tags.

Retained (``[retain]``): the positions of the axes listed in ``axes`` (those with absolute
feedback: the others start at 0 as an incremental encoder does) with what redefinitions
added to their feedback (the homing sensors stay where they are), every axis's homed flag,
and every instruction instance's operand values. Triggers: an ``Execute`` is restored as
it was *and* as already seen, so a trigger that was high makes no rising edge after the
restart (nothing re-fires); level triggers (MC_Power ``Enable``) are not restored, so a
restart never switches a drive on by itself. Power states, faults and motion are not
retained: every axis starts in Axis Ready, at rest. The cam tables' points and ``Length``
are retained like operands; their profiles are not (a real controller keeps its
CAM_PROFILE arrays, but they are what MCCP computed from the points: every ProfileStatus
starts at 0 and the program computes them again, see docs/semantics.md).

The file (JSON) carries a format tag, the site name and a SHA-256 of its payload. It is
written atomically (a temporary file in the same directory, flushed and fsynced, then
renamed over the old one), at shutdown and periodically. A file that is torn, corrupt,
of another format or of another site raises :class:`RetainError` naming the file and
the reason; it is never loaded silently. ``motion-server run --fresh`` ignores it.

A sound checksum is not enough: the payload must have the shape :func:`snapshot` writes
(tables where tables belong, a boolean ``homed``, positions and operands that are finite
numbers of their tag's type, positions within 2**53 encoder counts, where every count is
still a distinct float). Anything else is refused as a whole, before a single value is
applied, with one line naming the file and the entry.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any

from ..config.checks import operand_problem
from ..config.schema import SiteMap
from ..instructions import MotionSystem
from ..textfile import Refusal, TextFileError, explain, read_text_file

FORMAT = "motion-server-retain/1"
#: a retain file larger than this is refused unread (it holds a few numbers per tag)
MAX_RETAIN_BYTES = 64 * 2**20
#: a retained position may be at most this many encoder counts from zero (float64 holds
#: every integer up to 2**53: beyond, positions could not be quantised to single counts)
MAX_POSITION_COUNTS = 2.0**53


class RetainError(RuntimeError):
    """A retain file that cannot be trusted; the message names the file and the reason."""


class Payload(dict[str, Any]):
    """The payload of a retain file, and the file it came from (for messages)."""

    def __init__(self, data: dict[str, Any], path: Path) -> None:
        super().__init__(data)
        self.path = path


def retain_path(site: SiteMap) -> Path:
    path = Path(site.retain.path)
    return path if path.is_absolute() else Path(site.data_dir) / path


def snapshot(site: SiteMap, system: MotionSystem) -> dict[str, Any]:
    """The retained values of a running system (plain JSON types)."""
    ctl = system.ctl
    absolute = set(site.retain.axes)
    axes: dict[str, Any] = {}
    for ax in ctl.axes:
        entry: dict[str, Any] = {"homed": bool(ax.homed)}
        if ax.name in absolute:
            entry["position"] = float(ctl.act_x[ax.index])
            if ax.position_offset:
                # what redefinitions (homing, MRP) added: the sensors stay on the machine
                entry["offset"] = float(ax.position_offset)
        axes[ax.name] = entry
    operands = {
        name: {
            key: value
            for key, value in inst.inputs.items()
            if key != inst.TRIGGER or inst.TRIGGER == "Execute"
        }
        for name, inst in system.instances.items()
    }
    payload = {"site": site.site.name, "cycle": ctl.tick, "axes": axes, "operands": operands}
    if ctl.cams.tables:
        payload["cams"] = {
            t.name: {
                "length": t.length,
                "master": list(t.master),
                "slave": list(t.slave),
                "segment": list(t.segment),
            }
            for t in ctl.cams.tables.values()
        }
    return payload


def _digest(payload: dict[str, Any]) -> str:
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def save(path: Path, payload: dict[str, Any]) -> None:
    """Write atomically: readers see the old file or the new one, never a mix."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = json.dumps({"format": FORMAT, "sha256": _digest(payload), "payload": payload})
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def load(path: Path, site_name: str) -> dict[str, Any] | None:
    """The payload of a sound retain file; None when there is none; else RetainError."""
    text = _read(path)
    if text is None:
        return None
    try:
        doc = json.loads(text, parse_constant=_no_constant)
    except (json.JSONDecodeError, ValueError, RecursionError) as exc:
        raise RetainError(f"{path}: torn or corrupt retain file ({_reason(exc)})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise RetainError(f"{path}: not a {FORMAT} file")
    payload = doc.get("payload")
    if not isinstance(payload, dict) or doc.get("sha256") != _digest(payload):
        raise RetainError(f"{path}: checksum mismatch: the retain file is corrupt")
    problem = _shape_problem(payload)
    if problem:
        raise RetainError(f"{path}: malformed retain file: {problem}")
    if payload["site"] != site_name:
        raise RetainError(f"{path}: retained for site {payload['site']!r}, not {site_name!r}")
    return Payload(payload, path)


#: how the retain file's refusals read
_REFUSED = {
    Refusal.TOO_LARGE: f"retain file larger than {MAX_RETAIN_BYTES // 2**20} MiB",
    Refusal.NOT_UTF8: "torn or corrupt retain file (not UTF-8)",
    Refusal.NOT_REGULAR: "cannot read the retain file: not a regular file",
    Refusal.UNREADABLE: "cannot read the retain file: {reason}",
}


def _read(path: Path) -> str | None:
    """The file's text; None when there is none. Regular files of a bounded size only."""
    try:
        return read_text_file(path, MAX_RETAIN_BYTES)
    except FileNotFoundError:
        return None
    except TextFileError as exc:
        raise RetainError(f"{path}: {explain(exc, _REFUSED)}") from None


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    if isinstance(exc, RecursionError):
        return "nested too deeply"
    return str(exc)


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number a retain file may hold")


def _number(value: Any) -> bool:
    """A finite int or float (not a boolean)."""
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _shape_problem(payload: dict[str, Any]) -> str | None:
    """Why a payload does not have the shape :func:`snapshot` writes (None: it does)."""
    keys = {"site", "cycle", "axes", "operands"}
    if set(payload) - {"cams"} != keys:
        return f"payload keys {sorted(payload)}, expected {sorted(keys)} (and cams)"
    if not isinstance(payload["site"], str):
        return "site: not a string"
    cycle = payload["cycle"]
    if isinstance(cycle, bool) or not isinstance(cycle, int) or cycle < 0:
        return "cycle: not a cycle count"
    axes, operands = payload["axes"], payload["operands"]
    if not isinstance(axes, dict):
        return "axes: not a table"
    for name, entry in axes.items():
        if not isinstance(entry, dict):
            return f"axes.{name}: not a table"
        if not set(entry) <= {"homed", "position", "offset"} or not isinstance(
            entry.get("homed"), bool
        ):
            return f"axes.{name}: expected homed (a boolean), position and offset"
        for key in ("position", "offset"):
            if key in entry and not _number(entry[key]):
                return f"axes.{name}.{key}: {entry[key]!r} is not a finite number"
    if not isinstance(operands, dict):
        return "operands: not a table"
    for name, values in operands.items():
        if not isinstance(values, dict):
            return f"operands.{name}: not a table"
        for key, value in values.items():
            if not (isinstance(value, bool) or _number(value)):
                return f"operands.{name}.{key}: {value!r} is not a finite number or boolean"
    return _cams_problem(payload.get("cams", {}))


#: a cam table's retained entry
_CAM_KEYS = {"length", "master", "slave", "segment"}
_DINT = (-(2**31), 2**31 - 1)
#: the largest Logix REAL: a cam point is one
_REAL_MAX = 3.4028234663852886e38


def _dint(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and _DINT[0] <= value <= _DINT[1]


def _cams_problem(cams: Any) -> str | None:
    """Why the ``cams`` entry is not what :func:`snapshot` writes (None: it is)."""
    if not isinstance(cams, dict):
        return "cams: not a table"
    for name, entry in cams.items():
        if not isinstance(entry, dict) or set(entry) != _CAM_KEYS:
            return f"cams.{name}: expected {', '.join(sorted(_CAM_KEYS))}"
        if not _dint(entry["length"]):
            return f"cams.{name}.length: {entry['length']!r} is not a DINT"
        for key in ("master", "slave", "segment"):
            values = entry[key]
            if not isinstance(values, list):
                return f"cams.{name}.{key}: not a list"
            for k, v in enumerate(values):
                ok = _dint(v) if key == "segment" else _number(v) and abs(v) <= _REAL_MAX
                if not ok:
                    kind = "a DINT" if key == "segment" else "a finite REAL"
                    return f"cams.{name}.{key}[{k}]: {v!r} is not {kind}"
    return None


def restore(system: MotionSystem, payload: dict[str, Any], path: Path | str = "") -> list[str]:
    """Apply a payload (from :func:`load`) to a system that has not run yet. Returns notes
    on what was skipped (axes or operands the site map no longer has, values of another
    type). A value the system cannot hold raises :class:`RetainError` naming the file
    (``path``, else the one the payload was loaded from) before anything is applied."""
    ctl = system.ctl
    problem = _value_problem(system, payload)
    if problem:
        where = path or getattr(payload, "path", "") or "retain file"
        raise RetainError(f"{where}: malformed retain file: {problem}")
    notes: list[str] = []
    names = {ax.name: ax for ax in ctl.axes}
    for name, entry in payload.get("axes", {}).items():
        ax = names.get(name)
        if ax is None:
            notes.append(f"axis {name} is no longer configured")
            continue
        ax.homed = bool(entry.get("homed", False))
        pos = entry.get("position")
        if isinstance(pos, int | float):
            i = ax.index
            ctl.act_x[i] = ctl.act_pos[i] = ctl.cmd_pos[i] = ctl.drv_cmd[i] = float(pos)
            ax.base = float(pos)
            ax.position_offset = float(entry.get("offset", 0.0))
    for name, values in payload.get("operands", {}).items():
        inst = system.instances.get(name)
        if inst is None:
            notes.append(f"instance {name} is no longer configured")
            continue
        for key, value in values.items():
            if key not in inst.inputs or type(value) is not type(inst.inputs[key]):
                notes.append(f"{name}.{key}: not restored")
                continue
            inst.inputs[key] = value
        if inst.TRIGGER == "Execute":
            inst._last_trigger = bool(inst.inputs["Execute"])  # high: already seen
    tables = {t.name: t for t in ctl.cams.tables.values()}
    for name, entry in payload.get("cams", {}).items():
        table = tables.get(name)
        if table is None:
            notes.append(f"cam table {name} is no longer configured")
            continue
        n = min(table.capacity, len(entry["master"]), len(entry["slave"]), len(entry["segment"]))
        if n < table.capacity or n < len(entry["master"]):
            notes.append(f"cam table {name}: {n} of its {table.capacity} elements restored")
        table.master[:n] = [float(v) for v in entry["master"][:n]]
        table.slave[:n] = [float(v) for v in entry["slave"][:n]]
        table.segment[:n] = [int(v) for v in entry["segment"][:n]]
        table.length = int(entry["length"])
    return notes


def _value_problem(system: MotionSystem, payload: dict[str, Any]) -> str | None:
    """Why a well-shaped payload cannot be applied to ``system`` (None: it can)."""
    axes = {ax.name: ax for ax in system.ctl.axes}
    for name, entry in payload["axes"].items():
        ax = axes.get(name)
        if ax is None:
            continue
        cpu, units = ax.config.counts_per_unit, ax.config.units
        for key in ("position", "offset"):
            value = entry.get(key)
            if value is not None and not abs(float(value)) * cpu <= MAX_POSITION_COUNTS:
                return (
                    f"axes.{name}.{key}: {value:g} {units} is beyond 2**53 encoder counts "
                    f"({cpu:g} counts/{units})"
                )
    for name, values in payload["operands"].items():
        inst = system.instances.get(name)
        if inst is None:
            continue
        for key, value in values.items():
            if key not in inst.inputs or type(value) is not type(inst.inputs[key]):
                continue  # a changed map: skipped with a note
            problem = operand_problem(type(inst).operand(key), value)
            if problem:
                return f"operands.{name}.{key}: {problem}"
    return None
