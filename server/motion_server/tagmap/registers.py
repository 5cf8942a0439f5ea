"""Every holding register of a map from one array of tag values, at once (numpy).

The same encoding as :mod:`.codec` (a test compares them register by register): integers
in two's complement, REAL as binary32 (beyond its range: infinity), LREAL as binary64,
words in the map's word order, BOOLs as bits of their register. A front-end encodes a
snapshot once and serves every read of that cycle from the result.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Sequence

import numpy as np

from ..instructions.schema import TagType
from .codec import Decoder, RegisterValueError, Value, decoder
from .errors import BadValueError
from .model import Tag, WordOrder

_WIDE = {
    TagType.DINT: (np.int64, 0xFFFFFFFF, ">u4"),
    TagType.UDINT: (np.int64, 0xFFFFFFFF, ">u4"),
    TagType.REAL: (None, 0, ">f4"),
    TagType.LREAL: (None, 0, ">f8"),
}


class RegisterEncoder:
    """Encodes ``values`` (one float64 per tag, in the order of ``tags``) into registers
    ``0 .. size - 1`` (at least up to the last tag; registers no tag uses read 0)."""

    def __init__(self, tags: Sequence[Tag], order: WordOrder, size: int = 0) -> None:
        self.size = max(size, max((t.end for t in tags), default=0))
        little = order == WordOrder.LITTLE
        self._groups: list[tuple[TagType, np.ndarray, np.ndarray]] = []
        by_type: dict[TagType, list[int]] = {}
        for i, t in enumerate(tags):
            by_type.setdefault(t.type, []).append(i)
        for tag_type, idx in by_type.items():
            if tag_type == TagType.BOOL:
                continue
            n = tag_type.words
            words = np.arange(n)[::-1] if little and n > 1 else np.arange(n)
            addr = np.array([tags[i].address for i in idx], dtype=np.intp)[:, None] + words
            self._groups.append((tag_type, np.array(idx, dtype=np.intp), addr))
        bools = by_type.get(TagType.BOOL, [])
        self._bool_idx = np.array(bools, dtype=np.intp)
        regs = np.array([tags[i].address for i in bools], dtype=np.intp)
        self._bool_regs, self._bool_inv = np.unique(regs, return_inverse=True)
        self._bool_weight = np.array([1 << (tags[i].bit or 0) for i in bools], dtype=np.float64)

    def encode(self, values: np.ndarray) -> np.ndarray:
        """The registers (uint16) of ``values``."""
        regs = np.zeros(self.size, dtype=np.uint16)
        for tag_type, idx, addr in self._groups:
            v = values[idx]
            if tag_type in _WIDE:
                ints, mask, fmt = _WIDE[tag_type]
                if ints is not None:
                    raw = (v.astype(np.int64) & mask).astype(fmt)
                else:
                    with np.errstate(over="ignore", invalid="ignore"):
                        raw = v.astype(fmt)
                words = raw.view(">u2").reshape(len(idx), -1)
            else:  # SINT, INT: one register, two's complement
                words = (v.astype(np.int64) & 0xFFFF).astype(np.uint16).reshape(-1, 1)
            regs[addr] = words
        if self._bool_idx.size:
            on = (values[self._bool_idx] != 0.0) * self._bool_weight
            packed = np.bincount(self._bool_inv, weights=on, minlength=self._bool_regs.size)
            regs[self._bool_regs] = packed.astype(np.uint16)
        return regs


class RegisterWrites:
    """Registers written by a client -> the tag values they set.

    A write that covers part of a 32/64-bit value changes those words only (the other
    words keep their current value: operands are latched on the trigger's edge, so a
    client may write the two halves separately); registers between tags take no value;
    a register of BOOLs sets every BOOL in it.
    """

    def __init__(self, tags: Sequence[Tag], order: WordOrder) -> None:
        self._slots: list[tuple[int, int, list[Tag]]] = []
        self._decoders: dict[str, Decoder] = {}
        bits: dict[int, list[Tag]] = {}
        for tag in tags:
            if tag.type == TagType.BOOL:
                bits.setdefault(tag.address, []).append(tag)
                continue
            self._decoders[tag.name] = decoder(tag.type, order)
            self._slots.append((tag.address, tag.count, [tag]))
        self._slots += [(address, 1, group) for address, group in bits.items()]
        self._slots.sort(key=lambda s: s[0])
        self._starts = [s[0] for s in self._slots]

    def updates(
        self,
        address: int,
        values: Sequence[int],
        current: Callable[[int, int], Sequence[int]],
    ) -> list[tuple[Tag, Value]]:
        """The (tag, value) pairs of a write of ``values`` at ``address``; ``current(a,
        n)`` gives the registers as they are now. :class:`BadValueError` when registers
        hold no value of their tag's type."""
        out: list[tuple[Tag, Value]] = []
        end = address + len(values)
        slots = self._slots
        i = max(bisect.bisect_right(self._starts, address) - 1, 0)
        while i < len(slots) and slots[i][0] < end:
            start, count, tags = slots[i]
            i += 1
            if start + count <= address:
                continue
            if tags[0].type == TagType.BOOL:
                reg = values[start - address]
                out += [(t, bool((reg >> (t.bit or 0)) & 1)) for t in tags]
                continue
            words = list(current(start, count))
            for k in range(count):
                if address <= start + k < end:
                    words[k] = values[start + k - address]
            tag = tags[0]
            try:
                out.append((tag, self._decoders[tag.name](words)))
            except RegisterValueError as exc:
                raise BadValueError(f"{tag.name}: {exc}") from None
        return out
