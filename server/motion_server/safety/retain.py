"""Retentive memory: what survives a restart, like a controller's retained tags.

Retained (``[retain]``): the positions of the axes listed in ``axes`` (those with absolute
feedback: the others start at 0 as an incremental encoder does), every axis's homed flag,
and every instruction instance's operand values. Triggers: an ``Execute`` is restored as
it was *and* as already seen, so a trigger that was high makes no rising edge after the
restart (nothing re-fires); level triggers (MC_Power ``Enable``) are not restored, so a
restart never switches a drive on by itself. Power states, faults and motion are not
retained: every axis starts in Axis Ready, at rest.

The file (JSON) carries a format tag, the site name and a SHA-256 of its payload. It is
written atomically (a temporary file in the same directory, flushed and fsynced, then
renamed over the old one), at shutdown and periodically. A file that is torn, corrupt,
of another format or of another site raises :class:`RetainError` naming the file and
the reason; it is never loaded silently. ``motion-server run --fresh`` ignores it.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from ..config import SiteMap
from ..instructions import MotionSystem

FORMAT = "motion-server-retain/1"


class RetainError(RuntimeError):
    """A retain file that cannot be trusted; the message names the file and the reason."""


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
        axes[ax.name] = entry
    operands = {
        name: {
            key: value
            for key, value in inst.inputs.items()
            if key != inst.TRIGGER or inst.TRIGGER == "Execute"
        }
        for name, inst in system.instances.items()
    }
    return {"site": site.site.name, "cycle": ctl.tick, "axes": axes, "operands": operands}


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
    try:
        text = path.read_text("utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise RetainError(f"{path}: cannot read the retain file: {exc}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RetainError(f"{path}: torn or corrupt retain file ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise RetainError(f"{path}: not a {FORMAT} file")
    payload = doc.get("payload")
    if not isinstance(payload, dict) or doc.get("sha256") != _digest(payload):
        raise RetainError(f"{path}: checksum mismatch: the retain file is corrupt")
    if payload.get("site") != site_name:
        raise RetainError(f"{path}: retained for site {payload.get('site')!r}, not {site_name!r}")
    return payload


def restore(system: MotionSystem, payload: dict[str, Any]) -> list[str]:
    """Apply a payload to a system that has not run yet. Returns notes on what was
    skipped (axes or operands the site map no longer has, values of the wrong type)."""
    ctl = system.ctl
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
    return notes
