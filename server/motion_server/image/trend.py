"""The trend ring: every cycle's values of the channels the web view trends, in shared
memory (``docs/web.md`` § "Every cycle: the trend ring").

The image holds the last published cycle only; cycles run back to back (a ``Clock.Step``,
a late realtime scan, the fast clock) are published once. A trend that must show every
cycle therefore gets its own memory, which the scan writes after each cycle and the web
process drains. Memory layout (8-byte words)::

    control   magic, capacity (rows), MAX_CHANNELS,
              request generation G, channel count n, spare x3,
              MAX_CHANNELS image slot numbers (the request),
              taken generation, written rows W, spare x6
    rows      capacity x (sequence, tick, generation, MAX_CHANNELS float64 values)

The web process (the only writer of the request) makes G odd, writes the slot numbers
and the count, then makes G even again (G + 2 in all). The scan compares G with the
generation it took once per cycle (one word): with no trend asked for (n = 0) it does
nothing more. It takes a new request only when G is even and unchanged after it read the
slots, so it never trends a set half written. Row ``w`` (the w-th row written,
0-based) lives at ``w % capacity``; the scan makes its sequence ``2w + 1`` while it writes
it and ``2w + 2`` once complete, then sets W = w + 1. A reader copies rows ``[r, W)``
and checks each row's sequence after the copy: a row the scan overwrote meanwhile (its
sequence moved on) is lost, never shown torn. Rows carry the generation of the channel set
they were written with, so a set that changes between two drains splits cleanly.

The stores and loads are ordered as the image's (:mod:`.buffer`): CPython issues them in
program order, and x86-64 keeps stores ordered with stores and loads with loads.
"""

from __future__ import annotations

import mmap
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

MAGIC = 0x4D53545245454E44  # "MSTREEND"
#: channels one ring row holds (the union of every client's set; 16 per client)
MAX_CHANNELS = 64
#: rows of the ring: 32 s of a 1 ms scan (the web process drains it about every 20 ms)
CAPACITY = 1 << 15
ROW_WORDS = 3 + MAX_CHANNELS
# control words
_MAGIC, _CAP, _MAXCH, _REQ_GEN, _REQ_N = range(5)
_REQ_SLOTS = 8
_TAKEN = _REQ_SLOTS + MAX_CHANNELS
_WRITTEN = _TAKEN + 1
CONTROL_WORDS = _WRITTEN + 7
# row words
_SEQ, _TICK, _GEN = range(3)
_ROWS_AT = 8 * CONTROL_WORDS
_ROW_BYTES = 8 * ROW_WORDS
_WRITTEN_AT = 8 * _WRITTEN
_REQ_GEN_AT = 8 * _REQ_GEN
_WORD = struct.Struct("<q")


def ring_bytes(capacity: int = CAPACITY) -> int:
    """Size in bytes of a ring of ``capacity`` rows."""
    return 8 * (CONTROL_WORDS + capacity * ROW_WORDS)


class RingError(RuntimeError):
    """Shared memory that does not hold a trend ring."""


class _Ring:
    def __init__(self, buf: Any, capacity: int) -> None:
        if len(buf) < ring_bytes(capacity):
            raise RingError(f"trend ring of {len(buf)} bytes, {ring_bytes(capacity)} needed")
        self.capacity = capacity
        self.control = np.frombuffer(buf, dtype=np.int64, count=CONTROL_WORDS, offset=0)
        count = capacity * ROW_WORDS
        self.words = np.frombuffer(buf, np.int64, count, 8 * CONTROL_WORDS).reshape(
            capacity, ROW_WORDS
        )
        self.floats = np.frombuffer(buf, np.float64, count, 8 * CONTROL_WORDS).reshape(
            capacity, ROW_WORDS
        )


class RingWriter(_Ring):
    """The scan's side. ``getter(slot)`` gives a function that reads the live value of
    image slot ``slot`` (the kernel's state after the cycle: what the image shows once
    published), ``slots`` the number of slots. Call :meth:`cycle` after every cycle."""

    def __init__(
        self,
        buf: Any,
        getter: Callable[[int], Callable[[], Any]],
        slots: int,
        capacity: int = CAPACITY,
    ) -> None:
        super().__init__(buf, capacity)
        c = self.control
        if int(c[_MAGIC]) != MAGIC:  # a fresh ring (a restarted web process keeps its own)
            c[_CAP] = capacity
            c[_MAXCH] = MAX_CHANNELS
            c[_MAGIC] = MAGIC
        self._getter = getter
        self._slots = slots
        self._buf = buf
        self._body = struct.Struct("<qq")
        self._taken = int(c[_TAKEN])
        self._written = int(c[_WRITTEN])
        self._reading: list[Any] = []

    def cycle(self, tick: int) -> None:
        """Write this cycle's row (nothing when no channel is asked for)."""
        gen = _WORD.unpack_from(self._buf, _REQ_GEN_AT)[0]  # the idle cost: this read
        if gen != self._taken:
            self._take(gen)
        reading = self._reading
        if not reading:
            return
        # one C call per store (struct), in the order the reader relies on
        w = self._written
        at = _ROWS_AT + (w % self.capacity) * _ROW_BYTES
        buf = self._buf
        _WORD.pack_into(buf, at, 2 * w + 1)
        self._body.pack_into(buf, at + 8, tick, self._taken, *[get() for get in reading])
        _WORD.pack_into(buf, at, 2 * w + 2)
        self._written = w + 1
        _WORD.pack_into(buf, _WRITTEN_AT, w + 1)

    def renew(self) -> None:
        """Take the channel set again at the next cycle (the getters read another
        system: a snapshot was restored)."""
        self._taken = -1

    def _take(self, gen: int) -> None:
        """Take request ``gen`` unless the web process is writing one (G odd, or G moved
        while read): then the rows keep the set taken before, and the next cycle looks
        again."""
        if gen & 1:
            return
        c = self.control
        n = max(0, min(int(c[_REQ_N]), MAX_CHANNELS))
        slots = [int(s) for s in c[_REQ_SLOTS : _REQ_SLOTS + n]]
        if int(c[_REQ_GEN]) != gen:
            return
        self._reading = [self._getter(s) for s in slots if 0 <= s < self._slots]
        if len(self._reading) != n:  # a slot out of range: trend nothing rather than wrong
            self._reading = []
        self._body = struct.Struct(f"<qq{len(self._reading)}d")
        self._taken = gen
        c[_TAKEN] = gen


