"""Values <-> 16-bit holding registers, in either word order.

Integers are two's complement (SINT takes a whole register, sign-extended), REAL is IEEE
754 binary32, LREAL binary64. ``big`` puts the most significant word first (ABCD);
``little`` the least significant first (CDAB); bytes inside a word are always big-endian,
as Modbus sends them.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence

from ..instructions.schema import TagType
from .model import WordOrder

Value = bool | int | float

_FORMAT = {
    TagType.BOOL: "H",
    TagType.SINT: "h",
    TagType.INT: "h",
    TagType.DINT: "i",
    TagType.UDINT: "I",
    TagType.REAL: "f",
    TagType.LREAL: "d",
}
_BITS = {TagType.SINT: 16, TagType.INT: 16, TagType.DINT: 32, TagType.UDINT: 32}
_FLOAT32_MAX = 3.4028234663852886e38


class RegisterValueError(ValueError):
    """Registers that hold no value of the tag's type (a SINT beyond -128..127)."""


Encoder = Callable[[Value], tuple[int, ...]]
Decoder = Callable[[Sequence[int]], Value]


def encoder(tag_type: TagType, order: WordOrder) -> Encoder:
    """A function value -> registers for one type and word order (BOOLs: 0 or 1)."""
    words = tag_type.words
    value_struct = struct.Struct(">" + _FORMAT[tag_type])
    word_struct = struct.Struct(f">{words}H")
    swap = order == WordOrder.LITTLE and words > 1
    if tag_type.is_float:
        is_real = tag_type == TagType.REAL

        def encode_float(value: Value) -> tuple[int, ...]:
            v = float(value)
            if is_real and abs(v) > _FLOAT32_MAX and math.isfinite(v):
                v = math.copysign(math.inf, v)
            regs: tuple[int, ...] = word_struct.unpack(value_struct.pack(v))
            return regs[::-1] if swap else regs

        return encode_float
    mask = (1 << _BITS.get(tag_type, 16)) - 1
    unsigned = struct.Struct(">" + ("I" if words == 2 else "H"))

    def encode_int(value: Value) -> tuple[int, ...]:
        regs: tuple[int, ...] = word_struct.unpack(unsigned.pack(int(value) & mask))
        return regs[::-1] if swap else regs

    return encode_int


def decoder(tag_type: TagType, order: WordOrder) -> Decoder:
    """A function registers -> value; raises :class:`RegisterValueError` for a SINT out of range."""
    words = tag_type.words
    value_struct = struct.Struct(">" + _FORMAT[tag_type])
    word_struct = struct.Struct(f">{words}H")
    swap = order == WordOrder.LITTLE and words > 1

    def decode(regs: Sequence[int]) -> Value:
        seq = tuple(regs[::-1]) if swap else tuple(regs)
        value: Value = value_struct.unpack(word_struct.pack(*seq))[0]
        if tag_type == TagType.SINT and not -128 <= int(value) <= 127:
            raise RegisterValueError(f"{value} is not a SINT (-128..127)")
        if tag_type == TagType.BOOL:
            return bool(value)
        return value

    return decode


def encode(tag_type: TagType, value: Value, order: WordOrder = WordOrder.BIG) -> list[int]:
    """Registers of one value (convenience for clients and tests)."""
    return list(encoder(tag_type, order)(value))


def decode(tag_type: TagType, regs: Sequence[int], order: WordOrder = WordOrder.BIG) -> Value:
    """The value in ``regs`` (exactly ``tag_type.words`` registers)."""
    return decoder(tag_type, order)(regs)
