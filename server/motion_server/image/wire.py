"""The write queue's packets: what front-ends, the supervisor and the scan say to each
other over ``AF_UNIX``/``SOCK_SEQPACKET`` socket pairs.

A packet is one message (the socket keeps boundaries, so a front-end that dies mid-way
can never leave half a message for the scan to misread). Every packet starts with
``kind`` (:class:`Kind`), ``flags`` and a 32-bit sequence number; the rest depends on the
kind. Little-endian throughout. A write batch larger than :data:`MAX_PACKET` is sent as
fragments: every fragment but the last lacks :data:`FINAL`; the scan applies the batch
when the last one arrives, so a batch is applied whole or not at all.

The formats are fixed structs, not pickle: a front-end that a hostile client compromised
still cannot make the scan run code by what it sends.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import IntEnum

from ..safety.client import ClientInfo

#: the largest packet a side sends (well below the default socket buffer)
MAX_PACKET = 60_000
#: flags: the last fragment of a batch
FINAL = 1

_HEAD = struct.Struct("<BBxxI")  # kind, flags, sequence
_ITEM = struct.Struct("<Id")  # slot, value
_CLIENT = struct.Struct("<HI")  # port, connection
_ACK = struct.Struct("<QIB")  # tick when applied, cycles run for it, result
_HELLO = struct.Struct("<BqQ")  # channel, pid, layout fingerprint
_COUNT = struct.Struct("<Q")


class Kind(IntEnum):
    """What a packet carries."""

    HELLO = 1  # front-end -> scan: channel number, pid, layout fingerprint
    WELCOME = 2  # scan -> front-end: the hello was accepted
    REFUSED = 3  # scan -> front-end: the hello was refused (text); the channel closes
    WRITE = 4  # front-end -> scan: a batch of judged writes (slot, value)
    ACK = 5  # scan -> front-end: a batch was applied (and its cycles ran)
    STOP = 6  # supervisor -> scan: programmed stop, then exit
    RESTARTS = 7  # supervisor -> scan: front-end restarts so far (Diagnostics)
    RETAIN = 8  # scan -> supervisor: a retain payload (JSON) to write
    READY = 9  # scan -> supervisor: the controller runs
    STOPPED = 10  # scan -> supervisor: the programmed stop is complete


class Result(IntEnum):
    """The outcome of a batch, in its ACK."""

    APPLIED = 0
    REFUSED = 1  # the scan refused it (logged there); nothing was written
    NOT_RUN = 2  # applied, but its cycles did not run (the clock left manual mode, stop)
    FAILED = 3  # applied, but the command it carried failed (a snapshot; logged there)


class WireError(ValueError):
    """A packet that does not parse."""


@dataclass
class Batch:
    """Client writes to apply together, in order, at the start of the next cycle."""

    seq: int
    client: ClientInfo
    items: list[tuple[int, float]] = field(default_factory=list)


@dataclass(frozen=True)
class Ack:
    seq: int
    tick: int
    cycles: int
    result: Result


def _text(data: bytes, at: int) -> tuple[str, int]:
    if at >= len(data):
        raise WireError("truncated text")
    n = data[at]
    end = at + 1 + n
    if end > len(data):
        raise WireError("truncated text")
    return data[at + 1 : end].decode("utf-8", "replace"), end


def _put_text(text: str) -> bytes:
    raw = text.encode("utf-8")[:255]
    return bytes([len(raw)]) + raw


def header(data: bytes) -> tuple[Kind, int, int]:
    """(kind, flags, sequence) of a packet."""
    if len(data) < _HEAD.size:
        raise WireError(f"a packet of {len(data)} bytes")
    kind, flags, seq = _HEAD.unpack_from(data)
    try:
        return Kind(kind), flags, seq
    except ValueError:
        raise WireError(f"unknown packet kind {kind}") from None


# -- write batches -------------------------------------------------------------------------
def encode_batch(batch: Batch) -> list[bytes]:
    """The packets of a batch (one, or fragments each below :data:`MAX_PACKET`)."""
    c = batch.client
    first = (
        _put_text(c.protocol)
        + _put_text(c.address)
        + _put_text(c.user)
        + _put_text(c.role)
        + _CLIENT.pack(c.port & 0xFFFF, c.connection & 0xFFFFFFFF)
    )
    per = (MAX_PACKET - _HEAD.size - len(first)) // _ITEM.size
    items = batch.items
    packets: list[bytes] = []
    start = 0
    while True:
        chunk = items[start : start + per]
        start += len(chunk)
        final = start >= len(items)
        body = b"".join(_ITEM.pack(s, v) for s, v in chunk)
        prefix = first if not packets else b""
        packets.append(
            _HEAD.pack(Kind.WRITE, FINAL if final else 0, batch.seq & 0xFFFFFFFF) + prefix + body
        )
        if final:
            return packets


class BatchAssembler:
    """Reassembles the fragments of a channel's batches (one batch at a time)."""

    def __init__(self) -> None:
        self._partial: Batch | None = None

    def reset(self) -> None:
        self._partial = None

    def feed(self, data: bytes) -> Batch | None:
        """The batch completed by this WRITE packet, or None (more fragments follow)."""
        _, flags, seq = header(data)
        at = _HEAD.size
        batch = self._partial
        if batch is None or batch.seq != seq:
            protocol, at = _text(data, at)
            address, at = _text(data, at)
            user, at = _text(data, at)
            role, at = _text(data, at)
            if at + _CLIENT.size > len(data):
                raise WireError("truncated client")
            port, connection = _CLIENT.unpack_from(data, at)
            at += _CLIENT.size
            batch = Batch(seq, ClientInfo(protocol, address, port, connection, user, role))
        body = len(data) - at
        if body % _ITEM.size:
            raise WireError(f"a write body of {body} bytes")
        batch.items.extend(_ITEM.iter_unpack(data[at:]))
        if flags & FINAL:
            self._partial = None
            return batch
        self._partial = batch
        return None


