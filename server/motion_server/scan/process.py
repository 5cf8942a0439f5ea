"""The scan process: ``python -m motion_server.scan``, started by the supervisor.

It reads its :class:`~motion_server.launch.LaunchSpec` from standard input, maps the
shared image writable, builds the system and runs :meth:`Scan.service` in a ``select``
loop over its channels (the supervisor's control channel and one per front-end). It
imports no protocol stack (a test checks): nothing a client sends is parsed here, only
the judged batches front-ends forward.

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
from ..launch import LaunchSpec, setup_logging
from ..safety.retain import RetainError
from ..tagmap.fields import ClockMode
from .channel import CONTROL, Channel
from .core import LOAD_WINDOW, Scan

log = logging.getLogger("motion_server.scan")


#: the scan's scheduling priority (nice value) when the system allows raising it
SCAN_NICE = -10
#: seconds the scan waits, when it ends, for the supervisor to take what it still has to send
DRAIN_TIMEOUT = 5.0
#: the scan's load (% of each second busy) beyond which it leaves the real-time policy
OVERLOAD = 90.0
#: the scan's real-time priority (SCHED_FIFO, 1-99) while the clock runs in real time
SCAN_RT_PRIORITY = 10


class _Priority:
    """The operating system's scheduling of the scan, following the clock mode.

    While the clock follows the wall clock (realtime, scaled) the scan asks for SCHED_FIFO
    at priority :data:`SCAN_RT_PRIORITY`, as a controller's motion task runs: a waking
    cycle then preempts every ordinary process at once (front-ends, clients on the same
    machine), and the kernel's real-time throttling (``sched_rt_runtime_us``, 95 % by
    default) still leaves the machine to them should a cycle never end. In the manual and
    fast modes, where cycles run back to back on demand, it runs under the ordinary
    policy at nice :data:`SCAN_NICE`. Either needs root or CAP_SYS_NICE (a container
    without it, an unprivileged user): otherwise the scan keeps what it has, said once
    at DEBUG."""

    def __init__(self) -> None:
        self.realtime: bool | None = None
        self.demoted = False
        self._since = 0.0
        try:
            os.setpriority(os.PRIO_PROCESS, 0, SCAN_NICE)
        except OSError as exc:
            log.debug("scan priority unchanged: %s", exc)
        else:
            log.debug("scan priority raised (nice %d)", SCAN_NICE)

    def follow(self, mode: ClockMode, load: float) -> None:
        """Apply the policy for ``mode``. ``load``: the share of the last second the scan
        was busy (%). A scan busy beyond :data:`OVERLOAD` % cannot keep its period; as a
        real-time task it would leave the front-ends (on a machine of one core) almost
        no time to answer, so it goes back to the ordinary policy for good, said once."""
        settled = self.realtime and time.monotonic() - self._since > 2 * LOAD_WINDOW
        if load > OVERLOAD and settled and not self.demoted:
            self.demoted = True
            log.warning(
                "scan busy %.0f %% of the time (the cycle takes about as long as its "
                "period): it leaves the real-time scheduling policy so that clients are "
                "still served",
                load,
            )
        realtime = mode in (ClockMode.REALTIME, ClockMode.SCALED) and not self.demoted
        if realtime == self.realtime:
            return
        self.realtime = realtime
        self._since = time.monotonic()  # the load of the mode before is not this one's
        policy, priority = (os.SCHED_FIFO, SCAN_RT_PRIORITY) if realtime else (os.SCHED_OTHER, 0)
        try:
            os.sched_setscheduler(0, policy, os.sched_param(priority))
        except OSError as exc:
            if realtime:
                log.debug("scan keeps the ordinary scheduling policy: %s", exc)
        else:
            log.debug("scan scheduling: %s", "SCHED_FIFO" if realtime else "SCHED_OTHER")


def main() -> int:
    spec = LaunchSpec.read(sys.stdin.buffer)
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
        scan = Scan(site, buffer=image, fresh=spec.fresh, retain_sink=send_retain)
    except (SiteMapError, RetainError) as exc:
        print(f"motion-server: {exc}", file=sys.stderr)
        return 2
    for ch in channels.values():
        scan.attach(ch)
    priority = _Priority()
    priority.follow(scan.mode, scan.load)
    # the start-up heap (the whole system) is never scanned by the collector again
    gc.collect()
    gc.freeze()
    scan.start(time.monotonic())
    while not scan.finished:
        if stop[0]:
            scan.request_stop()
        wake = scan.service(time.monotonic())
        priority.follow(scan.mode, scan.load)
        if scan.finished:
            break
        fds: list[int] = [wake_r, *(ch.fileno() for ch in scan.channels.values())]
        timeout = None if wake is None else max(0.0, wake - time.monotonic())
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
    log.info("scan stopped")
    return 0
