"""The scan process's garbage collector: run between cycles, not inside them.

CPython collects its youngest generation whenever 700 more tracked objects have been
allocated than freed, wherever the interpreter is: in a cycle, that collection adds
about 100 µs (a 256-axis map under ``write_abuse.py``'s load, in-process: 87 of 15,000
cycles held one, 104 µs median, 225 µs at most), the next generation's a little more.
The scan process freezes its start-up heap (never scanned again) and then turns the
automatic collection off: after each pass of its loop, if the next cycle is at least
:data:`SLACK` away, :meth:`IdleCollector.between` collects the generations whose counts
passed the thresholds CPython would have applied. A scan that never has that much time
left (the fast clock runs its cycles back to back) still collects once the youngest
generation holds :data:`FORCE` times its threshold, so memory stays bounded.

The counts and their meaning are CPython's (``gc.get_count``): allocations less
deallocations since the last collection of generation 0, collections of generation 0
since the last of generation 1, of generation 1 since the last of generation 2.
``gc.collect(g)`` resets the counts of generations 0..g and adds one to g + 1's, as an
automatic collection does. (CPython also holds back a full collection until a quarter of
the long-lived objects are new: after the freeze there are few, and a full collection
costs about as much as the others, so that rule is left out.)
"""

from __future__ import annotations

import gc
import time

#: seconds that must be left before the next cycle for a collection to run now (the
#: longest seen in the benchmarks' scans: 0.64 ms)
SLACK = 0.0007
#: the youngest generation is collected anyway once its count is this many thresholds
FORCE = 20


class IdleCollector:
    """Collects between cycles; ``idle`` and ``forced`` count the collections run,
    ``longest`` is the longest one's duration (seconds)."""

    def __init__(self, slack: float = SLACK, force: int = FORCE) -> None:
        self.slack = slack
        self.force = force
        self.thresholds = gc.get_threshold()
        self.idle = 0
        self.forced = 0
        self.longest = 0.0

    def start(self) -> None:
        """Take over from the automatic collection (after the start-up heap is frozen)."""
        self.thresholds = gc.get_threshold()
        gc.disable()

    def stop(self) -> None:
        """Hand back to the automatic collection."""
        gc.enable()

    def between(self, time_left: float | None) -> int | None:
        """After a pass of the loop, ``time_left`` seconds before the next cycle (None:
        no cycle is due): collect what is due if there is time, or if it cannot wait any
        longer. Returns the generation collected, or None."""
        count = gc.get_count()
        t0, t1, t2 = self.thresholds
        if t0 <= 0 or count[0] <= t0:
            return None
        forced = False
        if time_left is not None and time_left < self.slack:
            if count[0] <= t0 * self.force:
                return None
            forced = True
        # the oldest generation past its threshold, as CPython picks it
        generation = 2 if count[2] > t2 else 1 if count[1] > t1 else 0
        start = time.perf_counter()
        gc.collect(generation)
        self.longest = max(self.longest, time.perf_counter() - start)
        if forced:
            self.forced += 1
        else:
            self.idle += 1
        return generation
