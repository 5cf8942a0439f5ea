"""Modbus frames without sockets: the limits of the Modbus Application Protocol
Specification V1.1b3 (FC3 reads 1..125 registers, FC16 writes 1..123 with a byte count
of 2 x N, FC23 reads 1..125 and writes 1..121) and of the MBAP header (protocol id 0;
the length counts the unit id and the PDU: 2..254, for ADUs of at most 260 bytes)."""

from __future__ import annotations

import struct

import pytest

from motion_server.frontends.modbus_pdu import (
    ExceptionCode,
    FunctionCode,
    HeaderError,
    PduError,
    adu,
    decode,
    exception_answer,
    header,
    read_answer,
    write_answer,
)


@pytest.mark.parametrize(("length", "ok"), [(0, False), (1, False), (2, True), (254, True),
                                            (255, False), (65535, False)])  # fmt: skip
def test_the_header_length_counts_unit_and_pdu_up_to_a_260_byte_adu(length: int, ok: bool) -> None:
    raw = struct.pack(">HHH", 0xABCD, 0, length)
    if ok:
        assert header(raw) == (0xABCD, length)
        assert 6 + length <= 260
    else:
        with pytest.raises(HeaderError, match=f"length {length}"):
            header(raw)


@pytest.mark.parametrize("protocol", [1, 7, 0xFFFF])
def test_a_protocol_id_other_than_0_is_no_modbus_header(protocol: int) -> None:
    with pytest.raises(HeaderError, match=f"protocol id {protocol}"):
        header(struct.pack(">HHH", 1, protocol, 6))


def exception_of(pdu: bytes) -> ExceptionCode:
    with pytest.raises(PduError) as err:
        decode(pdu)
    return err.value.code


@pytest.mark.parametrize(("count", "ok"), [(0, False), (1, True), (125, True), (126, False)])
def test_fc3_reads_1_to_125_registers(count: int, ok: bool) -> None:
    pdu = struct.pack(">BHH", 3, 100, count)
    if ok:
        request = decode(pdu)
        assert request.function == FunctionCode.READ_HOLDING_REGISTERS
        assert (request.read, request.write) == ((100, count), None)
    else:
        assert exception_of(pdu) == ExceptionCode.ILLEGAL_DATA_VALUE


@pytest.mark.parametrize(("count", "ok"), [(0, False), (1, True), (123, True), (124, False)])
def test_fc16_writes_1_to_123_registers(count: int, ok: bool) -> None:
    pdu = struct.pack(">BHHB", 16, 5000, count, (2 * count) & 0xFF)
    pdu += bytes(range(2 * count)) if ok else b""
    if ok:
        request = decode(pdu)
        assert request.write == (5000, count)
        words = bytes(range(2 * count))
        assert request.values == struct.unpack(f">{count}H", words)
        assert write_answer(request, pdu) == pdu[:5]  # address and count
    else:
        with pytest.raises(PduError) as err:
            decode(pdu)
        assert err.value.code == ExceptionCode.ILLEGAL_DATA_VALUE
        assert err.value.writes == (5000, count)


def test_fc16_byte_count_must_be_twice_the_count_and_match_the_data() -> None:
    ok = struct.pack(">BHHB", 16, 7, 2, 4) + bytes(4)
    assert decode(ok).values == (0, 0)
    for pdu in (ok[:5] + b"\x05" + bytes(4), ok[:-1], ok + b"\x00", ok[:5]):
        assert exception_of(pdu) == ExceptionCode.ILLEGAL_DATA_VALUE, pdu.hex()


@pytest.mark.parametrize(
    ("read", "write", "ok"),
    [(1, 1, True), (125, 121, True), (126, 1, False), (0, 1, False), (1, 122, False),
     (1, 0, False)],
)  # fmt: skip
def test_fc23_reads_1_to_125_and_writes_1_to_121(read: int, write: int, ok: bool) -> None:
    pdu = struct.pack(">BHHHHB", 23, 10, read, 20, write, (2 * write) & 0xFF)
    pdu += bytes(2 * write) if ok else b""
    if ok:
        request = decode(pdu)
        assert (request.read, request.write) == ((10, read), (20, write))
    else:
        assert exception_of(pdu) == ExceptionCode.ILLEGAL_DATA_VALUE


def test_fc6_and_fc22_echo_the_request() -> None:
    fc6 = struct.pack(">BHH", 6, 11, 0xBEEF)
    request = decode(fc6)
    assert (request.write, request.values) == ((11, 1), (0xBEEF,))
    assert write_answer(request, fc6) == fc6
    fc22 = struct.pack(">BHHH", 22, 12, 0xFFFE, 0x0001)
    request = decode(fc22)
    assert (request.write, request.masks) == ((12, 1), (0xFFFE, 0x0001))
    assert write_answer(request, fc22) == fc22
    assert exception_of(fc22[:-1]) == ExceptionCode.ILLEGAL_DATA_VALUE
    assert exception_of(fc6 + b"\x00") == ExceptionCode.ILLEGAL_DATA_VALUE


@pytest.mark.parametrize("fc", [c for c in range(256) if c not in (3, 6, 16, 22, 23)])
def test_every_other_function_code_is_illegal(fc: int) -> None:
    assert exception_of(bytes([fc, 0, 0, 0, 1])) == ExceptionCode.ILLEGAL_FUNCTION
    assert exception_answer(fc, ExceptionCode.ILLEGAL_FUNCTION) == bytes([fc | 0x80, 1])


def test_answers_carry_the_request_header() -> None:
    answer = adu(0x1234, 1, read_answer(3, b"\x00\x2a"))
    assert answer == bytes([0x12, 0x34, 0, 0, 0, 5, 1, 3, 2, 0, 0x2A])
