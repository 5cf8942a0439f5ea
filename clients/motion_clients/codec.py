"""Tag values <-> 16-bit holding registers: the one register codec of the project.

The server (``motion_server.tagmap.codec``), the clients (:mod:`.tagmap`) and the
container's health check (``container/heartbeat.py``) all encode and decode through this
module. It lives on the clients' side because clients may import nothing of the server
but its map export, while the server may import this; it imports nothing but the
standard library, because the scan process, which imports it through the server's tag
map, must not load protocol code (pymodbus, asyncua).

The encoding is the one the map export documents (``modbus.word_order``), and the one
pymodbus' ``convert_to_registers`` / ``convert_from_registers`` produce for the same
types (a test compares them, value by value): integers in two's complement (a SINT fills
its register, sign-extended), REAL as IEEE 754 binary32, LREAL as binary64; bytes in a
register big-endian, as Modbus sends them; ``big`` puts the most significant word first
(ABCD), ``little`` the least significant (CDAB). Where pymodbus raises, this codec
defines a value instead, so that a server can always publish what it holds: a finite
number beyond the REAL range is encoded as infinity of its sign, an integer beyond its
type's range wraps to its low bits (callers judge ranges before they encode). A BOOL is
encoded as 0 or 1 in a whole register; the bit a BOOL occupies in a shared register is
the caller's business (the map export's ``modbus.bit``).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence

Value = bool | int | float
Encoder = Callable[[Value], tuple[int, ...]]
Decoder = Callable[[Sequence[int]], Value]

#: registers per value of each type (``UINT`` only in older maps' health checks)
WORDS = {
    "BOOL": 1,
    "SINT": 1,
    "INT": 1,
    "UINT": 1,
    "DINT": 2,
    "UDINT": 2,
    "REAL": 2,
    "LREAL": 4,
}
#: struct code of each type's value
_FORMAT = {
    "BOOL": "H",
    "SINT": "h",
    "INT": "h",
    "UINT": "H",
    "DINT": "i",
    "UDINT": "I",
    "REAL": "f",
    "LREAL": "d",
}
_FLOATS = frozenset({"REAL", "LREAL"})
FLOAT32_MAX = 3.4028234663852886e38


def _order(word_order: str) -> bool:
    """True for CDAB (``little``); ValueError for a word order that is neither."""
    if word_order not in ("big", "little"):
        raise ValueError(f"word order {word_order!r}: expected 'big' or 'little'")
    return word_order == "little"


def encoder(type_name: str, word_order: str = "big") -> Encoder:
    """A function value -> registers for one type and word order (compiled once)."""
    words = WORDS[type_name]
    swap = _order(word_order) and words > 1
    as_words = struct.Struct(f">{words}H")
    if type_name in _FLOATS:
        value_struct = struct.Struct(">" + _FORMAT[type_name])
        is_real = type_name == "REAL"

        def encode_float(value: Value) -> tuple[int, ...]:
            v = float(value)
            if is_real and abs(v) > FLOAT32_MAX and math.isfinite(v):
                v = math.copysign(math.inf, v)
            regs: tuple[int, ...] = as_words.unpack(value_struct.pack(v))
            return regs[::-1] if swap else regs

        return encode_float
    mask = (1 << (16 * words)) - 1
    unsigned = struct.Struct(">I" if words == 2 else ">H")

    def encode_int(value: Value) -> tuple[int, ...]:
        regs: tuple[int, ...] = as_words.unpack(unsigned.pack(int(value) & mask))
        return regs[::-1] if swap else regs

    return encode_int


def decoder(type_name: str, word_order: str = "big") -> Decoder:
    """A function registers -> value for one type and word order (compiled once): the
    first ``WORDS[type_name]`` registers; a BOOL is its register's value as a bool."""
    words = WORDS[type_name]
    swap = _order(word_order) and words > 1
    as_words = struct.Struct(f">{words}H")
    value_struct = struct.Struct(">" + _FORMAT[type_name])
    is_bool = type_name == "BOOL"

    def decode(regs: Sequence[int]) -> Value:
        seq = tuple(regs[:words])
        value: Value = value_struct.unpack(as_words.pack(*(seq[::-1] if swap else seq)))[0]
        return bool(value) if is_bool else value

    return decode


def encode(type_name: str, value: Value, word_order: str = "big") -> list[int]:
    """The registers of one value."""
    return list(encoder(type_name, word_order)(value))


def decode(type_name: str, registers: Sequence[int], word_order: str = "big") -> Value:
    """The value in ``registers`` (its first ``WORDS[type_name]``)."""
    return decoder(type_name, word_order)(registers)
