"""Modbus TCP frames without I/O: the MBAP header, request PDUs with the checks of the
Modbus Application Protocol Specification V1.1b3, and the answers.

An ADU is the 7-byte MBAP header (transaction id, protocol id 0, length, unit id) and a
PDU (function code and data); ``length`` counts the unit id and the PDU, so it lies in
2..254 (an ADU is at most 260 bytes). :func:`header` judges a header from its first 6
bytes: a protocol id other than 0 or a length outside 2..254 is :class:`HeaderError`,
after which nothing on that connection can be delimited any more (the connection closes).

:func:`decode` turns a PDU of a served function code into a :class:`Request`, or raises
:class:`PduError` with the exception code the specification gives:

- 01 any function code but 3, 6, 16, 22 and 23 (0 and 128..255 included);
- 03 a PDU whose length does not fit its function code, FC3 read count outside 1..125,
  FC16 count outside 1..123 or a byte count other than 2 x count, FC23 read count outside
  1..125, write count outside 1..121 or a byte count other than 2 x write count.

Address checks (02) and the processing itself (03, 04) belong to whoever serves the
request. :func:`read_answer`, :func:`write_answer` and :func:`exception_answer` build the
answer PDUs, :func:`adu` wraps one in its header.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

#: transaction id, protocol id, length, unit id
MBAP = struct.Struct(">HHHB")
#: the first 6 bytes of the header: enough to judge it
MBAP_FIXED = struct.Struct(">HHH")
HEADER_SIZE = 7
#: the MBAP length: unit id + function code at least, 260-byte ADUs at most
MIN_LENGTH = 2
MAX_LENGTH = 254
#: registers one request may read (FC3, FC23) or write (FC16, FC23)
MAX_READ = 125
MAX_WRITE = 123
MAX_READ_WRITE = 121

_U16 = struct.Struct(">H")
_U16X2 = struct.Struct(">HH")
_U16X3 = struct.Struct(">HHH")
_U16X4 = struct.Struct(">HHHH")


class FunctionCode(IntEnum):
    """The function codes served (every other one answers exception 01)."""

    READ_HOLDING_REGISTERS = 3
    WRITE_SINGLE_REGISTER = 6
    WRITE_MULTIPLE_REGISTERS = 16
    MASK_WRITE_REGISTER = 22
    READ_WRITE_MULTIPLE_REGISTERS = 23


class ExceptionCode(IntEnum):
    ILLEGAL_FUNCTION = 0x01
    ILLEGAL_DATA_ADDRESS = 0x02
    ILLEGAL_DATA_VALUE = 0x03
    SERVER_DEVICE_FAILURE = 0x04
    GATEWAY_TARGET_FAILED_TO_RESPOND = 0x0B


SERVED_FUNCTION_CODES = frozenset(int(fc) for fc in FunctionCode)
#: function codes that write (coils, registers, file records): audited when refused
WRITE_FUNCTION_CODES = frozenset({5, 6, 15, 16, 21, 22, 23})


class HeaderError(ValueError):
    """An MBAP header that delimits no frame (the connection must close)."""


class PduError(ValueError):
    """A request refused before it touches the image: ``code`` to answer, and the
    registers it would have written (``address``, ``count``) when the PDU says so."""

    def __init__(self, code: ExceptionCode, why: str, writes: tuple[int, int] | None = None):
        super().__init__(why)
        self.code = code
        self.writes = writes


@dataclass(frozen=True, slots=True)
class Request:
    """One decoded request. ``read``/``write``: (first register, count) or None;
    ``values``: the registers written; ``masks``: FC22's (and, or)."""

    function: FunctionCode
    read: tuple[int, int] | None = None
    write: tuple[int, int] | None = None
    values: tuple[int, ...] = ()
    masks: tuple[int, int] = (0xFFFF, 0)


def header(buf: bytes | bytearray, pos: int = 0) -> tuple[int, int]:
    """(transaction id, length) of the header at ``pos`` (6 bytes at least there)."""
    tid, protocol, length = MBAP_FIXED.unpack_from(buf, pos)
    if protocol != 0:
        raise HeaderError(f"protocol id {protocol} (Modbus is 0)")
    if not MIN_LENGTH <= length <= MAX_LENGTH:
        raise HeaderError(f"length {length} (outside {MIN_LENGTH}..{MAX_LENGTH})")
    return tid, length


def _malformed(fc: int, why: str, writes: tuple[int, int] | None = None) -> PduError:
    return PduError(ExceptionCode.ILLEGAL_DATA_VALUE, f"FC{fc}: {why}", writes)


