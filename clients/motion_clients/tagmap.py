"""The client's view of a site: the ``motion-server-map/1`` JSON export, and value codecs.

A :class:`ClientMap` is loaded from the JSON export (a file, a dict, or the output of
``motion-server map --format json``). It knows each tag's type, access, Modbus registers
and OPC UA node, enumerations, and the server's error table. Values are converted to and
from 16-bit holding registers by :mod:`.codec` (the server's own codec), in the map's
word order.
"""

from __future__ import annotations

import difflib
import json
import shutil
import subprocess
import sys
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import codec

MAP_FORMAT = "motion-server-map/1"

Value = bool | int | float

_INT_RANGE = {
    "SINT": (-128, 127),
    "INT": (-32768, 32767),
    "DINT": (-(2**31), 2**31 - 1),
    "UDINT": (0, 2**32 - 1),
}


class MapError(ValueError):
    """A map that is not a ``motion-server-map/1`` export, or a name it does not hold."""


@dataclass(frozen=True)
class MapTag:
    """One tag of the map: what a back-end needs to read or write it."""

    name: str
    type: str
    access: str
    address: int
    count: int
    node_id: str
    bit: int | None = None
    enum: dict[str, int] = field(default_factory=dict)
    units: str = ""
    description: str = ""

    @property
    def owner(self) -> str:
        return self.name.split(".", 1)[0]

    @property
    def field(self) -> str:
        return self.name.split(".", 1)[1]

    @property
    def writable(self) -> bool:
        return self.access == "read_write"

    @property
    def is_float(self) -> bool:
        return self.type in ("REAL", "LREAL")

    def coerce(self, value: Value | str) -> Value:
        """``value`` as this tag's Python type; accepts enum names and numeric strings."""
        if isinstance(value, str):
            text = value.strip()
            if text.upper() in self.enum:
                return self.enum[text.upper()]
            if self.type == "BOOL" and text.lower() in ("true", "false", "on", "off"):
                return text.lower() in ("true", "on")
            try:
                value = float(text) if self.is_float else int(text, 0)
            except ValueError:
                if self.enum:
                    names = ", ".join(f"{k} ({v})" for k, v in self.enum.items())
                    raise MapError(
                        f"{self.name}: {value!r} is not one of its names: {names}"
                    ) from None
                raise MapError(f"{self.name}: {value!r} is not a {self.type}") from None
        if self.type == "BOOL":
            return bool(value)
        if self.is_float:
            return float(value)
        if isinstance(value, float) and not value.is_integer():
            raise MapError(f"{self.name}: {value} is not an integer ({self.type})")
        number = int(value)
        lo, hi = _INT_RANGE[self.type]
        if not lo <= number <= hi:
            raise MapError(f"{self.name}: {number} outside the {self.type} range {lo}..{hi}")
        return number

    def label(self, value: Value) -> str:
        """The value for people: enum names spelled out, units appended."""
        if self.type == "BOOL":
            return "1" if value else "0"
        names = {v: k for k, v in self.enum.items()}
        if isinstance(value, int) and value in names:
            return f"{value} ({names[value]})"
        text = f"{value:.6g}" if isinstance(value, float) else str(value)
        return f"{text} {self.units}" if self.units else text


def encode(tag: MapTag, value: Value, word_order: str = "big") -> list[int]:
    """Registers holding ``value`` (not for BOOLs: they are bits, see the back-end)."""
    return codec.encode(tag.type, tag.coerce(value), word_order)


def decode(tag: MapTag, regs: Sequence[int], word_order: str = "big") -> Value:
    """The value held in ``regs`` (``tag.count`` registers from ``tag.address``)."""
    if tag.type == "BOOL":
        return bool(regs[0] >> (tag.bit or 0) & 1)
    return codec.decode(tag.type, regs, word_order)


