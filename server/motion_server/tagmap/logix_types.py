"""The tag map as Logix data types and tags: what the EtherNet/IP front-end serves and
``motion-server map --format l5x`` exports.

Computed from the tag map alone (so from the same instruction catalog and site map as
the Modbus registers and the OPC UA model: the three can never disagree). Every owner of
the map (an instruction instance, an axis, a group, Clock, Diagnostics, a cam table, a
watchdog) is one controller-scope tag of a structured type (a UDT) whose members are the
owner's fields, named as on the other protocols (``MAG_1.DN``, ``Axis2.ActualPosition``).
Owners with the same fields share one type: ``MS_MAG`` for every MAG instance, ``MS_AXIS``
for the axes (an axis with other fields, a hand wheel with ``FeedbackInput``, gets
``MS_AXIS_2``), ``MS_GROUP``, ``MS_CLOCK``, ``MS_DIAGNOSTICS``, ``MS_CAM``, ``MS_WATCHDOG``.

Layout, as Logix lays out a UDT:

- a Logix instruction's ``FLAGS`` is the first member, a DINT (the MOTION_INSTRUCTION
  word: EN bit 31, DN 29, ER 28, PC 27, IP 26, AC 23); the BOOL members ``EN``, ``DN``,
  ``ER``, ``PC``, ``IP``, ``AC`` are aliases of those bits (no storage of their own), so
  ``MAG_1.DN`` is bit 29 of ``MAG_1.FLAGS`` by construction;
- other BOOLs (``Execute``, PLCopen ``Busy``/``Done``...) are bits of hidden SINT host
  members (``ZZZZZZZZZZMS_MAG0``), eight to a host, as Logix packs them;
- every other member is aligned to its size (LREAL to 8), the structure padded to its
  largest alignment (at least 4 bytes);
- fields ``Master[0]`` ... ``Master[n-1]`` (cam tables) are one array member ``Master``.

A BOOL member's bit is given within the byte at its offset (``EN``: offset 3, bit 7):
how pycomm3 and libplctag read a bit member (``raw[offset] & (1 << bit)``).

Types are the map's: BOOL, SINT, INT, DINT, UDINT (Logix 5580, firmware 32 and later),
REAL, LREAL; only ``FLAGS`` is served as the DINT Logix declares it (same bits).
"""

from __future__ import annotations

import re
import struct
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import IntEnum

from ..instructions.schema import TagType
from .model import Access, Folder, Tag, TagMap


class CipType(IntEnum):
    """CIP elementary data type codes (the Logix atomic types)."""

    BOOL = 0xC1
    SINT = 0xC2
    INT = 0xC3
    DINT = 0xC4
    UDINT = 0xC8
    REAL = 0xCA
    LREAL = 0xCB

    @property
    def size(self) -> int:
        return _SIZE[self]

    @property
    def fmt(self) -> str:
        """The :mod:`struct` format of one value (little endian)."""
        return _FMT[self]


_SIZE = {
    CipType.BOOL: 1,
    CipType.SINT: 1,
    CipType.INT: 2,
    CipType.DINT: 4,
    CipType.UDINT: 4,
    CipType.REAL: 4,
    CipType.LREAL: 8,
}
_FMT = {
    CipType.BOOL: "<B",
    CipType.SINT: "<b",
    CipType.INT: "<h",
    CipType.DINT: "<i",
    CipType.UDINT: "<I",
    CipType.REAL: "<f",
    CipType.LREAL: "<d",
}

#: the map's types as CIP types
CIP_OF = {
    TagType.BOOL: CipType.BOOL,
    TagType.SINT: CipType.SINT,
    TagType.INT: CipType.INT,
    TagType.DINT: CipType.DINT,
    TagType.UDINT: CipType.UDINT,
    TagType.REAL: CipType.REAL,
    TagType.LREAL: CipType.LREAL,
}

#: the MOTION_INSTRUCTION bits of FLAGS (Rockwell's MOTION_INSTRUCTION data type page)
FLAG_BITS = {"EN": 31, "DN": 29, "ER": 28, "PC": 27, "IP": 26, "AC": 23}
#: symbol type bit: the tag is a structure (its low 12 bits: the template instance)
STRUCT_BIT = 0x8000
#: template member type bit: a one-dimensional array
ARRAY_BIT = 0x2000
#: first template instance (user-defined types live in 0x100..0xEFF)
FIRST_TEMPLATE = 0x100
#: the name prefix of hidden BOOL host members (Logix's own convention)
HOST_PREFIX = "ZZZZZZZZZZ"

