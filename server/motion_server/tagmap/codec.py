"""Values <-> 16-bit holding registers, in either word order, for the server's tags.

The encoding itself is :mod:`motion_clients.codec`, the project's one register codec
(shared with the clients and the container's health check; it imports nothing but the
standard library, so the scan process stays free of protocol code). This module gives it
the server's types (:class:`~motion_server.instructions.schema.TagType`,
:class:`~.model.WordOrder`) and the server's own check on decoding: registers that hold
no value of the tag's type (a SINT beyond -128..127) raise :class:`RegisterValueError`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from motion_clients import codec as shared

from ..instructions.schema import TagType
from .model import WordOrder

Value = bool | int | float


class RegisterValueError(ValueError):
    """Registers that hold no value of the tag's type (a SINT beyond -128..127)."""


Encoder = Callable[[Value], tuple[int, ...]]
Decoder = Callable[[Sequence[int]], Value]


def encoder(tag_type: TagType, order: WordOrder) -> Encoder:
    """A function value -> registers for one type and word order (BOOLs: 0 or 1)."""
    return shared.encoder(tag_type.value, order.value)


def decoder(tag_type: TagType, order: WordOrder) -> Decoder:
    """A function registers -> value; raises :class:`RegisterValueError` for a SINT out of range."""
    decode_value = shared.decoder(tag_type.value, order.value)
    if tag_type != TagType.SINT:
        return decode_value

    def decode_sint(regs: Sequence[int]) -> Value:
        value = decode_value(regs)
        if not -128 <= int(value) <= 127:
            raise RegisterValueError(f"{value} is not a SINT (-128..127)")
        return value

    return decode_sint


def encode(tag_type: TagType, value: Value, order: WordOrder = WordOrder.BIG) -> list[int]:
    """Registers of one value (convenience for clients and tests)."""
    return list(encoder(tag_type, order)(value))


def decode(tag_type: TagType, regs: Sequence[int], order: WordOrder = WordOrder.BIG) -> Value:
    """The value in ``regs`` (exactly ``tag_type.words`` registers)."""
    return decoder(tag_type, order)(regs)
