"""Liveness: how the supervisor tells a process that runs from one that only exists.

``waitpid`` sees a process that exited. A process can also stand still while it exists:
stopped (SIGSTOP, a debugger), stuck in a loop, its event loop blocked. A Modbus
front-end in that state still accepts connections (the kernel completes the handshake)
and answers nothing; a scan in that state runs no cycle and does not answer SIGTERM
(its handler only sets a flag its loop would look at). So every process shows, while it
works, something that moves:

- **the scan**: two words of the shared image's control area. The publish count moves
  after every cycle; the scan's *beat* (:meth:`ImageWriter.beat
  <motion_server.image.buffer.ImageWriter.beat>`) moves on every pass of its loop, and
  the loop passes at least every :data:`SCAN_BEAT` seconds even when nothing is due. The
  beat is what makes this independent of the clock mode: with the manual clock the scan
  publishes only when a client steps it, and an idle controller is not a hung one.
- **a front-end**: a line ``{"beat": n}`` on its standard output (the pipe it already
  has to the supervisor) every :data:`FRONTEND_BEAT` seconds, written by a task of its
  event loop, so a loop that is blocked misses it. Any other line (an audit line) counts
  as well.

A process that showed nothing for its limit (:data:`SCAN_HANG`, :data:`FRONTEND_HANG`) is
hung. The limits are in seconds, not in cycles: what stops a process (a hang, a debugger,
the operating system) is measured in seconds whatever the period, and the scan's beat
does not depend on the period or the clock mode. :data:`SCAN_HANG` is 3 s: 1,500 cycles
at the default period of 2 ms (94 at the longest, 32 ms); a scan that runs passes its
loop every few milliseconds (at most every :data:`SCAN_BEAT`), and one pass is bounded
(at most ``max_catch_up`` cycles in real time, 200 for a manual step, 1 ms of the fast
clock, 50 cycles of the programmed stop), so 3 s is twelve missed beats: no loaded
machine delays a runnable process that long, and a hung controller is still found
within seconds.

The supervisor does not blame its own stalls on the others: when it looked last more
than :data:`SELF_STALL` seconds ago (it was stopped, or the whole machine was), every
process gets a fresh window from now.

:class:`Liveness` is the bookkeeping, pure and clocked by its caller (unit tests drive
it with numbers); the supervisor feeds it and acts on what :meth:`Liveness.hung` returns.
"""

from __future__ import annotations

from dataclasses import dataclass

#: seconds between two beats of an idle scan (its loop's longest sleep)
SCAN_BEAT = 0.25
#: seconds without a publish or a beat after which the scan is hung
SCAN_HANG = 3.0
#: seconds a hung scan gets to run the programmed stop the supervisor asks for, and to
#: exit, before it is killed
SCAN_KILL_GRACE = 2.0
#: seconds between two beats of a front-end
FRONTEND_BEAT = 0.5
#: seconds without a line after which a front-end that listens is hung. Modbus serves
#: the PLCs and panels that command motion and does little work per request: 3 s (six
#: missed beats). OPC UA does bulk work on its loop (an address space of thousands of
#: nodes, large reads and browses within its OperationLimits, publishing): 10 s, so that
#: a heavy but legitimate request is not mistaken for a hang. The web view serves a page
#: and streams trends (small work per message): 5 s
FRONTEND_HANG = {"modbus": 3.0, "opcua": 10.0, "web": 5.0}
#: the supervisor's own gap between two looks beyond which it forgives everyone
SELF_STALL = 1.0


@dataclass
class _Watched:
    limit: float
    seen: float


class Liveness:
    """When each watched process last showed progress, on the caller's monotonic clock."""

    def __init__(self) -> None:
        self._watched: dict[str, _Watched] = {}
        self._looked: float | None = None

    def watch(self, name: str, limit: float, now: float) -> None:
        """Watch ``name`` from ``now`` on: hung when nothing is seen for ``limit`` s."""
        self._watched[name] = _Watched(limit, now)

    def forget(self, name: str) -> None:
        self._watched.pop(name, None)

    def watching(self, name: str) -> bool:
        return name in self._watched

    def seen(self, name: str, now: float) -> None:
        """``name`` showed progress at ``now``."""
        watched = self._watched.get(name)
        if watched is not None:
            watched.seen = now

    def hung(self, now: float) -> list[tuple[str, float]]:
        """(name, seconds silent) of every process silent beyond its limit. Call it on
        every look: a gap since the previous look longer than :data:`SELF_STALL` was the
        caller's own stall, and everyone's window starts again at ``now``."""
        if self._looked is not None and now - self._looked > SELF_STALL:
            for watched in self._watched.values():
                watched.seen = max(watched.seen, now)
        self._looked = now
        return [(name, now - w.seen) for name, w in self._watched.items() if now - w.seen > w.limit]
