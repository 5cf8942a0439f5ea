"""The web view's live data: status messages from the image, trend frames from the ring.

:class:`TrendHub` owns the web process's end of the trend ring
(:mod:`motion_server.image.trend`). The ring carries the union of every connected
client's channel set (at most :data:`~motion_server.image.trend.MAX_CHANNELS`); every
:data:`DRAIN_PERIOD` s the hub drains it and hands each client a binary frame of its own
columns (:func:`frame`). A client whose outgoing queue is full (it reads too slowly) has
frames dropped; the ticks missing before the next frame it gets are counted in that
frame's ``gaps_before``, as are rows the ring lost: gaps are computed from the ticks
themselves, so no cause of a missing cycle can go uncounted.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
from dataclasses import dataclass, field

import numpy as np

from ..image.trend import MAX_CHANNELS, RingReader

log = logging.getLogger("motion_server.web")

MAGIC = 0x4D535452  # 'MSTR'
VERSION = 1
HEADER = struct.Struct("<IHHIIII")
#: seconds between two drains of the ring (frames go out at about 50 Hz)
DRAIN_PERIOD = 0.02
#: channels of one client's trend
MAX_CLIENT_CHANNELS = 16
#: rows queued for one client beyond which its frames are dropped (2 s of a 1 ms scan)
QUEUE_ROWS = 2000
#: messages queued for one client beyond which error messages are dropped for it
BACKLOG = 1000


def frame(layout: int, ticks: np.ndarray, values: np.ndarray, gaps: int) -> bytes:
    """One binary trend frame (``docs/web.md`` § "Protocol")."""
    n, nchan = values.shape
    rows = np.empty((n, 1 + nchan), dtype="<f8")
    rows[:, 1:] = values
    rows.view("<u8")[:, 0] = ticks.astype("<u8")
    return HEADER.pack(MAGIC, VERSION, nchan, layout, n, min(gaps, 0xFFFFFFFF), 0) + rows.tobytes()


def parse_frame(data: bytes) -> tuple[int, int, np.ndarray, np.ndarray]:
    """(layout id, gaps_before, ticks, values) of a frame (tests and benches)."""
    magic, version, nchan, layout, n, gaps, _ = HEADER.unpack_from(data)
    if magic != MAGIC or version != VERSION:
        raise ValueError("not a trend frame")
    rows = np.frombuffer(data, dtype="<f8", offset=HEADER.size).reshape(n, 1 + nchan)
    return layout, gaps, rows.view("<u8")[:, 0].astype(np.int64), rows[:, 1:]


@dataclass(eq=False)
class TrendClient:
    """One WebSocket's trend: its channels (image slots), its layout id, its queue."""

    queue: asyncio.Queue[tuple[bytes, int] | dict[str, object]] = field(
        default_factory=asyncio.Queue
    )
    #: rows in the queue
    queued_rows: int = 0
    names: list[str] = field(default_factory=list)
    slots: tuple[int, ...] = ()
    layout: int = 0
    #: the ring generation from which this client's set is in the rows
    since: int = 0
    announced: bool = False
    last_tick: int | None = None
    dropped_frames: int = 0

    def say(self, message: dict[str, object]) -> None:
        """Queue a text message; an error message is dropped when :data:`BACKLOG`
        messages wait already (a client that sends bad messages and reads nothing)."""
        if message.get("type") == "error" and self.queue.qsize() >= BACKLOG:
            return
        self.queue.put_nowait(message)

    def offer(self, item: bytes, rows: int) -> bool:
        """Queue a frame of ``rows`` rows; False (dropped) when :data:`QUEUE_ROWS` rows
        wait already: the client is behind, and the ticks of the next frame it gets show
        the gap."""
        if self.queued_rows >= QUEUE_ROWS:
            self.dropped_frames += 1
            return False
        self.queued_rows += rows
        self.queue.put_nowait((item, rows))
        return True

    async def next(self) -> bytes | dict[str, object]:
        """The next frame or text message to send."""
        item = await self.queue.get()
        if isinstance(item, tuple):
            self.queued_rows -= item[1]
            return item[0]
        return item


class TrendHub:
    """The ring's reader, shared by every client of this process."""

    def __init__(self, ring: RingReader | None) -> None:
        self.ring = ring
        self.clients: set[TrendClient] = set()
        self._union: tuple[int, ...] = ()
        self._gen = 0
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        if self.ring is not None:
            self._task = asyncio.create_task(self._run())

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task

    def set_channels(self, client: TrendClient, names: list[str], slots: list[int]) -> None:
        """Replace ``client``'s set (``[]``: no trend); ValueError when it cannot be."""
        if self.ring is None:
            raise ValueError("trends are not available (no trend ring)")
        if len(slots) > MAX_CLIENT_CHANNELS:
            raise ValueError(f"{len(slots)} channels: at most {MAX_CLIENT_CHANNELS}")
        others = {s for c in self.clients if c is not client for s in c.slots}
        if len(others | set(slots)) > MAX_CHANNELS:
            raise ValueError(f"the clients together trend more than {MAX_CHANNELS} channels")
        client.names = list(names)
        client.slots = tuple(slots)
        client.layout += 1
        client.announced = False
        client.last_tick = None
        if slots:
            self.clients.add(client)
        else:
            self.clients.discard(client)
        self._request()
        client.since = self._gen

    def remove(self, client: TrendClient) -> None:
        if client in self.clients:
            self.clients.discard(client)
            self._request()

    def _request(self) -> None:
        union = tuple(sorted({s for c in self.clients for s in c.slots}))
        if union != self._union:
            assert self.ring is not None
            self._union = union
            self._gen = self.ring.request(list(union))

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(DRAIN_PERIOD)
            try:
                self.drain()
            except Exception:  # a bug here must not end the web process's loop
                log.exception("web: trend drain failed")

    def drain(self) -> None:
        """Take the new rows and give every client its frame."""
        assert self.ring is not None
        chunks = self.ring.drain()
        if not chunks or not self.clients:
            return
        for rows in chunks:
            if rows.generation < 0 or len(rows.ticks) == 0:
                continue
            ring_slots = self.ring.sets.get(rows.generation)
            if ring_slots is None:
                continue
            column = {s: i for i, s in enumerate(ring_slots)}
            for c in list(self.clients):
                if rows.generation < c.since or any(s not in column for s in c.slots):
                    continue
                if not c.announced:
                    c.announced = True
                    c.say({"type": "trend-layout", "id": c.layout, "channels": c.names})
                cols = [column[s] for s in c.slots]
                ticks = rows.ticks
                gaps = 0
                if c.last_tick is not None:
                    gaps = max(0, int(ticks[0]) - c.last_tick - 1)
                if c.offer(frame(c.layout, ticks, rows.values[:, cols], gaps), len(ticks)):
                    c.last_tick = int(ticks[-1])
