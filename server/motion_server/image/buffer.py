"""The image in shared memory: two snapshot buffers under sequence counters.

Memory layout (all 8-byte words)::

    control   magic, slot count, layout fingerprint, publish count P, scan pid, beat B,
              spare x2
    buffer 0  sequence, META_WORDS meta words, one float64 per slot
    buffer 1  the same

The writer (the scan) fills buffer ``(P + 1) % 2`` with its sequence counter odd, makes it
even, then sets P to P + 1: it never waits for a reader. A reader takes buffer ``P % 2``,
copies it between two reads of its sequence counter and retries when they differ (the
writer lapped it: two publishes during one copy). A reader therefore never sees half a
cycle.

The order of the writer's stores and of the reader's loads is what makes this correct;
CPython performs them in program order (each is a separate C call), and x86-64 keeps
stores ordered with stores and loads with loads. On a weakly ordered CPU (ARM) a torn
snapshot is possible in principle; nothing else in the server depends on the CPU.

B moves on every pass of the scan's loop, idle included: with P it tells the supervisor
that the scan works (:class:`Progress`, :mod:`motion_server.liveness`).

Meta words: the cycle (tick) the snapshot shows, the publish count, the scan's state,
the clock mode, and for every write channel the sequence number of the last batch the
scan applied (a front-end drops its pending writes up to it: read-your-writes).
"""

from __future__ import annotations

import mmap
import os
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

MAGIC = 0x4D4F54494F4E494D  # "MOTIONIM"
CONTROL_WORDS = 8
#: write channels the meta words track (channel numbers 0 .. MAX_CHANNELS - 1)
MAX_CHANNELS = 16
META_WORDS = 8 + MAX_CHANNELS

# control words
_C_MAGIC, _C_SLOTS, _C_PRINT, _C_COUNT, _C_PID, _C_BEAT = range(6)


class Meta(IntEnum):
    """Index of a meta word of a snapshot."""

    TICK = 0
    COUNT = 1
    STATE = 2
    CLOCK_MODE = 3
    APPLIED = 8  # + channel number


class ScanState(IntEnum):
    """The scan's life, as a snapshot shows it."""

    STARTING = 0
    RUNNING = 1
    STOPPING = 2
    STOPPED = 3


def image_bytes(slots: int) -> int:
    """Size in bytes of an image of ``slots`` slots."""
    return 8 * (CONTROL_WORDS + 2 * (1 + META_WORDS + slots))


class ImageError(RuntimeError):
    """Shared memory that does not hold the expected image."""


@dataclass
class Snapshot:
    """A consistent copy of one published cycle."""

    values: np.ndarray
    meta: np.ndarray
    count: int

    @property
    def tick(self) -> int:
        return int(self.meta[Meta.TICK])

    @property
    def state(self) -> ScanState:
        return ScanState(int(self.meta[Meta.STATE]))

    def applied(self, channel: int) -> int:
        return int(self.meta[Meta.APPLIED + channel])


class _Image:
    def __init__(self, buf: memoryview | bytearray | mmap.mmap, slots: int) -> None:
        need = image_bytes(slots)
        if len(buf) < need:
            raise ImageError(f"shared image of {len(buf)} bytes, {need} needed")
        self._buf = buf
        self.slots = slots
        self.control = np.frombuffer(buf, dtype=np.int64, count=CONTROL_WORDS, offset=0)
        stride = 8 * (1 + META_WORDS + slots)
        self._seq: list[np.ndarray] = []
        self._meta: list[np.ndarray] = []
        self._values: list[np.ndarray] = []
        for k in range(2):
            base = 8 * CONTROL_WORDS + k * stride
            self._seq.append(np.frombuffer(buf, dtype=np.int64, count=1, offset=base))
            self._meta.append(np.frombuffer(buf, dtype=np.int64, count=META_WORDS, offset=base + 8))
            self._values.append(
                np.frombuffer(
                    buf, dtype=np.float64, count=slots, offset=base + 8 * (1 + META_WORDS)
                )
            )


