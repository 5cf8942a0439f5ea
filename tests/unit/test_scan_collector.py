"""The scan process's collector (``scan/collector.py``): with the automatic collection off,
a generation is collected between cycles when its count passed CPython's threshold and
the next cycle is far enough away, or without that time once the youngest generation
holds ``force`` thresholds; the generation is the oldest past its threshold."""

from __future__ import annotations

import gc
import weakref
from collections.abc import Iterator

import pytest

from motion_server.scan.collector import SLACK, IdleCollector


class Node:
    """A container in a reference cycle: only a collection frees it."""

    def __init__(self) -> None:
        self.me = self


@pytest.fixture
def collector() -> Iterator[IdleCollector]:
    c = IdleCollector(force=4)
    c.start()
    try:
        gc.collect()  # every count at zero
        c.thresholds = (1000, 2, 2)  # (small: the test allocates a little past them)
        yield c
    finally:
        c.stop()


def grow(count: int) -> list[list[int]]:
    """``count`` new tracked containers, kept alive (the young generation's count grows)."""
    return [[k] for k in range(count)]


def test_nothing_is_collected_below_the_threshold(collector: IdleCollector) -> None:
    kept = grow(10)
    assert gc.get_count()[0] < 1000
    assert collector.between(None) is None
    assert collector.idle == collector.forced == 0
    assert kept


def test_a_due_collection_waits_for_time_between_cycles(collector: IdleCollector) -> None:
    """Past the threshold with too little time left: nothing; with time left (or no cycle
    due at all): the youngest generation, and a reference cycle dropped before is freed."""
    node = Node()
    gone = weakref.ref(node)
    del node
    kept = grow(1200)
    assert gc.get_count()[0] > 1000
    assert collector.between(SLACK / 2) is None
    assert gone() is not None  # (no automatic collection either)
    assert collector.between(SLACK * 2) == 0
    assert gone() is None
    assert gc.get_count()[0] < 1000
    assert (collector.idle, collector.forced) == (1, 0)
    kept += grow(1200)
    assert collector.between(None) == 0
    assert collector.idle == 2
    assert kept


def test_a_collection_that_cannot_wait_is_forced(collector: IdleCollector) -> None:
    """No time left in any pass (the fast clock): collected once the count passes four
    thresholds (``force=4``), not before."""
    kept = grow(2500)
    assert 2000 < gc.get_count()[0] <= 4000
    assert collector.between(0.0) is None
    kept += grow(2000)
    assert gc.get_count()[0] > 4000
    assert collector.between(0.0) == 0
    assert (collector.idle, collector.forced) == (0, 1)
    assert kept


def test_the_oldest_generation_past_its_threshold_is_collected(
    collector: IdleCollector,
) -> None:
    """Thresholds (1000, 2, 2): three collections of generation 0 put generation 1's count
    past 2, so the fourth is of generation 1 (and the count starts again); three of those
    put generation 2's past 2, and the next collection is a full one."""
    kept: list[list[int]] = []
    seen = []
    for _ in range(13):
        kept += grow(1200)
        seen.append(collector.between(None))
    assert seen == [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 2]
    assert kept