_ELEMENT = re.compile(r"^(\w+)\[(\d+)\]$")
_BASE_NAMES = {
    Folder.CLOCK: "MS_CLOCK",
    Folder.DIAGNOSTICS: "MS_DIAGNOSTICS",
    Folder.GROUPS: "MS_GROUP",
    Folder.AXES: "MS_AXIS",
    Folder.SAFETY: "MS_WATCHDOG",
    Folder.CAMS: "MS_CAM",
}


@dataclass(frozen=True)
class Member:
    """One member of a structure. ``offset``: byte offset; ``bit``: a BOOL's bit in the
    byte at ``offset``; ``length``: element count of an array member (0: scalar);
    ``fields``: the owner's fields it shows (one, or ``length`` for an array; none for a
    hidden host); ``writable``: a client may write it (the map says so)."""

    name: str
    type: CipType
    offset: int
    bit: int | None = None
    length: int = 0
    fields: tuple[str, ...] = ()
    hidden: bool = False
    writable: bool = False

    @property
    def size(self) -> int:
        """Bytes the member occupies (0 for a BOOL alias of a bit)."""
        if self.bit is not None:
            return 0
        return self.type.size * max(self.length, 1)

    @property
    def info(self) -> int:
        """The template's member info word: the bit of a BOOL, an array's length."""
        if self.bit is not None:
            return self.bit
        return self.length


@dataclass(frozen=True)
class Structure:
    """A UDT: its template instance, members and size in bytes."""

    name: str
    instance: int
    members: tuple[Member, ...]
    size: int
    _by_name: dict[str, Member] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        self._by_name.update({m.name.lower(): m for m in self.members})

    def member(self, name: str) -> Member | None:
        """The member named ``name`` (any case), or None."""
        return self._by_name.get(name.lower())

    @property
    def handle(self) -> int:
        """The structure handle (a CRC of the definition, as Logix's is one): clients
        send it with a whole-structure write."""
        return zlib.crc32(template_definition(self)) & 0xFFFF

    @property
    def symbol_type(self) -> int:
        return STRUCT_BIT | (self.instance & 0x0FFF)

    @property
    def writable(self) -> bool:
        return any(m.writable for m in self.members)


@dataclass(frozen=True)
class LogixTag:
    """A controller-scope tag: an owner of the map, typed by its structure."""

    name: str
    instance: int
    folder: Folder
    structure: Structure
    #: the map's tag of each field (``"DN"`` -> the ``MAG_1.DN`` Tag)
    tags: dict[str, Tag] = field(compare=False, repr=False)


class LogixMap:
    """Every owner as a Logix tag, and the structures they use."""

    def __init__(self, tags: list[LogixTag], structures: list[Structure]) -> None:
        self.tags = tags
        self.structures = structures
        self._by_name = {t.name.lower(): t for t in tags}
        self._by_instance = {t.instance: t for t in tags}
        self._templates = {s.instance: s for s in structures}

    def tag(self, name: str) -> LogixTag | None:
        return self._by_name.get(name.lower())

    def by_instance(self, instance: int) -> LogixTag | None:
        return self._by_instance.get(instance)

    def template(self, instance: int) -> Structure | None:
        return self._templates.get(instance)


def _align(offset: int, alignment: int) -> int:
    return (offset + alignment - 1) // alignment * alignment


