"""The static tag map: tags, register blocks and the look-ups front-ends and exports use.

A :class:`TagMap` is computed once from a site map (see :mod:`.layout`) and never changes
while the server runs; live values come from a :class:`~.image.TagImage` bound to it.
"""

from __future__ import annotations

import bisect
import builtins
from collections.abc import Iterator
from dataclasses import dataclass, field
from enum import IntEnum, StrEnum
from typing import Any

from ..instructions.schema import Quantity, TagType

#: the JSON export's contract name (bump the number on an incompatible change)
MAP_FORMAT = "motion-server-map/1"
#: the highest holding register address (0-based)
MAX_ADDRESS = 65535


class Access(StrEnum):
    READ = "read"
    READ_WRITE = "read_write"


class Folder(StrEnum):
    """The OPC UA folder a tag lives in (the first part of its node id)."""

    CLOCK = "Clock"
    DIAGNOSTICS = "Diagnostics"
    GROUPS = "Groups"
    AXES = "Axes"
    INSTRUCTIONS = "Instructions"
    SAFETY = "Safety"
    #: cam tables (``[[cams]]``): the Logix CAM arrays and their CAM_PROFILE Status
    CAMS = "Cams"


class RegisterAccess(IntEnum):
    """What a client may do with one holding register."""

    NONE = 0  # outside the map: exception 02
    READ = 1
    READ_WRITE = 2


class WordOrder(StrEnum):
    """Order of the 16-bit words of a 32/64-bit value: ``big`` = most significant word
    first (ABCD), ``little`` = least significant word first (CDAB)."""

    BIG = "big"
    LITTLE = "little"


class TagMapError(ValueError):
    """The site map cannot be laid out: ``problems`` are (location, message) pairs whose
    location is a site-map field path such as ``("instructions", "instances", 3,
    "modbus_base")``."""

    def __init__(self, problems: list[tuple[tuple[int | str, ...], str]]) -> None:
        self.problems = problems
        super().__init__("; ".join(f"{'.'.join(map(str, loc))}: {msg}" for loc, msg in problems))


class UnknownTagError(KeyError):
    """No tag of that name (or node id) in the map."""


@dataclass(frozen=True)
class Tag:
    """One value a client can reach: ``owner.field`` (``MAJ_1.Speed``, ``Axis2.ActualPosition``).

    ``address``/``count`` are the 0-based holding registers; a BOOL is bit ``bit`` (0 = least
    significant) of the register at ``address``. ``node_id`` is the OPC UA string NodeId
    (``Instructions.MAJ_1.Speed``), ``units`` the engineering units of analog values,
    ``enum`` the enumeration the value follows (if any), ``minimum``/``maximum`` the range
    an operand is judged against at execution (``exclusive_minimum``: it must be greater
    than ``minimum``), ``eu_range`` the span an analog value takes
    in normal operation (OPC UA EURange, from the axis limits: :mod:`.units`).
    """

    name: str
    owner: str
    field: str
    folder: Folder
    type: TagType
    access: Access
    address: int
    count: int
    bit: int | None
    node_id: str
    units: str = ""
    quantity: Quantity = Quantity.NONE
    enum: builtins.type[IntEnum] | None = None
    description: str = ""
    minimum: float | None = None
    maximum: float | None = None
    #: instruction type of the owner (instruction tags only)
    instruction: str = ""
    eu_range: tuple[float, float] | None = None
    #: the value must be greater than ``minimum`` (not equal to it)
    exclusive_minimum: bool = False

    @property
    def writable(self) -> bool:
        return self.access == Access.READ_WRITE

    @property
    def end(self) -> int:
        """One past the last register of the tag."""
        return self.address + self.count

    def enum_members(self) -> dict[str, int]:
        return {m.name: int(m.value) for m in self.enum} if self.enum is not None else {}


@dataclass(frozen=True)
class Block:
    """The registers of one owner (an instance, an axis, a group, Clock, Diagnostics).

    ``[base, end)`` is all valid (unused registers read 0); ``[command_start,
    command_end)`` is the writable region (empty when the owner has no writable tags).
    ``part`` names a second block of the same owner (an axis's ``configuration``).
    """

    owner: str
    folder: Folder
    base: int
    end: int
    command_start: int
    command_end: int
    instruction: str = ""
    part: str = ""

    @property
    def size(self) -> int:
        return self.end - self.base