# -- the other kinds -----------------------------------------------------------------------
def encode_ack(ack: Ack) -> bytes:
    return _HEAD.pack(Kind.ACK, 0, ack.seq & 0xFFFFFFFF) + _ACK.pack(
        ack.tick, ack.cycles & 0xFFFFFFFF, int(ack.result)
    )


def decode_ack(data: bytes) -> Ack:
    _, _, seq = header(data)
    if len(data) != _HEAD.size + _ACK.size:
        raise WireError("a malformed ACK")
    tick, cycles, result = _ACK.unpack_from(data, _HEAD.size)
    return Ack(seq, tick, cycles, Result(result))


def encode_hello(channel: int, pid: int, fingerprint: int) -> bytes:
    return _HEAD.pack(Kind.HELLO, 0, 0) + _HELLO.pack(channel, pid, fingerprint)


def decode_hello(data: bytes) -> tuple[int, int, int]:
    if len(data) != _HEAD.size + _HELLO.size:
        raise WireError("a malformed HELLO")
    channel, pid, fingerprint = _HELLO.unpack_from(data, _HEAD.size)
    return channel, pid, fingerprint


def encode_simple(kind: Kind, text: str = "", seq: int = 0) -> bytes:
    """A packet whose body is UTF-8 text (WELCOME, REFUSED, STOP, READY, STOPPED)."""
    return _HEAD.pack(kind, 0, seq) + text.encode("utf-8")


def decode_text(data: bytes) -> str:
    return data[_HEAD.size :].decode("utf-8", "replace")


def encode_count(kind: Kind, count: int) -> bytes:
    return _HEAD.pack(kind, 0, 0) + _COUNT.pack(count)


def decode_count(data: bytes) -> int:
    if len(data) != _HEAD.size + _COUNT.size:
        raise WireError("a malformed count")
    (count,) = _COUNT.unpack_from(data, _HEAD.size)
    return int(count)


def encode_blob(kind: Kind, blob: bytes) -> Iterator[bytes]:
    """A large body (RETAIN) in fragments: FINAL on the last."""
    step = MAX_PACKET - _HEAD.size
    parts: Sequence[bytes] = [blob[i : i + step] for i in range(0, len(blob), step)] or [b""]
    for i, part in enumerate(parts):
        yield _HEAD.pack(kind, FINAL if i == len(parts) - 1 else 0, 0) + part