def decode(pdu: bytes) -> Request:
    """The request in ``pdu`` (function code first), or :class:`PduError`."""
    fc = pdu[0]
    n = len(pdu)
    if fc == FunctionCode.READ_HOLDING_REGISTERS:
        if n != 5:
            raise _malformed(fc, f"{n} bytes (5 expected)")
        address, count = _U16X2.unpack_from(pdu, 1)
        if not 1 <= count <= MAX_READ:
            raise _malformed(fc, f"read count {count} (1..{MAX_READ})")
        return Request(FunctionCode.READ_HOLDING_REGISTERS, read=(address, count))
    if fc == FunctionCode.WRITE_SINGLE_REGISTER:
        writes = (_U16.unpack_from(pdu, 1)[0], 1) if n >= 3 else None
        if n != 5:
            raise _malformed(fc, f"{n} bytes (5 expected)", writes)
        address, value = _U16X2.unpack_from(pdu, 1)
        return Request(FunctionCode.WRITE_SINGLE_REGISTER, write=(address, 1), values=(value,))
    if fc == FunctionCode.WRITE_MULTIPLE_REGISTERS:
        writes = _U16X2.unpack_from(pdu, 1) if n >= 5 else None
        if n < 6:
            raise _malformed(fc, f"{n} bytes (6 at least)", writes)
        address, count = _U16X2.unpack_from(pdu, 1)
        size = pdu[5]
        if not 1 <= count <= MAX_WRITE:
            raise _malformed(fc, f"write count {count} (1..{MAX_WRITE})", writes)
        if size != 2 * count or n != 6 + size:
            why = f"byte count {size}, {n - 6} data bytes, {count} registers"
            raise _malformed(fc, why, writes)
        values = struct.unpack_from(f">{count}H", pdu, 6)
        return Request(FunctionCode.WRITE_MULTIPLE_REGISTERS, write=(address, count), values=values)
    if fc == FunctionCode.MASK_WRITE_REGISTER:
        writes = (_U16.unpack_from(pdu, 1)[0], 1) if n >= 3 else None
        if n != 7:
            raise _malformed(fc, f"{n} bytes (7 expected)", writes)
        address, and_mask, or_mask = _U16X3.unpack_from(pdu, 1)
        return Request(
            FunctionCode.MASK_WRITE_REGISTER, write=(address, 1), masks=(and_mask, or_mask)
        )
    if fc == FunctionCode.READ_WRITE_MULTIPLE_REGISTERS:
        writes = _U16X2.unpack_from(pdu, 5) if n >= 9 else None
        if n < 10:
            raise _malformed(fc, f"{n} bytes (10 at least)", writes)
        read_address, read_count, address, count = _U16X4.unpack_from(pdu, 1)
        size = pdu[9]
        if not 1 <= read_count <= MAX_READ:
            raise _malformed(fc, f"read count {read_count} (1..{MAX_READ})", writes)
        if not 1 <= count <= MAX_READ_WRITE:
            raise _malformed(fc, f"write count {count} (1..{MAX_READ_WRITE})", writes)
        if size != 2 * count or n != 10 + size:
            why = f"byte count {size}, {n - 10} data bytes, {count} registers"
            raise _malformed(fc, why, writes)
        values = struct.unpack_from(f">{count}H", pdu, 10)
        return Request(
            FunctionCode.READ_WRITE_MULTIPLE_REGISTERS,
            read=(read_address, read_count),
            write=(address, count),
            values=values,
        )
    raise PduError(ExceptionCode.ILLEGAL_FUNCTION, f"function code {fc} not served")


def adu(tid: int, unit: int, pdu: bytes) -> bytes:
    """``pdu`` with its MBAP header."""
    return MBAP.pack(tid, 0, len(pdu) + 1, unit) + pdu


def read_answer(function: int, registers: bytes) -> bytes:
    """FC3/FC23 answer PDU: byte count, then the registers (big-endian words)."""
    return bytes((function, len(registers))) + registers


def write_answer(request: Request, pdu: bytes) -> bytes:
    """FC6 and FC22 echo the request; FC16 answers its address and count."""
    if request.function == FunctionCode.WRITE_MULTIPLE_REGISTERS:
        return pdu[:5]
    return pdu


def exception_answer(function: int, code: int) -> bytes:
    """The exception PDU: the function code with bit 7 set, the exception code."""
    return bytes(((function | 0x80) & 0xFF, code))
