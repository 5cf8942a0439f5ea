"""The whole server in one process and one asyncio loop: tests, benches, tools.

``motion-server run`` runs the scan and the front-ends in processes of their own
(:mod:`.supervisor`). :class:`Runtime` connects the very same parts the very same way
(the shared image, the write queue, :class:`~.scan.Scan`, the front-ends with their
:class:`~.frontends.view.ImageView`) but runs the scan as a task on the caller's event
loop, so a test can step the clock, inspect the kernel and talk to the front-ends over
real sockets in one process::

    rt = Runtime(site)                 # the scan is built and its first image published
    rt.image.write("MSO_1.Execute", 1) # through the write queue, like a client
    rt.cycle(10)                       # ten cycles now (whatever the clock mode)
    rt.image.read("MSO_1.DN")          # from the published image
    await rt.serve()                   # the front-ends and the clock, until request_stop()

``rt.image`` is a front-end view of its own (the ``local`` channel): its writes are
judged like a client's and, with the manual clock, applied at once.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import signal
import socket
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from .config import SiteMap, opcua_users
from .frontends.link import Link, ScanLink, Ticket
from .frontends.modbus import ModbusFrontend
from .frontends.opcua import OpcUaFrontend
from .frontends.view import ImageView
from .image import wire
from .image.buffer import ImageReader
from .instructions import MotionSystem
from .kernel import Controller
from .safety.access import AccessPolicy, plain_role
from .safety.audit import AuditLog
from .safety.client import ClientInfo
from .scan import Scan
from .scan.channel import LOCAL, MODBUS, OPCUA, Channel
from .tagmap import ClockMode
from .tagmap.judge import Judge

log = logging.getLogger("motion_server.runtime")

__all__ = ["ClockMode", "Runtime"]


class _LocalChannel(Channel):
    """The scan's side of the runtime's own view: no socket, acknowledgements handed
    straight to the link."""

    def __init__(self, deliver: Callable[[bytes], None]) -> None:
        self.number = LOCAL
        self.name = "local"
        self.assembler = wire.BatchAssembler()
        self.outbox = deque()
        self.closed = False
        self.welcomed = True
        self.peer_pid = 0
        self._deliver = deliver

    def fileno(self) -> int:
        return -1

    def receive(self) -> list[bytes]:
        return []

    def send(self, packet: bytes) -> None:
        self._deliver(packet)

    def flush(self) -> None:
        return None


class _LocalLink:
    """The runtime view's link: a batch goes straight into the scan's queue; with the
    manual clock the scan applies it before :meth:`send` returns."""

    def __init__(self, runtime: Runtime) -> None:
        self._runtime = runtime
        self._seq = 0
        self._tickets: dict[int, Ticket] = {}
        self.channel = _LocalChannel(self._ack)
        self.broken = ""

    def send(self, items: list[tuple[int, float]], client: ClientInfo) -> Ticket:
        self._seq = (self._seq + 1) & 0xFFFFFFFF or 1
        ticket = Ticket(self._seq)
        self._tickets[ticket.seq] = ticket
        self._runtime.scan.deliver(self.channel, wire.Batch(ticket.seq, client, items))
        self._runtime._written()
        return ticket

    def _ack(self, packet: bytes) -> None:
        ack = wire.decode_ack(packet)
        ticket = self._tickets.pop(ack.seq, None)
        if ticket is not None:
            ticket._resolve(ack)


class Runtime:
    """One site's scan and front-ends on the running event loop (see the module)."""

    def __init__(
        self, site: SiteMap, system: MotionSystem | None = None, fresh: bool = False
    ) -> None:
        self.site = site
        self.scan = Scan(site, system, fresh=fresh)
        self.tagmap = self.scan.tagmap
        self.layout = self.scan.layout
        self._buffer = self.scan.writer._buf
        self.judge = Judge.for_system(self.tagmap, self.scan.system)
        #: the audit log of client writes (``[audit]``), None when off
        self.audit = AuditLog.from_config(site.audit, site.data_dir, lambda: self.ctl.tick)
        self._local = _LocalLink(self)
        self.scan.attach(self._local.channel)
        self.image = self._view(self._local, LOCAL)
        self.modbus: ModbusFrontend | None = None
        self.opcua: OpcUaFrontend | None = None
        #: set once the front-ends listen (``serve``)
        self.ready = asyncio.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._waiter: asyncio.Future[None] | None = None
        self._settled: asyncio.Event | None = None
        self._sockets: list[socket.socket] = []
        self.scan.start(0.0)

    def _view(self, link: Link | None, channel: int) -> ImageView:
        reader = ImageReader(self._buffer, self.layout.size, self.layout.fingerprint)
        view = ImageView(self.layout, reader, self.judge, link, channel)
        if self.audit is not None:
            view.observers.append(self.audit.accepted)
        return view

    # -- the scan ---------------------------------------------------------------------------
    @property
    def system(self) -> MotionSystem:
        """The controller and its instances (a restored snapshot replaces them)."""
        return self.scan.system

    @property
    def ctl(self) -> Controller:
        return self.scan.system.ctl

    @property
    def period(self) -> float:
        return self.ctl.period

    @property
    def cycle_count(self) -> int:
        return self.ctl.tick

    @property
    def sim_time(self) -> float:
        return self.ctl.time

    @property
    def mode(self) -> ClockMode:
        return self.scan.mode

    @property
    def scale(self) -> float:
        return self.scan.scale

    @scale.setter
    def scale(self, value: float) -> None:
        self.scan.scale = value
        self.scan._reschedule = True

    def __getattr__(self, name: str) -> Any:
        # the scan's diagnostics: overruns, dropped, heartbeat, max_cycle_time, load ...
        if name in _SCAN_COUNTERS:
            return getattr(self.scan, name)
        raise AttributeError(name)

    def cycle(self, count: int = 1) -> None:
        """Run ``count`` cycles now, whatever the clock mode (the queued writes first)."""
        self.scan.cycle(count)

    def set_mode(self, mode: ClockMode) -> None:
        self.scan.set_mode(mode)
        self._wake()

    def request_cycles(self, count: int) -> None:
        """Manual clock: run ``count`` more cycles (ignored in the other modes)."""
        self.scan.request_cycles(count)
        self._wake()

    async def settle(self) -> None:
        """Return once the cycles requested so far have run (or can no longer run)."""
        while self.scan._pending_cycles and not self.scan.finished:
            await asyncio.sleep(0.001)

    def request_stop(self) -> None:
        self.scan.request_stop()
        self._wake()

    def save_retained(self) -> None:
        self.scan.save_retained()

    def status_line(self) -> str:
        return self.scan.status_line()

    def _written(self) -> None:
        """A local write arrived: with the manual clock (or before serving) it applies now."""
        if self.scan.mode == ClockMode.MANUAL or self._loop is None:
            if self.scan.mode == ClockMode.MANUAL:
                self.scan.service(self._now())
            return
        self._wake()

    def _now(self) -> float:
        return self._loop.time() if self._loop is not None else 0.0

    # -- serving ----------------------------------------------------------------------------
    async def serve(self, modbus: bool | None = None, opcua: bool | None = None) -> None:
        """Run the clock with the front-ends of the site map around it until
        :meth:`request_stop` (then the programmed stop of every group); ``modbus`` and
        ``opcua`` override the site map's ``enabled`` of each front-end."""
        loop = asyncio.get_running_loop()
        self._loop = loop
        self.scan.rebase(loop.time(), loop.time)
        cfg = self.site.modbus
        task: asyncio.Task[None] | None = None
        links: list[ScanLink] = []
        try:
            task = asyncio.create_task(self._run(), name="scan")
            if cfg.enabled if modbus is None else modbus:
                view = await self._link(MODBUS, links)
                plain = plain_role(self.site, bool(opcua_users(self.site)))
                policy = AccessPolicy(cfg.access, self.tagmap, plain)
                self.modbus = ModbusFrontend(
                    view, cfg.host, cfg.port, cfg.unit_id, policy, self.audit, cfg.tls
                )
                await self.modbus.start()
            ucfg = self.site.opcua
            if ucfg.enabled if opcua is None else opcua:
                view = await self._link(OPCUA, links)
                self.opcua = OpcUaFrontend(view, ucfg, opcua_users(self.site), audit=self.audit)
                await self.opcua.start()
            self.ready.set()
            with frozen_heap():
                await task
        finally:
            if task is not None and not task.done():
                self.scan.request_stop()
                self._wake()
                with contextlib.suppress(Exception):
                    await task
            if self.opcua is not None:
                await self.opcua.stop()
            if self.modbus is not None:
                await self.modbus.stop()
            for link in links:
                link.close()
            for ch in list(self.scan.channels.values()):
                if ch.number != LOCAL:
                    with contextlib.suppress(ValueError, OSError):
                        loop.remove_reader(ch.fileno())
            for sock in self._sockets:
                sock.close()
            self._sockets.clear()
            if self.audit is not None:
                self.audit.close()
            self._loop = None

    async def _link(self, number: int, links: list[ScanLink]) -> ImageView:
        """A socket pair between the scan and a front-end, exactly as between processes."""
        assert self._loop is not None
        scan_end, fe_end = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self._sockets += [scan_end, fe_end]
        ch = Channel(scan_end, number)
        self.scan.attach(ch)
        self._loop.add_reader(ch.fileno(), self._wake)
        link = ScanLink(fe_end, number, self.layout.fingerprint)
        links.append(link)
        await link.connect()
        return self._view(link, number)

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        scan = self.scan
        while not scan.finished:
            wake = scan.service(loop.time())
            if scan.finished:
                break
            if wake is not None and wake <= loop.time():
                await asyncio.sleep(0)
                continue
            await self._sleep_until(wake)

    def _wake(self) -> None:
        """End the scan task's sleep now (a packet, a request, a stop)."""
        if self._waiter is not None and not self._waiter.done():
            self._waiter.set_result(None)

    async def _sleep_until(self, deadline: float | None) -> None:
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[None] = loop.create_future()
        self._waiter = fut
        timer = loop.call_at(deadline, _resolve, fut) if deadline is not None else None
        try:
            await fut
        finally:
            if timer is not None:
                timer.cancel()
            self._waiter = None

    def install_signal_handlers(self) -> None:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, self.request_stop)


_SCAN_COUNTERS = frozenset(
    {
        "overruns",
        "dropped",
        "heartbeat",
        "last_cycle_time",
        "max_cycle_time",
        "load",
        "queued_writes",
        "restarts",
        "writes_applied",
        "watchdogs",
        "retain_file",
        "version",
    }
)

_frozen_by = 0


@contextlib.contextmanager
def frozen_heap() -> Iterator[None]:
    """Keep the start-up heap out of the garbage collector while the loop runs.

    A served site holds several hundred thousand tracked objects (asyncua's address space
    alone is most of them); a full collection scans them all and stops the loop for
    hundreds of milliseconds. Frozen objects are never scanned; what the server allocates
    later is still collected. Nested uses (several runtimes in one process) unfreeze with
    the last.
    """
    global _frozen_by
    _frozen_by += 1
    gc.freeze()
    try:
        yield
    finally:
        _frozen_by -= 1
        if not _frozen_by:
            gc.unfreeze()


def _resolve(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)
