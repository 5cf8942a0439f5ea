"""Bit layouts of the packed words: which bit of which register means what.

Two kinds of packed words:

- the status words whose bits the documents define: an instruction's ``FLAGS`` (the Logix
  MOTION_INSTRUCTION word: EN 31, DN 29, ER 28, PC 27, IP 26, AC 23), an axis's
  ``MotionStatus`` (Logix MotionStatus bits) and ``AxisFault``;
- the BOOL registers of the map: each block's status bits (EN, DN, ER, ... or Busy, Done,
  Error, ...) and command bits (the trigger ``Execute`` is bit 0), one BOOL tag per bit.

:func:`packed_words` lists both for a tag map, in address order; every export shows them.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..instructions.schema import TagType
from ..instructions.status import LogixBit
from ..kernel import MotionStatusBit
from .model import Access, Tag, TagMap

#: AxisFault bits (kernel ``AxisFault``; bit 2 is set by the communication watchdog, bits
#: 4-9 by injected faults: ``kernel/faults.py``)
AXIS_FAULT_BITS: dict[int, str] = {
    0: "PositionError",
    1: "Profile",
    2: "CommunicationWatchdog",
    3: "Numeric",
    4: "DriveFault",
    5: "FeedbackFault",
    6: "PosHardOvertravel",
    7: "NegHardOvertravel",
    8: "PosSoftOvertravel",
    9: "NegSoftOvertravel",
}

#: the Logix ServoFaultBits attribute (Rockwell MOTION-RM002)
SERVO_FAULT_BITS: dict[int, str] = {
    0: "PosSoftOvertravelFault",
    1: "NegSoftOvertravelFault",
    2: "PosHardOvertravelFault",
    3: "NegHardOvertravelFault",
    4: "FeedbackFault",
    8: "PositionErrorFault",
    9: "DriveFault",
}


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


#: the bit layout of a packed status word, by field name
WORD_BITS: dict[str, dict[int, str]] = {
    "FLAGS": {int(b): b.name for b in sorted(LogixBit, key=int)},
    "MotionStatus": {int(b): _camel(b.name) for b in sorted(MotionStatusBit, key=int)},
    "AxisFault": AXIS_FAULT_BITS,
    "ServoFault": SERVO_FAULT_BITS,
}


@dataclass(frozen=True)
class PackedWord:
    """One packed word: ``tag`` set for a status word (FLAGS ...), None for a register of
    BOOL tags; ``bits`` maps bit number -> name (the BOOL's field name for a register)."""

    owner: str
    address: int
    count: int
    access: Access
    bits: dict[int, str]
    tag: Tag | None = None

    @property
    def kind(self) -> str:
        if self.tag is not None:
            return self.tag.field
        return "command bits" if self.access == Access.READ_WRITE else "status bits"


def word_bits(tag: Tag) -> dict[int, str] | None:
    """The bit layout of a packed status word, None for other tags."""
    if tag.type not in (TagType.UDINT, TagType.DINT):
        return None
    return WORD_BITS.get(tag.field)


def packed_words(tagmap: TagMap) -> list[PackedWord]:
    """Every packed word of the map, in address order."""
    out: list[PackedWord] = []
    registers: dict[int, list[Tag]] = {}
    for tag in tagmap:
        if tag.type == TagType.BOOL:
            registers.setdefault(tag.address, []).append(tag)
            continue
        bits = word_bits(tag)
        if bits is not None:
            out.append(PackedWord(tag.owner, tag.address, tag.count, tag.access, bits, tag))
    for address, tags in registers.items():
        bits = {t.bit or 0: t.field for t in sorted(tags, key=lambda t: t.bit or 0)}
        out.append(PackedWord(tags[0].owner, address, 1, tags[0].access, bits))
    return sorted(out, key=lambda w: w.address)


def bits_text(bits: dict[int, str]) -> str:
    """``0=EN; 1=DN; ...``"""
    return "; ".join(f"{n}={name}" for n, name in sorted(bits.items()))