@dataclass
class TagMap:
    """The ordered tags of a site (by address, then bit) and their register blocks."""

    site: str
    namespace_uri: str
    unit_id: int
    word_order: WordOrder
    tags: tuple[Tag, ...]
    blocks: tuple[Block, ...]
    #: the site map it was computed from (exports read initial values from it)
    source: Any = field(default=None, repr=False, compare=False)
    _by_name: dict[str, Tag] = field(init=False, repr=False)
    _by_node: dict[str, Tag] = field(init=False, repr=False)
    _starts: list[int] = field(init=False, repr=False)
    _by_entry: dict[str, list[Tag]] | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        self.tags = tuple(sorted(self.tags, key=lambda t: (t.address, t.bit or 0)))
        self.blocks = tuple(sorted(self.blocks, key=lambda b: b.base))
        self._by_name = {t.name: t for t in self.tags}
        self._by_node = {t.node_id: t for t in self.tags}
        self._starts = [b.base for b in self.blocks]

    # -- look-ups -------------------------------------------------------------------------
    def __iter__(self) -> Iterator[Tag]:
        return iter(self.tags)

    def __len__(self) -> int:
        return len(self.tags)

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def tag(self, name: str) -> Tag:
        """The tag called ``name`` (``MAJ_1.Speed``)."""
        try:
            return self._by_name[name]
        except KeyError:
            raise UnknownTagError(f"no tag {name!r} in the map of site {self.site}") from None

    def by_node_id(self, node_id: str) -> Tag:
        try:
            return self._by_node[node_id]
        except KeyError:
            raise UnknownTagError(f"no node {node_id!r} in the map of site {self.site}") from None

    def block_at(self, address: int) -> Block | None:
        i = bisect.bisect_right(self._starts, address) - 1
        if i >= 0 and address < self.blocks[i].end:
            return self.blocks[i]
        return None

    def block(self, owner: str) -> Block:
        """The main block of ``owner`` (not a second ``part`` such as an axis's
        configuration block: :meth:`blocks_of` lists those too)."""
        for b in self.blocks:
            if b.owner == owner and not b.part:
                return b
        raise UnknownTagError(f"no block {owner!r} in the map of site {self.site}")

    def blocks_of(self, owner: str) -> list[Block]:
        return [b for b in self.blocks if b.owner == owner]

    def at(self, address: int) -> list[Tag]:
        """The tags that occupy register ``address`` (several BOOLs share one)."""
        return [t for t in self.tags if t.address <= address < t.end]

    def access(self, address: int) -> RegisterAccess:
        b = self.block_at(address)
        if b is None:
            return RegisterAccess.NONE
        if b.command_start <= address < b.command_end:
            return RegisterAccess.READ_WRITE
        return RegisterAccess.READ

    def owned_by(self, owner: str) -> list[Tag]:
        return [t for t in self.tags if t.owner == owner]

    def in_folder(self, folder: Folder) -> list[Tag]:
        return [t for t in self.tags if t.folder == folder]

    def named(self, entry: str) -> list[Tag]:
        """The tags an entry of an access rule names: a folder (``Instructions``), an
        owner (``MAJ_1``) or a tag (``MAJ_1.Speed``), in map order; empty: it names none."""
        if self._by_entry is None:
            by_entry: dict[str, list[Tag]] = {}
            for t in self.tags:
                for key in {t.folder.value, t.owner, t.name}:
                    by_entry.setdefault(key, []).append(t)
            self._by_entry = by_entry
        return list(self._by_entry.get(entry, ()))

    def owners(self, folder: Folder) -> list[str]:
        """Owners of a folder in block order (instances, axes ...), each once: an owner
        with more than one block (an axis and its fault-injection words) is named where
        its first block is."""
        return list(dict.fromkeys(b.owner for b in self.blocks if b.folder == folder))