class ImageWriter(_Image):
    """The scan's side: :meth:`publish` a full snapshot after every cycle."""

    def __init__(
        self, buf: memoryview | bytearray | mmap.mmap, slots: int, fingerprint: int
    ) -> None:
        super().__init__(buf, slots)
        c = self.control
        c[_C_SLOTS] = slots
        c[_C_PRINT] = fingerprint
        c[_C_COUNT] = 0
        c[_C_PID] = os.getpid()
        c[_C_MAGIC] = MAGIC
        self.count = 0

    def publish(self, values: np.ndarray, meta: np.ndarray) -> int:
        """Publish ``values`` (one per slot) and ``meta`` (META_WORDS); returns the
        publish count."""
        n = self.count + 1
        k = n & 1
        seq = self._seq[k]
        seq[0] += 1  # odd: being written
        self._meta[k][:] = meta
        self._meta[k][Meta.COUNT] = n
        self._values[k][:] = values
        seq[0] += 1  # even: complete
        self.control[_C_COUNT] = n
        self.count = n
        return n

    def beat(self) -> None:
        """The scan's loop made a pass (it calls this on every one, idle included)."""
        self.control[_C_BEAT] += 1


class Progress:
    """The supervisor's view of the image: only what shows that the scan works."""

    def __init__(self, buf: memoryview | bytearray | mmap.mmap) -> None:
        self._control = np.frombuffer(buf, dtype=np.int64, count=CONTROL_WORDS, offset=0)

    def marker(self) -> tuple[int, int]:
        """(publish count, beat): the scan worked between two calls when they differ."""
        c = self._control
        return int(c[_C_COUNT]), int(c[_C_BEAT])


class ImageReader(_Image):
    """A front-end's side: :meth:`snapshot` returns the latest published cycle."""

    #: copies tried before giving up (each failure means two publishes during one copy)
    ATTEMPTS = 1000

    def __init__(
        self, buf: memoryview | bytearray | mmap.mmap, slots: int, fingerprint: int
    ) -> None:
        super().__init__(buf, slots)
        c = self.control
        if int(c[_C_MAGIC]) != MAGIC:
            raise ImageError("shared memory does not hold a motion-server image")
        if int(c[_C_SLOTS]) != slots or int(c[_C_PRINT]) != fingerprint:
            raise ImageError("the image was laid out for another site map")
        self._last: Snapshot | None = None

    @property
    def published(self) -> int:
        """The publish count of the newest snapshot (cheap: one word)."""
        return int(self.control[_C_COUNT])

    def snapshot(self) -> Snapshot:
        """The newest complete snapshot (the previous copy when nothing new was published)."""
        for _ in range(self.ATTEMPTS):
            n = int(self.control[_C_COUNT])
            last = self._last
            if last is not None and last.count == n:
                return last
            k = n & 1
            seq = self._seq[k]
            s1 = int(seq[0])
            if s1 & 1:
                continue
            meta = self._meta[k].copy()
            values = self._values[k].copy()
            if int(seq[0]) == s1 and int(meta[Meta.COUNT]) == n:
                snap = Snapshot(values, meta, n)
                self._last = snap
                return snap
        raise ImageError("no consistent snapshot: the writer laps every copy")


def create_shared(size: int) -> int:
    """An anonymous shared-memory file of ``size`` bytes (Linux ``memfd``): its file
    descriptor is passed to the scan and front-end processes; it disappears with the
    last of them. Nothing is visible in the file system."""
    fd = os.memfd_create("motion-server-image", os.MFD_CLOEXEC)
    os.ftruncate(fd, size)
    return fd


def map_shared(fd: int, size: int, writable: bool) -> mmap.mmap:
    """Map the shared image: read-write for the scan, read-only for front-ends."""
    prot = mmap.PROT_READ | (mmap.PROT_WRITE if writable else 0)
    return mmap.mmap(fd, size, flags=mmap.MAP_SHARED, prot=prot)
