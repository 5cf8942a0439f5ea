"""``motion-server run``: the scan and the front-ends, each in a process of its own.

The supervisor (this process) checks the site map, creates the shared image (an
anonymous ``memfd``) and one ``SOCK_SEQPACKET`` socket pair per channel, and starts:

1. the **scan** (``python -m motion_server.scan``): kernel, instructions, clock,
   watchdogs, retained state. It imports no protocol code;
2. once the scan says READY (the controller runs), the **front-ends**, one process per
   protocol (``python -m motion_server.frontends modbus|opcua``), so their ports open
   only when there is a controller behind them.

Then it watches them, for their exits and for their liveness (:mod:`.liveness`: the
scan's publish count and beat in the image, each front-end's beat on its standard
output), from the moment the scan runs, start-up included:

- a front-end that dies, or hangs (no beat for its limit: it is killed), is logged and
  started again (after 0.5 s, doubling to 30 s while it keeps dying within a minute of its
  start) on the same port, with the same channel to the scan, while motion goes on;
  clients reconnect. ``Diagnostics.FrontendRestarts`` counts the restarts;
- a scan that ends without being asked to (it died, or it ran its programmed stop
  because something else sent it SIGTERM) stops everything with one log line, exit 1;
- a scan that hangs (neither a cycle nor a beat for ``SCAN_HANG`` s) stops everything
  with one log line, exit 1: it is asked for its programmed stop, killed after
  ``SCAN_KILL_GRACE`` s, then the front-ends are stopped. What it might still send is
  not written: the retain file keeps what was last saved before the hang;
- the retained state is written only as the scan hands it over: a scan that dies or
  hangs leaves the file as it was;
- SIGINT or SIGTERM: the scan runs the programmed stop of every group, hands over the
  retained state, and ends; then the front-ends are stopped; exit 0.

The children die with the supervisor, however it ends (``launch.follow_supervisor``).

The supervisor also owns the files several processes feed: the audit log (the
front-ends send it their lines) and the retain file (the scan sends its payload).

With a ready file (``motion-server run --ready-file PATH``), once every front-end listens
it writes there, atomically, a JSON object for test benches and tools::

    {"format": "motion-server-ready/1", "pid": 4242, "site": "demo",
     "modbus": {"host": "127.0.0.1", "port": 5020, "tls_port": 0},
     "opcua": {"host": "127.0.0.1", "port": 4840, "endpoint": "opc.tcp://..."},
     "web": {"host": "127.0.0.1", "port": 8080, "url": "http://127.0.0.1:8080/"}}

(a protocol not served is absent), and removes it when the server begins to stop.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import selectors
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from .config import OpcUaUser, SiteMap, opcua_users
from .image import trend, wire
from .image.buffer import Progress, create_shared, image_bytes, map_shared
from .image.layout import ImageLayout
from .launch import LaunchSpec
from .liveness import FRONTEND_HANG, SCAN_HANG, SCAN_KILL_GRACE, Liveness
from .safety import retain
from .safety.audit import AuditLog
from .scan.channel import CONTROL, MODBUS, OPCUA, WEB
from .tagmap import build_tagmap

log = logging.getLogger("motion_server.supervisor")

#: seconds the scan may take to build the system and publish its first image
SCAN_START_TIMEOUT = 120.0
#: seconds a front-end may take to listen (OPC UA builds its address space first)
FRONTEND_START_TIMEOUT = 120.0
#: seconds a stopping process gets after SIGTERM before SIGKILL
TERMINATE_GRACE = 10.0
#: restart back-off of a front-end that keeps dying: first delay, the longest
RESTART_FIRST = 0.5
RESTART_LONGEST = 30.0
#: a front-end that ran this long before dying restarts with the first delay again
RESTART_RESET = 60.0
#: the ``format`` of the ready file
READY_FORMAT = "motion-server-ready/1"


class StartError(RuntimeError):
    """The server could not start (the reason is one line)."""


@dataclass
class _Child:
    """One process the supervisor started."""

    role: str  # "scan", "modbus", "opcua", "web"
    proc: subprocess.Popen[bytes]
    started: float
    listening: dict[str, Any] = field(default_factory=dict)
    buffer: bytes = b""
    failed: str = ""
    #: why the supervisor killed it ("": it was not killed for hanging)
    hung: str = ""

    @property
    def stdout(self) -> IO[bytes]:
        assert self.proc.stdout is not None
        return self.proc.stdout


def _describe(returncode: int) -> str:
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exit code {returncode}"


class Supervisor:
    """Runs one site map; :meth:`run` returns the process exit code."""

    def __init__(
        self,
        site: SiteMap,
        log_level: str = "INFO",
        fresh: bool = False,
        modbus: bool | None = None,
        opcua: bool | None = None,
        users: list[OpcUaUser] | None = None,
        web: bool | None = None,
        ready_file: Path | None = None,
    ) -> None:
        self.site = site
        self.log_level = log_level
        self.fresh = fresh
        self.roles: dict[str, int] = {}
        if site.modbus.enabled if modbus is None else modbus:
            self.roles["modbus"] = MODBUS
        if site.opcua.enabled if opcua is None else opcua:
            self.roles["opcua"] = OPCUA
        if site.web.enabled if web is None else web:
            self.roles["web"] = WEB
        self.layout = ImageLayout(build_tagmap(site))
        self.size = image_bytes(self.layout.size)
        if "opcua" not in self.roles and "web" not in self.roles:
            self.users: list[OpcUaUser] = []
        else:
            self.users = opcua_users(site) if users is None else users
        self.ready_file = ready_file
        self._ready_written = False
        self.audit = AuditLog.from_config(site.audit, site.data_dir, lambda: 0)
        self.retain_file = retain.retain_path(site) if site.retain.enabled else None
        self.restarts = 0
        self._generation: dict[str, int] = {}
        self._delay: dict[str, float] = {}
        self._children: dict[str, _Child] = {}
        self._due: dict[str, float] = {}
        self._ports: dict[str, dict[str, Any]] = {}
        self._selector = selectors.DefaultSelector()
        self._stopping = False
        self._scan_stopped = False
        self._retain_parts: list[bytes] = []
        #: False once the scan hung: what it hands over afterwards is not written
        self._retain_trusted = True
        self._signal_r, self._signal_w = os.pipe()
        self._live = Liveness()
        self._progress: Progress | None = None
        self._marker = (0, 0)
        self._serving = False

    # -- start ------------------------------------------------------------------------------
    def run(self) -> int:
        for fd in (self._signal_r, self._signal_w):
            os.set_blocking(fd, False)
        previous = signal.set_wakeup_fd(self._signal_w)
        handlers = {
            sig: signal.signal(sig, lambda *_: None) for sig in (signal.SIGINT, signal.SIGTERM)
        }
        self._selector.register(self._signal_r, selectors.EVENT_READ, "signal")
        try:
            return self._run()
        except StartError as exc:
            log.error("%s", exc)
            self._stop_all()
            return 1
        finally:
            self._remove_ready()
            signal.set_wakeup_fd(previous)
            for sig, handler in handlers.items():
                signal.signal(sig, handler)
            if self.audit is not None:
                self.audit.close()

    def _run(self) -> int:
        if self.retain_file is not None and not self.fresh:
            # refuse a bad retain file here, in one line, before anything starts
            retain.load(self.retain_file, self.site.site.name)
        self.image_fd = create_shared(self.size)
        # the web view's trend ring: the scan writes every cycle's trended values there
        self.trend_fd, self.trend_size = -1, 0
        if "web" in self.roles:
            self.trend_size = trend.ring_bytes()
            self.trend_fd = create_shared(self.trend_size)
        # read-only: what shows that the scan works (its publish count and its beat)
        self._progress = Progress(map_shared(self.image_fd, self.size, writable=False))
        self.control, scan_control = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.control.setblocking(False)
        self._fe_ends: dict[str, socket.socket] = {}
        scan_fds = {CONTROL: scan_control.fileno()}
        scan_socks = [scan_control]
        for role, number in self.roles.items():
            scan_end, fe_end = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
            self._fe_ends[role] = fe_end
            scan_fds[number] = scan_end.fileno()
            scan_socks.append(scan_end)
        spec = LaunchSpec.build(
            self.site,
            self.log_level,
            self.image_fd,
            self.size,
            scan_fds,
            fresh=self.fresh,
            supervisor=os.getpid(),
            trend_fd=self.trend_fd,
            trend_size=self.trend_size,
        )
        scan = self._spawn("scan", [sys.executable, "-m", "motion_server.scan"], spec)
        for sock in scan_socks:  # the scan holds them now
            sock.close()
        self._selector.register(self.control, selectors.EVENT_READ, "control")
        if not self._wait_ready(scan):
            code = scan.proc.poll()
            if code is not None and code < 0:  # killed by a signal (said in one line)
                return 1
            return code if code else (0 if self._stopping else 1)
        for role in self.roles:
            self._start_frontend(role)
        code = self._wait_listening()
        if code is not None:
            return code
        self._serving = True
        self._write_ready()
        return self._watch()

    def _spawn(self, role: str, argv: list[str], spec: LaunchSpec) -> _Child:
        fds = [self.image_fd, *spec.channels.values()]
        if spec.trend_fd >= 0:
            fds.append(spec.trend_fd)
        proc = subprocess.Popen(
            argv,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE if role != "scan" else subprocess.DEVNULL,
            pass_fds=fds,
        )
        assert proc.stdin is not None
        proc.stdin.write(spec.encode())
        proc.stdin.flush()  # left open: the child's lifeline
        child = _Child(role, proc, time.monotonic())
        self._children[role] = child
        if proc.stdout is not None:
            os.set_blocking(proc.stdout.fileno(), False)
            self._selector.register(proc.stdout, selectors.EVENT_READ, role)
        return child

    def _start_frontend(self, role: str) -> None:
        generation = self._generation.get(role, 0)
        self._generation[role] = generation + 1
        site = self.site
        port = self._ports.get(role, {})
        if port:  # a restart: the port it had (an ephemeral one included)
            if role == "modbus":
                modbus = site.modbus.model_copy(update={"port": port.get("port", 0)})
                tls = site.modbus.tls
                if port.get("tls_port"):
                    tls = tls.model_copy(update={"port": port["tls_port"]})
                site = site.model_copy(update={"modbus": modbus.model_copy(update={"tls": tls})})
            elif role == "web":
                web = site.web.model_copy(update={"port": port.get("port", 0)})
                site = site.model_copy(update={"web": web})
            else:
                opcua = site.opcua.model_copy(update={"port": port.get("port", 0)})
                site = site.model_copy(update={"opcua": opcua})
        fe_end = self._fe_ends[role]
        spec = LaunchSpec.build(
            site,
            self.log_level,
            self.image_fd,
            self.size,
            {self.roles[role]: fe_end.fileno()},
            users=self.users if role in ("opcua", "web") else None,
            generation=generation,
            supervisor=os.getpid(),
            **({"trend_fd": self.trend_fd, "trend_size": self.trend_size} if role == "web" else {}),
        )
        self._spawn(role, [sys.executable, "-m", "motion_server.frontends", role], spec)
        if self._serving:  # a restart: it must listen in time as well (then beat)
            self._live.watch(role, FRONTEND_START_TIMEOUT, time.monotonic())

    def _wait_ready(self, scan: _Child) -> bool:
        """Until the scan says READY; False when it exited or a signal came first."""
        give_up = time.monotonic() + SCAN_START_TIMEOUT
        while time.monotonic() < give_up:
            for kind in self._poll(0.2):
                if kind == wire.Kind.READY:
                    self._live.watch("scan", SCAN_HANG, time.monotonic())
                    return True
            if self._stopping:
                self._stop_all()
                return False
            if scan.proc.poll() is not None:
                log.error("the scan process could not start (%s)", _describe(scan.proc.returncode))
                return False
        raise StartError(f"the scan did not start within {SCAN_START_TIMEOUT:.0f} s")

    def _wait_listening(self) -> int | None:
        """Until every front-end listens (None). One that reports it cannot serve (a port
        in use) stops the server; one that dies otherwise is started again, as later. A
        scan that ends or hangs meanwhile stops it too. Else the exit code."""
        give_up = time.monotonic() + FRONTEND_START_TIMEOUT
        while time.monotonic() < give_up:
            self._poll(0.2)
            failed = [c for c in self._children.values() if c.failed]
            for c in [c for c in failed if c.role == "web"]:
                self._without_web(c)
            failed = [c for c in failed if c.role != "web"]
            if failed or self._stopping:
                asked = self._stopping
                for c in failed:
                    log.error("motion-server: cannot serve %s: %s", c.role, c.failed)
                self._stop_all()
                return 0 if asked and not failed and self._scan_clean() else 1
            code = self._look()
            if code is not None:
                return code
            self._reap_frontends()
            now = time.monotonic()
            for role, when in list(self._due.items()):
                if now >= when:
                    del self._due[role]
                    self._start_frontend(role)
            children = [self._children.get(r) for r in self.roles]
            if all(c is not None and c.listening for c in children):
                log.info("serving: %s", self._where())
                return None
        raise StartError(f"the front-ends did not listen within {FRONTEND_START_TIMEOUT:.0f} s")

    def _without_web(self, child: _Child) -> None:
        """The web view could not start (its port in use, a certificate file): one line,
        and the server goes on without it. A viewer is not what PLCs and panels command
        the controller through; a port taken on a shared host must not stop motion."""
        log.error("motion-server: the web view cannot serve: %s; serving without it", child.failed)
        del self.roles["web"]
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.proc.wait(TERMINATE_GRACE)
        if child.proc.poll() is None:
            child.proc.kill()
            child.proc.wait()
        self._drop(child)

    def _where(self) -> str:
        parts = []
        for role, msg in self._ports.items():
            if role == "modbus":
                if msg.get("port"):
                    parts.append(f"Modbus TCP port {msg['port']}")
                if msg.get("tls_port"):
                    parts.append(f"Modbus/TCP Security port {msg['tls_port']}")
            elif role == "web":
                parts.append(f"web view {msg.get('url', '')}")
            else:
                parts.append(f"OPC UA {msg.get('endpoint', '')}")
        return ", ".join(parts) or "no front-end"

    # -- watch ------------------------------------------------------------------------------
    def _watch(self) -> int:
        while True:
            timeout = 0.5
            if self._due:
                timeout = max(0.0, min(0.5, min(self._due.values()) - time.monotonic()))
            self._poll(timeout)
            if self._stopping and not self._stop_sent:
                self._send_stop()
            code = self._look()
            if code is not None:
                return code
            self._reap_frontends()
            now = time.monotonic()
            for role, when in list(self._due.items()):
                if now >= when and not self._stopping:
                    del self._due[role]
                    self._start_frontend(role)

    def _look(self) -> int | None:
        """One look at every process, after a poll: the scan first (its end or its hang
        ends the server: then every process is stopped and the exit code returned), then
        the front-ends (a hung one is killed here and restarted by the next reap)."""
        scan = self._children["scan"]
        hung = self._hung()
        if scan.proc.poll() is not None or self._scan_stopped:
            return self._scan_ended(scan)
        if "scan" in hung:
            return self._scan_hung(scan, hung.pop("scan"))
        if not self._stopping:
            for role, silent in hung.items():
                self._kill_hung(role, silent)
        return None

    def _hung(self) -> dict[str, float]:
        """Process -> seconds silent, of those silent beyond their limit."""
        now = time.monotonic()
        if self._progress is not None:
            marker = self._progress.marker()
            if marker != self._marker:
                self._marker = marker
                self._live.seen("scan", now)
        return dict(self._live.hung(now))

    def _scan_ended(self, scan: _Child) -> int:
        """The scan exited, or said STOPPED and is exiting: 0 when it was asked to stop
        and stopped cleanly; else one line and 1. Every process is stopped."""
        self._live.forget("scan")
        give_up = time.monotonic() + TERMINATE_GRACE
        while scan.proc.poll() is None and time.monotonic() < give_up:
            self._poll(0.1)  # its last packets (the retained state, STOPPED) are read
        if scan.proc.poll() is None:
            scan.proc.kill()
        code = scan.proc.wait()
        # its last packets may still be unread: it can exit between a poll and the check
        self._on_control()
        clean = self._scan_stopped or code == 0
        if self._stopping and clean:
            self._stop_frontends()
            log.info("stopped")
            return 0
        if clean:
            log.error(
                "the scan process stopped without being asked to (%s; a SIGTERM sent to it "
                "runs the programmed stop): motion has stopped; stopping the server",
                _describe(code),
            )
        else:
            log.error(
                "the scan process died (%s): motion has stopped; stopping the server",
                _describe(code),
            )
        self._stop_frontends()
        return 1

    def _scan_hung(self, scan: _Child, silent: float) -> int:
        """A scan that shows no progress: one line, a programmed stop asked for (it may
        still run one), killed after the grace, the front-ends stopped; 1."""
        log.error(
            "the scan process hung (no cycle and no heartbeat for %.1f s): motion has "
            "stopped; stopping the server (it is killed if it does not stop within %.0f s)",
            silent,
            SCAN_KILL_GRACE,
        )
        self._live.forget("scan")
        self._retain_trusted = False
        self._stopping = True
        self._remove_ready()
        if not self._stop_sent:
            self._send_stop()
        give_up = time.monotonic() + SCAN_KILL_GRACE
        while scan.proc.poll() is None and time.monotonic() < give_up:
            self._poll(0.1)
        if scan.proc.poll() is None:
            scan.proc.kill()
            scan.proc.wait()
        self._stop_frontends()
        return 1

    def _scan_clean(self) -> bool:
        """The scan has ended after its programmed stop (not killed, not hung)."""
        scan = self._children.get("scan")
        code = None if scan is None else scan.proc.poll()
        return self._retain_trusted and (self._scan_stopped or code == 0)

    def _kill_hung(self, role: str, silent: float) -> None:
        """A front-end that stands still: killed (SIGKILL: a loop that does not run does
        not handle SIGTERM); the next reap restarts it like one that died."""
        self._live.forget(role)
        child = self._children.get(role)
        if child is None or child.proc.poll() is not None:
            return
        if child.listening:
            child.hung = f"hung (no heartbeat for {silent:.1f} s) and was killed"
        else:
            child.hung = f"did not listen within {silent:.0f} s and was killed"
        child.proc.kill()
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.proc.wait(2.0)  # at once, unless it is stuck in the kernel

    _stop_sent = False

    def _send_stop(self) -> None:
        self._stop_sent = True
        try:
            self.control.send(wire.encode_simple(wire.Kind.STOP))
        except OSError:
            scan = self._children.get("scan")
            if scan is not None and scan.proc.poll() is None:
                scan.proc.terminate()

    def _reap_frontends(self) -> None:
        for role in list(self.roles):
            child = self._children.get(role)
            if child is None or child.proc.poll() is None:
                continue
            self._drop(child)
            lived = time.monotonic() - child.started
            if self._stopping:
                continue
            delay = self._delay.get(role, RESTART_FIRST)
            if lived > RESTART_RESET:
                delay = RESTART_FIRST
            self._delay[role] = min(delay * 2, RESTART_LONGEST)
            self.restarts += 1
            log.error(
                "the %s front-end %s: restarting it in %.1f s; motion goes on",
                role,
                child.hung or f"died ({_describe(child.proc.returncode)})",
                delay,
            )
            self._due[role] = time.monotonic() + delay
            with contextlib.suppress(OSError):
                self.control.send(wire.encode_count(wire.Kind.RESTARTS, self.restarts))

    def _drop(self, child: _Child) -> None:
        del self._children[child.role]
        self._live.forget(child.role)
        if child.proc.stdout is not None:
            with contextlib.suppress(KeyError, ValueError):
                self._selector.unregister(child.proc.stdout)
            child.proc.stdout.close()
        if child.proc.stdin is not None:
            with contextlib.suppress(OSError):
                child.proc.stdin.close()

    def _poll(self, timeout: float) -> list[wire.Kind]:
        """Wait up to ``timeout`` for signals, the scan's packets and the children's
        lines; returns the kinds of the control packets that came."""
        kinds: list[wire.Kind] = []
        for key, _ in self._selector.select(timeout):
            what = key.data
            if what == "signal":
                self._on_signal()
            elif what == "control":
                kinds += self._on_control()
            else:
                self._on_child_output(what)
        return kinds

    def _on_signal(self) -> None:
        try:
            while os.read(self._signal_r, 512):
                pass
        except BlockingIOError:
            pass
        if not self._stopping:
            log.info("stop requested: programmed stop of every group")
            self._stopping = True
            self._remove_ready()

    def _on_control(self) -> list[wire.Kind]:
        kinds: list[wire.Kind] = []
        while True:
            try:
                data = self.control.recv(1 << 16)
            except BlockingIOError:
                return kinds
            except OSError:
                data = b""
            if not data:
                with contextlib.suppress(KeyError, ValueError):  # read to the end before
                    self._selector.unregister(self.control)
                return kinds
            try:
                kind, flags, _ = wire.header(data)
            except wire.WireError as exc:
                log.warning("control channel: %s", exc)
                continue
            kinds.append(kind)
            if kind == wire.Kind.RETAIN:
                self._retain_parts.append(data[8:])
                if flags & wire.FINAL:
                    self._write_retain(b"".join(self._retain_parts))
                    self._retain_parts = []
            elif kind == wire.Kind.STOPPED:
                self._scan_stopped = True
                self._live.forget("scan")  # only its exit is still to come

    def _write_retain(self, blob: bytes) -> None:
        if self.retain_file is None:
            return
        if not self._retain_trusted:
            log.warning("retain: the state a hung scan handed over is not written")
            return
        try:
            payload = json.loads(blob)
            retain.save(self.retain_file, payload)
        except (OSError, ValueError) as exc:
            log.error("retain: cannot write %s: %s", self.retain_file, exc)

    def _on_child_output(self, role: str) -> None:
        child = self._children.get(role)
        if child is None:
            return
        try:
            data = child.stdout.read()
        except (BlockingIOError, OSError):
            data = None
        if data is None:
            return
        self._live.seen(role, time.monotonic())  # a line, or part of one: its loop runs
        if not data:  # end of file: the child is exiting
            with contextlib.suppress(KeyError, ValueError):
                self._selector.unregister(child.stdout)
            return
        child.buffer += data
        *lines, child.buffer = child.buffer.split(b"\n")
        for raw in lines:
            try:
                msg = json.loads(raw)
            except ValueError:
                continue
            if "audit" in msg and self.audit is not None:
                self.audit.write_line(str(msg["audit"]))
            elif "listening" in msg:
                child.listening = msg
                self._ports[role] = msg
                self._live.watch(role, FRONTEND_HANG[role], time.monotonic())
            elif "failed" in msg:
                child.failed = str(msg.get("reason", "failed"))

    # -- the ready file ---------------------------------------------------------------------
    def _write_ready(self) -> None:
        """Every front-end listens: say where, atomically (a file renamed into place)."""
        if self.ready_file is None:
            return
        info: dict[str, Any] = {
            "format": READY_FORMAT,
            "pid": os.getpid(),
            "site": self.site.site.name,
        }
        if "modbus" in self.roles:
            at = self._ports.get("modbus", {})
            info["modbus"] = {
                "host": self.site.modbus.host,
                "port": int(at.get("port", 0)),
                "tls_port": int(at.get("tls_port", 0)),
            }
        if "opcua" in self.roles:
            at = self._ports.get("opcua", {})
            info["opcua"] = {
                "host": self.site.opcua.host,
                "port": int(at.get("port", 0)),
                "endpoint": str(at.get("endpoint", "")),
            }
        if "web" in self.roles:
            at = self._ports.get("web", {})
            info["web"] = {
                "host": self.site.web.host,
                "port": int(at.get("port", 0)),
                "url": str(at.get("url", "")),
            }
        path = self.ready_file
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            tmp.write_text(json.dumps(info, indent=2) + "\n", "utf-8")
            os.replace(tmp, path)
        except OSError as exc:
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise StartError(f"cannot write the ready file {path}: {exc.strerror or exc}") from None
        self._ready_written = True
        log.info("ready: %s", path)

    def _remove_ready(self) -> None:
        if self._ready_written and self.ready_file is not None:
            self._ready_written = False
            with contextlib.suppress(FileNotFoundError):
                self.ready_file.unlink()

    # -- stop -------------------------------------------------------------------------------
    def _stop_frontends(self) -> None:
        self._stopping = True
        frontends = [c for r, c in self._children.items() if r != "scan"]
        for c in frontends:
            if c.proc.poll() is None:
                c.proc.terminate()
        self._wait_children(frontends)

    def _stop_all(self) -> None:
        self._stopping = True
        scan = self._children.get("scan")
        if scan is not None and scan.proc.poll() is None:
            self._send_stop()
            give_up = time.monotonic() + TERMINATE_GRACE * 3
            while scan.proc.poll() is None and time.monotonic() < give_up:
                self._poll(0.1)
                hung = self._hung()
                if "scan" in hung:  # it does not run its programmed stop: no use waiting
                    self._scan_hung(scan, hung["scan"])
        self._stop_frontends()
        self._wait_children(list(self._children.values()))

    def _wait_children(self, children: list[_Child]) -> None:
        give_up = time.monotonic() + TERMINATE_GRACE
        for c in children:
            try:
                c.proc.wait(max(0.0, give_up - time.monotonic()))
            except subprocess.TimeoutExpired:
                log.warning("the %s process did not stop: killed", c.role)
                c.proc.kill()
                c.proc.wait()
            if c.proc.stdin is not None:
                with contextlib.suppress(OSError):
                    c.proc.stdin.close()