def _layout(name: str, instance: int, tags: list[Tag]) -> Structure:
    """Lay out one owner's fields as a Logix UDT (see the module docstring)."""
    by_field = {t.field: t for t in tags}
    flags = by_field.get("FLAGS")
    members: list[Member] = []
    offset = 0
    biggest = 4
    if flags is not None:  # the MOTION_INSTRUCTION word first, its BOOLs aliases of it
        members.append(Member("FLAGS", CipType.DINT, 0, fields=("FLAGS",)))
        offset = 4
        for flag, bit in FLAG_BITS.items():
            if flag in by_field:
                members.append(Member(flag, CipType.BOOL, bit // 8, bit=bit % 8, fields=(flag,)))
    host: Member | None = None
    host_bits = 0
    hosts = 0
    arrays: dict[str, list[Tag]] = {}
    order: list[str | Tag] = []
    for t in tags:
        if flags is not None and (t.field == "FLAGS" or t.field in FLAG_BITS):
            continue
        m = _ELEMENT.match(t.field)
        if m:
            base = m.group(1)
            if base not in arrays:
                arrays[base] = []
                order.append(base)
            arrays[base].append(t)
        else:
            order.append(t)
    for item in order:
        if isinstance(item, str):  # an array member
            elements = sorted(arrays[item], key=lambda t: int(_ELEMENT.match(t.field)[2]))  # type: ignore[index]
            ctype = CIP_OF[elements[0].type]
            size = ctype.size
            offset = _align(offset, min(size, 8))
            biggest = max(biggest, min(size, 8))
            members.append(
                Member(
                    item,
                    ctype,
                    offset,
                    length=len(elements),
                    fields=tuple(t.field for t in elements),
                    writable=any(t.access == Access.READ_WRITE for t in elements),
                )
            )
            offset += size * len(elements)
            host = None
            continue
        t = item
        ctype = CIP_OF[t.type]
        writable = t.access == Access.READ_WRITE
        if ctype == CipType.BOOL:
            if host is None or host_bits == 8:
                host = Member(f"{HOST_PREFIX}{name}{hosts}", CipType.SINT, offset, hidden=True)
                hosts += 1
                host_bits = 0
                members.append(host)
                offset += 1
            members.append(
                Member(
                    t.field,
                    CipType.BOOL,
                    host.offset,
                    bit=host_bits,
                    fields=(t.field,),
                    writable=writable,
                )
            )
            host_bits += 1
            continue
        host = None
        size = ctype.size
        offset = _align(offset, min(size, 8))
        biggest = max(biggest, min(size, 8))
        members.append(Member(t.field, ctype, offset, fields=(t.field,), writable=writable))
        offset += size
    return Structure(name, instance, tuple(members), _align(max(offset, 1), biggest))


def _signature(tags: Iterable[Tag]) -> tuple[tuple[str, TagType, bool], ...]:
    return tuple((t.field, t.type, t.access == Access.READ_WRITE) for t in tags)


def build_logix_map(tagmap: TagMap) -> LogixMap:
    """The Logix tags and types of ``tagmap``: owners in the map's order, symbol instances
    from 1, template instances from :data:`FIRST_TEMPLATE`."""
    owners: dict[str, list[Tag]] = {}
    for t in tagmap:
        owners.setdefault(t.owner, []).append(t)
    shapes: dict[tuple[object, ...], Structure] = {}
    names: set[str] = set()
    structures: list[Structure] = []
    tags: list[LogixTag] = []
    for owner, fields in owners.items():
        first = fields[0]
        sig = (first.folder, first.instruction, _signature(fields))
        structure = shapes.get(sig)
        if structure is None:
            base = (
                f"MS_{first.instruction}"
                if first.folder == Folder.INSTRUCTIONS
                else _BASE_NAMES.get(first.folder, f"MS_{first.folder.value.upper()}")
            )
            name, n = base, 1
            while name in names:
                n += 1
                name = f"{base}_{n}"
            names.add(name)
            structure = _layout(name, FIRST_TEMPLATE + len(structures), fields)
            shapes[sig] = structure
            structures.append(structure)
        tags.append(
            LogixTag(owner, len(tags) + 1, first.folder, structure, {t.field: t for t in fields})
        )
    return LogixMap(tags, structures)


def template_definition(structure: Structure) -> bytes:
    """The Template object's definition (what Template Read returns): per member its info
    word, type and offset, then ``NAME;n`` with two access bytes per member, then the
    member names, each NUL-terminated, padded to a multiple of 4 bytes.

    The access bytes (after ``;n``, as Logix 5580 sends them): 0x01 then 0x03 for a
    read/write member, 0x01 for read only, 0x04 (no access) for a hidden host; none is 0 or
    ``;``, so a client that splits the names on NUL is not misled."""
    out = bytearray()
    for m in structure.members:
        ctype = int(m.type) | (ARRAY_BIT if m.length else 0)
        out += struct.pack("<HHI", m.info, ctype, m.offset)
    access = b"".join(
        bytes((0x01, 0x04 if m.hidden else 0x03 if m.writable else 0x01)) for m in structure.members
    )
    out += structure.name.encode("ascii") + b";n" + access + b"\x00"
    for m in structure.members:
        out += m.name.encode("ascii") + b"\x00"
    while len(out) % 4:
        out += b"\x00"
    return bytes(out)