class ClientMap:
    """Every tag of a site by name, plus the Modbus/OPC UA settings and the error table."""

    def __init__(self, doc: dict[str, Any]) -> None:
        if doc.get("format") != MAP_FORMAT:
            raise MapError(f"not a {MAP_FORMAT} map (format = {doc.get('format')!r})")
        self.site: str = doc.get("site", "")
        self.word_order: str = doc["modbus"]["word_order"]
        self.unit_id: int = int(doc["modbus"]["unit_id"])
        self.namespace_uri: str = doc["opcua"]["namespace_uri"]
        self.errors: dict[int, str] = {int(k): v for k, v in doc.get("errors", {}).items()}
        self._tags: dict[str, MapTag] = {}
        for rec in doc["tags"]:
            tag = MapTag(
                name=rec["name"],
                type=rec["type"],
                access=rec["access"],
                address=int(rec["modbus"]["address"]),
                count=int(rec["modbus"]["count"]),
                bit=rec["modbus"].get("bit"),
                node_id=rec["opcua"]["node_id"],
                enum=dict(rec.get("enum", {})),
                units=rec.get("units", ""),
                description=rec.get("description", ""),
            )
            self._tags[tag.name] = tag

    # -- loading ----------------------------------------------------------------------------
    @classmethod
    def from_file(cls, path: str | Path) -> ClientMap:
        try:
            doc = json.loads(Path(path).read_text("utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise MapError(f"{path}: cannot read the map: {exc}") from None
        return cls(doc)

    @classmethod
    def from_server(cls, site: str | Path | None = None) -> ClientMap:
        """Run ``motion-server map --format json [site]`` and load its output."""
        exe = shutil.which("motion-server")
        cmd = [exe] if exe else [sys.executable, "-m", "motion_server.cli"]
        cmd += ["map", "--format", "json"]
        if site is not None:
            cmd.append(str(site))
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise MapError(f"{' '.join(cmd)} failed: {proc.stderr.strip() or proc.stdout}")
        return cls(json.loads(proc.stdout))

    @classmethod
    def load(cls, source: str | Path | None = None) -> ClientMap:
        """A ``.json`` export as it is; a site map (``.toml``) or None through the server."""
        if source is not None and str(source).endswith(".json"):
            return cls.from_file(source)
        return cls.from_server(source)

    # -- look-ups ---------------------------------------------------------------------------
    def tag(self, name: str) -> MapTag:
        try:
            return self._tags[name]
        except KeyError:
            hint = _nearest(name, self._tags)
            raise MapError(f"no tag {name!r} in the map of site {self.site!r}{hint}") from None

    def __contains__(self, name: object) -> bool:
        return name in self._tags

    def __iter__(self) -> Iterator[MapTag]:
        return iter(self._tags.values())

    def owned_by(self, owner: str) -> list[MapTag]:
        """The tags of an axis, group, instance, ``Clock`` or ``Diagnostics``."""
        tags = [t for t in self._tags.values() if t.owner == owner]
        if not tags:
            hint = _nearest(owner, {t.owner for t in self._tags.values()})
            raise MapError(f"no axis, group or instance {owner!r} in the map{hint}")
        return tags

    def expand(self, names: Sequence[str]) -> list[MapTag]:
        """Tag names as given; a bare owner name stands for all its tags."""
        out: list[MapTag] = []
        for name in names:
            out += [self.tag(name)] if "." in name else self.owned_by(name)
        return out

    def error_text(self, code: int) -> str:
        if code in self.errors:
            return self.errors[code]
        return "no error" if code == 0 else f"error {code} (not in the map's error table)"


def _nearest(name: str, names: Iterable[str]) -> str:
    """``"; did you mean 'X'?"`` for the name closest to ``name``, or nothing."""
    known = list(names)
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    if not close:  # a case slip: difflib's ratio does not fold case
        folded = {k.lower(): k for k in known}
        close = [folded[m] for m in difflib.get_close_matches(name.lower(), folded, n=1)]
    return f"; did you mean {close[0]!r}?" if close else ""
