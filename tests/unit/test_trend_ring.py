"""The trend ring (motion_server.image.trend): every cycle's row, channel sets that change
between two drains, a reader lapped by the writer, a row overwritten while copied."""

from __future__ import annotations

import numpy as np

from motion_server.image.trend import RingReader, RingWriter, ring_bytes


class Source:
    """Image slots whose values the test sets: slot s reads ``values[s]``."""

    def __init__(self, slots: int) -> None:
        self.values = [0.0] * slots
        self.made = 0

    def getter(self, slot: int):  # type: ignore[no-untyped-def]
        self.made += 1
        return lambda: self.values[slot]


def ring(capacity: int = 64, slots: int = 10) -> tuple[Source, RingWriter, RingReader]:
    buf = bytearray(ring_bytes(capacity))
    src = Source(slots)
    writer = RingWriter(buf, src.getter, slots, capacity)
    return src, writer, RingReader(buf)


def test_nothing_is_written_until_a_set_is_asked_for() -> None:
    src, writer, reader = ring()
    for tick in range(1, 100):
        writer.cycle(tick)
    assert reader.drain() == []
    assert src.made == 0


def test_every_cycle_has_its_row_with_its_values() -> None:
    src, writer, reader = ring()
    gen = reader.request([3, 7])
    for tick in range(1, 41):
        src.values[3] = tick * 0.5
        src.values[7] = -tick
        writer.cycle(tick)
    (rows,) = reader.drain()
    assert rows.generation == gen and rows.lost_before == 0
    assert rows.ticks.tolist() == list(range(1, 41))
    assert rows.values[:, 0].tolist() == [t * 0.5 for t in range(1, 41)]
    assert rows.values[:, 1].tolist() == [-float(t) for t in range(1, 41)]
    assert reader.drain() == []  # taken once


def test_a_new_set_splits_the_rows_by_generation() -> None:
    _, writer, reader = ring()
    first = reader.request([1])
    for tick in range(1, 6):
        writer.cycle(tick)
    second = reader.request([2, 1, 4])
    for tick in range(6, 9):
        writer.cycle(tick)
    a, b = reader.drain()
    assert (a.generation, a.ticks.tolist(), a.values.shape) == (first, [1, 2, 3, 4, 5], (5, 1))
    assert (b.generation, b.ticks.tolist(), b.values.shape) == (second, [6, 7, 8], (3, 3))
    reader.request([])
    writer.cycle(9)
    assert reader.drain() == []


def test_a_lapped_reader_counts_the_rows_it_lost() -> None:
    capacity = 16
    _, writer, reader = ring(capacity)
    reader.request([0])
    for tick in range(1, 51):  # 50 rows into 16: the first 34 are overwritten
        writer.cycle(tick)
    (rows,) = reader.drain()
    assert rows.lost_before == 50 - capacity
    assert rows.ticks.tolist() == list(range(51 - capacity, 51))


def test_a_row_overwritten_while_copied_is_lost_not_torn() -> None:
    _, writer, reader = ring(8)
    reader.request([0])
    for tick in range(1, 5):
        writer.cycle(tick)
    # the writer has begun row 2 again (sequence odd): what the reader copies is not it
    reader.words[2, 0] = 2 * (2 + 8) + 1
    first, second = reader.drain()
    assert first.ticks.tolist() == [1, 2] and first.lost_before == 0
    assert second.ticks.tolist() == [4] and second.lost_before == 1


def test_a_restored_system_is_read_from_the_next_cycle() -> None:
    src, writer, reader = ring()
    reader.request([5])
    writer.cycle(1)
    made = src.made
    writer.renew()
    writer.cycle(2)
    assert src.made == made + 1  # the getters were made again
    (rows,) = reader.drain()
    assert rows.ticks.tolist() == [1, 2]


def test_a_slot_out_of_range_trends_nothing() -> None:
    _, writer, reader = ring(slots=4)
    reader.request([1, 99])
    writer.cycle(1)
    assert reader.drain() == []
    assert np.all(reader.words[:, 0] == 0)


def test_a_request_half_written_is_not_taken() -> None:
    src, writer, reader = ring()
    first = reader.request([1])
    writer.cycle(1)
    # the web process is writing another request: G odd, slots changing
    reader.control[3] = first + 1
    reader.control[8] = 2
    writer.cycle(2)
    reader.control[3] = first + 2
    reader.sets[first + 2] = (2,)
    src.values[1], src.values[2] = 1.0, 2.0
    writer.cycle(3)
    a, b = reader.drain()
    assert (a.generation, a.ticks.tolist()) == (first, [1, 2])  # the old set meanwhile
    assert (b.generation, b.ticks.tolist(), b.values[:, 0].tolist()) == (first + 2, [3], [2.0])
