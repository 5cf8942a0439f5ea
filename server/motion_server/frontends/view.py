"""A front-end's image: reads from the scan's shared snapshot, writes through its queue.

Reads (:meth:`ImageView.read`, :meth:`ImageView.read_registers`) always show a whole
cycle: the newest snapshot the scan published (:mod:`motion_server.image.buffer`),
with this front-end's own writes that the scan has not applied yet laid over it, so a
client reads back what it just wrote. Registers are encoded once per snapshot, for the
whole map at once.

Writes are judged here, at once, exactly as before the scan had a process of its own
(:class:`~motion_server.tagmap.judge.Judge`: type, range, the kernel's numeric
boundary; read-only tags refused), then queued for the scan (:class:`ScanLink`), which
applies them at the start of its next cycle in arrival order. The returned
:class:`Ticket` resolves once the image shows the write; ``ticket.waits`` says the
protocol answer must wait for it (a ``Clock.Step``: answered once its cycles ran).
Accepted writes are reported to :attr:`ImageView.observers` (the audit log) with the
value they replace.

A REAL written with a subnormal value (0 < |value| < 1.18e-38) is accepted, as a
controller takes it, but warned of once per tag: it is what a 32-bit value sent in the
other word order looks like (10.0 as CDAB read as ABCD is 2.3e-41), and a jog at that
speed runs forever without moving. See ``docs/hmi.md``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from ..image import wire
from ..image.buffer import ImageReader, Meta, ScanState, Snapshot
from ..image.layout import ImageLayout
from ..instructions.schema import TagType
from ..safety.client import current_client
from ..tagmap import ClockMode, ReadOnlyError, Tag, TagMap
from ..tagmap.codec import Value
from ..tagmap.image import check_registers
from ..tagmap.judge import Judge
from ..tagmap.registers import RegisterEncoder, RegisterWrites
from .link import Link, ScanUnavailable, Ticket, WriteRefused

__all__ = ["ImageView", "ScanUnavailable", "Ticket", "WriteRefused", "outcome"]

log = logging.getLogger("motion_server.writes")

_HALF = 1 << 31
#: the smallest normal REAL (IEEE 754 binary32); below it, but not 0, a REAL is subnormal
REAL_MIN_NORMAL = 1.1754943508222875e-38
#: Clock commands whose write is answered once the scan carried them out
_ANSWERED_WHEN_DONE = frozenset({"Step", "SnapshotSave", "SnapshotRestore"})


async def outcome(ticket: Ticket) -> None:
    """Wait for the scan's acknowledgement of ``ticket``; :class:`WriteRefused` when the
    scan refused the write or the command it carried failed."""
    ack = await ticket.done()
    if ack.result == wire.Result.REFUSED:
        raise WriteRefused("the scan refused the write (see the server log)")
    if ack.result == wire.Result.FAILED:
        raise WriteRefused("the command failed (see the server log)")


def _applied(seq: int, applied: int) -> bool:
    """True when batch ``seq`` is at or before ``applied`` (32-bit sequence numbers)."""
    return (applied - seq) % (1 << 32) < _HALF


def _typed(tag_type: TagType, raw: float) -> Value:
    if tag_type == TagType.BOOL:
        return raw != 0.0
    if tag_type.is_float:
        return float(raw)
    return int(raw)


class ImageView:
    def __init__(
        self,
        layout: ImageLayout,
        reader: ImageReader,
        judge: Judge,
        link: Link | None,
        channel: int,
    ) -> None:
        self.layout = layout
        self.map: TagMap = layout.tagmap
        self.reader = reader
        self.judge = judge
        self.link = link
        self.channel = channel
        #: called after every accepted write with (tag, old value, new value)
        self.observers: list[Callable[[Tag, Value, Value], None]] = []
        self._slot = {t.name: i for i, t in enumerate(layout.tags)}
        self._types = [t.type for t in layout.tags]
        end = max((b.end for b in self.map.blocks), default=0)
        self._encoder = RegisterEncoder(layout.tags, self.map.word_order, end)
        self._writes = RegisterWrites(layout.tags, self.map.word_order)
        #: this front-end's writes the scan has not applied yet: slot -> (sequence, value)
        self._pending: dict[int, tuple[int, float]] = {}
        self._overlay = 0
        self._values_key: tuple[int, int] = (-1, -1)
        self._values: np.ndarray = np.zeros(layout.size)
        self._regs_key: tuple[int, int] = (-1, -1)
        self._regs: np.ndarray = np.zeros(0, dtype=np.uint16)
        #: REAL tags a subnormal value was written to (warned once each)
        self._subnormal_warned: set[str] = set()

    # -- the snapshot ---------------------------------------------------------------------
    def snapshot(self) -> Snapshot:
        """The newest cycle the scan published (without this front-end's pending writes)."""
        return self.reader.snapshot()

    def values(self) -> np.ndarray:
        """Every slot's value as this front-end's clients see it (do not modify)."""
        snap = self.reader.snapshot()
        key = (snap.count, self._overlay)
        if key == self._values_key:
            return self._values
        values = snap.values
        if self._pending:
            applied = snap.applied(self.channel)
            done = [s for s, (seq, _) in self._pending.items() if _applied(seq, applied)]
            for s in done:
                del self._pending[s]
            if done:
                self._overlay += 1
                key = (snap.count, self._overlay)
            if self._pending:
                values = values.copy()
                for s, (_, v) in self._pending.items():
                    values[s] = v
        self._values = values
        self._values_key = key
        return values

    @property
    def tick(self) -> int:
        """The cycle the newest snapshot shows."""
        return self.reader.snapshot().tick

    @property
    def mode(self) -> ClockMode:
        return ClockMode(int(self.reader.snapshot().meta[Meta.CLOCK_MODE]))

    @property
    def state(self) -> ScanState:
        return self.reader.snapshot().state

    # -- by tag -----------------------------------------------------------------------------
    def tag(self, tag: Tag | str) -> Tag:
        return tag if isinstance(tag, Tag) else self.map.tag(tag)

    def slot(self, tag: Tag | str) -> int:
        return self._slot[tag if isinstance(tag, str) else tag.name]

    def read(self, tag: Tag | str) -> Value:
        """A tag's value as of the newest snapshot (or as this front-end last wrote it)."""
        t = self.tag(tag)
        i = self._slot[t.name]
        return _typed(t.type, float(self.values()[i]))

    def typed(self, slot: int, raw: float) -> Value:
        """The Python value of slot ``slot`` holding ``raw``."""
        return _typed(self._types[slot], raw)

    def _check_subnormal(self, tag: Tag, value: float) -> None:
        """Warn (once per tag) of a subnormal REAL: the mark of a wrong word order."""
        if value == 0.0 or not math.isfinite(value) or abs(value) >= REAL_MIN_NORMAL:
            return
        self._subnormal_warned.add(tag.name)
        client = current_client()
        who = f" by {client.address}:{client.port}" if client is not None else ""
        order = self.map.word_order
        log.warning(
            "%s written as %.3g%s, a subnormal REAL: accepted, but a Modbus client that "
            "sends 32-bit values in the other word order (this map's: %s, %s) writes such "
            "values (docs/hmi.md); warned once per tag",
            tag.name,
            value,
            who,
            order.value,
            "ABCD" if order.value == "big" else "CDAB",
        )

    def write(self, tag: Tag | str, value: Any) -> Ticket:
        """Judge and queue one write (:class:`ReadOnlyError`, :class:`BadValueError`)."""
        return self.write_many([(self.tag(tag), value)])

    def write_many(self, updates: Iterable[tuple[Tag | str, Any]]) -> Ticket:
        """Judge every value, then queue them as one batch (all or nothing); words before
        bits, so a trigger sees the operands written with it."""
        staged: list[tuple[Tag, Value]] = []
        for ref, value in updates:
            tag = self.tag(ref)
            if not tag.writable:
                raise ReadOnlyError(f"{tag.name} is read-only")
            judged = self.judge(tag, value)
            if tag.type == TagType.REAL and tag.name not in self._subnormal_warned:
                self._check_subnormal(tag, float(judged))
            staged.append((tag, judged))
        staged.sort(key=lambda tv: tv[0].type == TagType.BOOL)
        if self.link is None:
            raise ScanUnavailable("this image is read-only (no link to the scan)")
        current = self.values()
        items = [(self._slot[t.name], float(v)) for t, v in staged]
        ticket = self.link.send(items, current_client())
        # a Clock.Step is answered once its cycles ran, a snapshot once it is saved or
        # restored; with the manual clock every write is answered once applied (time
        # stands still: a client that then steps the clock through another front-end
        # finds its write in that cycle)
        # (the link may have said so already: a client with too many writes in flight)
        ticket.waits = (
            ticket.waits
            or self.mode == ClockMode.MANUAL
            or any(t.owner == "Clock" and t.field in _ANSWERED_WHEN_DONE for t, _ in staged)
        )
        for (tag, value), (slot, raw) in zip(staged, items, strict=True):
            old = _typed(tag.type, float(current[slot]))
            self._pending[slot] = (ticket.seq, raw)
            for observe in self.observers:
                observe(tag, old, value)
        self._overlay += 1
        return ticket

    # -- by register ------------------------------------------------------------------------
    def check(self, address: int, count: int, write: bool) -> None:
        """:class:`AddressError` unless every register is in the map (and writable)."""
        check_registers(self.map, address, count, write)

    def registers(self) -> np.ndarray:
        """Every register of the map (uint16), encoded once per snapshot."""
        values = self.values()
        key = self._values_key
        if key != self._regs_key:
            self._regs = self._encoder.encode(values)
            self._regs_key = key
        return self._regs

    def read_registers(self, address: int, count: int, check: bool = True) -> list[int]:
        """``count`` registers from ``address`` (unused registers of a block read 0)."""
        if check:
            self.check(address, count, write=False)
        regs = self.registers()
        out: list[int] = regs[address : address + count].tolist()
        if len(out) < count:  # past the last tag (only without check)
            out += [0] * (count - len(out))
        return out

    def write_registers(self, address: int, values: Sequence[int], check: bool = True) -> Ticket:
        """Write registers (a write covering part of a 32/64-bit value changes those words)."""
        if check:
            self.check(address, len(values), write=True)
        updates = self._writes.updates(address, values, self._current)
        return self.write_many(updates)

    def _current(self, address: int, count: int) -> list[int]:
        regs: list[int] = self.registers()[address : address + count].tolist()
        return regs