@dataclass
class Rows:
    """Rows taken from the ring: ``ticks`` and ``values`` (rows x channels of that
    generation), and how many rows were lost just before them."""

    generation: int
    ticks: np.ndarray
    values: np.ndarray
    lost_before: int


class RingReader(_Ring):
    """The web process's side: asks for a channel set (:meth:`request`) and drains the
    rows written since its last look (:meth:`drain`)."""

    def __init__(self, buf: Any, capacity: int | None = None) -> None:
        control = np.frombuffer(buf, dtype=np.int64, count=CONTROL_WORDS, offset=0)
        if int(control[_MAGIC]) != MAGIC:
            raise RingError("shared memory does not hold a trend ring")
        super().__init__(buf, int(control[_CAP]) if capacity is None else capacity)
        self._next = int(self.control[_WRITTEN])
        #: generation -> its image slots, for the sets this reader asked for
        self.sets: dict[int, tuple[int, ...]] = {}

    @property
    def generation(self) -> int:
        return int(self.control[_REQ_GEN])

    @property
    def taken(self) -> int:
        """The generation the scan writes rows of."""
        return int(self.control[_TAKEN])

    def request(self, slots: list[int]) -> int:
        """Ask the scan for ``slots`` (image slot numbers, at most :data:`MAX_CHANNELS`)
        from its next cycle on; returns the generation their rows will carry."""
        if len(slots) > MAX_CHANNELS:
            raise ValueError(f"{len(slots)} channels: at most {MAX_CHANNELS}")
        c = self.control
        before = int(c[_REQ_GEN])
        c[_REQ_GEN] = before + 1  # odd: being written
        c[_REQ_SLOTS : _REQ_SLOTS + len(slots)] = slots
        c[_REQ_N] = len(slots)
        gen = before + 2
        c[_REQ_GEN] = gen  # even: complete
        self.sets[gen] = tuple(slots)
        return gen

    def drain(self) -> list[Rows]:
        """Every row written since the last drain, split by generation; rows lost (the
        ring lapped this reader, or a row was overwritten while copied) are counted in
        ``lost_before`` of the rows that follow them (and of a last, empty, :class:`Rows`
        when nothing follows)."""
        written = int(self.control[_WRITTEN])
        start = self._next
        lost = 0
        if written - start > self.capacity:
            lost = written - self.capacity - start
            start = written - self.capacity
        if start >= written:
            return []
        idx = np.arange(start, written) % self.capacity
        words = self.words[idx]  # a copy
        floats = self.floats[idx]
        seq_after = self.words[idx, _SEQ]
        expect = 2 * np.arange(start, written, dtype=np.int64) + 2
        good = (words[:, _SEQ] == expect) & (seq_after == expect)
        self._next = written
        out: list[Rows] = []
        # runs of rows of one generation (-1: rows lost), found with numpy, not row by row
        keys = np.where(good, words[:, _GEN], -1)
        cuts = np.flatnonzero(np.diff(keys)) + 1
        starts = [0, *cuts.tolist()]
        ends = [*cuts.tolist(), len(keys)]
        for i, j in zip(starts, ends, strict=True):
            gen = int(keys[i])
            if gen < 0:
                lost += j - i
                continue
            width = len(self.sets.get(gen, ()))
            out.append(Rows(gen, words[i:j, _TICK].copy(), floats[i:j, 3 : 3 + width], lost))
            lost = 0
        if lost:
            out.append(Rows(-1, np.zeros(0, np.int64), np.zeros((0, 0)), lost))
        return out


def map_ring(fd: int, size: int) -> mmap.mmap:
    """Map the trend ring read-write (both sides write: the request, the rows)."""
    return mmap.mmap(fd, size, flags=mmap.MAP_SHARED, prot=mmap.PROT_READ | mmap.PROT_WRITE)
