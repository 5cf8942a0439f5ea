"""The scan process: ``python -m motion_server.scan``, started by the supervisor.

It reads its :class:`~motion_server.launch.LaunchSpec` from standard input, maps the
shared image writable, builds the system and runs :meth:`Scan.service` in a ``select``
loop over its channels (the supervisor's control channel and one per front-end). It
imports no protocol stack (a test checks): nothing a client sends is parsed here, only
the judged batches front-ends forward.

Liveness: every pass of the loop beats in the image (:meth:`ImageWriter.beat`), and the
loop passes at least every :data:`~motion_server.liveness.SCAN_BEAT` seconds even with
nothing due (the manual clock waiting for a step), so the supervisor can tell an idle scan
from a hung one (:mod:`motion_server.liveness`).

Garbage: the start-up heap is frozen, and the collector runs between cycles, when the
next one is far enough away (:mod:`.collector`), not inside them.

Signals: SIGTERM runs the programmed stop of every group, then the process exits 0;
SIGINT is left to the supervisor (a terminal's Ctrl-C reaches the whole process group,
and the supervisor orders the stop). End of file on the control channel (the
supervisor died) stops the same way.
"""

from __future__ import annotations

import gc
import logging
import os
import select
import signal
import socket
import sys
import time

from ..config import SiteMapError
from ..image import wire
from ..image.buffer import map_shared
from ..image.trend import map_ring
from ..launch import LaunchSpec, follow_supervisor, setup_logging
from ..liveness import SCAN_BEAT
from ..safety.retain import RetainError
from ..scheduling import SCAN_RT_PRIORITY, Policy
from ..tagmap.fields import ClockMode
from .channel import CONTROL, Channel
from .collector import IdleCollector
from .core import Scan

log = logging.getLogger("motion_server.scan")


#: the scan's scheduling priority (nice value) when the system allows raising it
SCAN_NICE = -10
#: seconds the scan waits, when it ends, for the supervisor to take what it still has to send
DRAIN_TIMEOUT = 5.0
#: the scan's load (% of each second busy) beyond which it leaves the real-time policy: it
#: cannot keep its period then, and on a machine of one core it would leave the front-ends
#: almost no time to answer
OVERLOAD = 90.0


def scan_policy() -> Policy:
    """Real-time (:data:`~motion_server.scheduling.SCAN_RT_PRIORITY`) while the clock
    follows the wall clock; in the manual and fast modes, where cycles run back to back
    on demand, the ordinary policy at nice :data:`SCAN_NICE`."""
    return Policy("scan", SCAN_RT_PRIORITY, OVERLOAD, nice=SCAN_NICE)


def _realtime(mode: ClockMode) -> bool:
    return mode in (ClockMode.REALTIME, ClockMode.SCALED)


def main() -> int:
    spec = LaunchSpec.read(sys.stdin.buffer)
    follow_supervisor(spec)
    setup_logging(spec.log_level)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_r, False)
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    stop = [False]

    def on_term(signum: int, frame: object) -> None:
        stop[0] = True

    signal.signal(signal.SIGTERM, on_term)
    channels = {
        number: Channel(socket.socket(fileno=fd), number) for number, fd in spec.channels.items()
    }
    control = channels.get(CONTROL)

    def send_retain(payload: dict[str, object]) -> None:
        import json

        blob = json.dumps(payload, separators=(",", ":")).encode("utf-8")
        if control is not None and not control.closed:
            for packet in wire.encode_blob(wire.Kind.RETAIN, blob):
                control.send(packet)

    try:
        site = spec.site_map()
        image = map_shared(spec.image_fd, spec.image_size, writable=True)
        scan = Scan(site, buffer=image, fresh=spec.fresh, retain_sink=send_retain, background=True)
    except (SiteMapError, RetainError) as exc:
        print(f"motion-server: {exc}", file=sys.stderr)
        return 2
    for ch in channels.values():
        scan.attach(ch)
    if spec.trend_fd >= 0:
        scan.attach_trend(map_ring(spec.trend_fd, spec.trend_size))
    priority = scan_policy()
    priority.follow(_realtime(scan.mode), scan.load)
    # the start-up heap (the whole system) is never scanned by the collector again, and
    # what is allocated later is collected between cycles (:mod:`.collector`)
    gc.collect()
    gc.freeze()
    collector = IdleCollector()
    collector.start()
    scan.start(time.monotonic())
    terminated = False
    while not scan.finished:
        if stop[0] and not terminated:
            terminated = True
            log.warning("SIGTERM: programmed stop of every group, then the scan ends")
            scan.request_stop()
        scan.writer.beat()
        wake = scan.service(time.monotonic())
        priority.follow(_realtime(scan.mode), scan.load)
        if scan.finished:
            break
        collector.between(None if wake is None else wake - time.monotonic())
        fds: list[int] = [wake_r, *(ch.fileno() for ch in scan.channels.values())]
        timeout = SCAN_BEAT if wake is None else min(SCAN_BEAT, max(0.0, wake - time.monotonic()))
        if timeout == 0.0:
            continue
        try:
            ready, _, _ = select.select(fds, [], [], timeout)
        except InterruptedError:
            continue
        if wake_r in ready:
            try:
                while os.read(wake_r, 512):
                    pass
            except BlockingIOError:
                pass
    # what the supervisor has not taken yet (the retained state, STOPPED): before exiting
    if control is not None:
        control.drain(DRAIN_TIMEOUT)
    collector.stop()
    log.info(
        "scan stopped (garbage collections between cycles: %d, the longest %.2f ms; forced "
        "without time left: %d)",
        collector.idle,
        collector.longest * 1e3,
        collector.forced,
    )
    return 0
