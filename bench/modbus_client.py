"""Shared by the benchmarks: a minimal blocking Modbus TCP client on a raw socket (so that
the client costs little next to the server), starting and stopping a server process, and
what a server costs, measured over its whole process tree.

``motion-server run`` is a supervisor with children (the scan, one front-end per
protocol): its CPU time, memory and descriptors are sums over the supervisor and every
descendant (:func:`process_tree` reads ``/proc/<pid>/task/<tid>/children``
recursively). CPU time includes the children a process has already reaped (a front-end
that died and was restarted), through the ``cutime``/``cstime`` fields of /proc.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from motion_server.tagmap import TagMap, TagType, decode, encode
from motion_server.tagmap.codec import Value

MODBUS_PORT = r"Modbus TCP on [\d.]+:(\d+)"
OPCUA_ENDPOINT = r"OPC UA on (opc\.tcp://[\d.]+:\d+/)"


class RawClient:
    """FC3 / FC6 / FC16 over one TCP connection, one request in flight."""

    def __init__(self, port: int, unit: int = 1, timeout: float | None = None) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.unit = unit
        self.tid = 0

    def _call(self, pdu: bytes, answer: int) -> bytes:
        self.tid = (self.tid + 1) & 0xFFFF
        self.sock.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, self.unit) + pdu)
        want = 7 + answer
        buf = b""
        while len(buf) < 9:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("the server closed the connection")
            buf += chunk
        if buf[7] & 0x80:
            raise RuntimeError(f"Modbus exception {buf[8]}")
        while len(buf) < want:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("the server closed the connection")
            buf += chunk
        return buf[7:want]

    def read(self, address: int, count: int) -> list[int]:
        pdu = self._call(struct.pack(">BHH", 3, address, count), 2 + 2 * count)
        return list(struct.unpack(f">{count}H", pdu[2:]))

    def write(self, address: int, value: int) -> None:
        self._call(struct.pack(">BHH", 6, address, value), 5)

    def write_many(self, address: int, values: list[int]) -> None:
        n = len(values)
        body = struct.pack(f">BHHB{n}H", 16, address, n, 2 * n, *values)
        self._call(body, 5)

    def close(self) -> None:
        self.sock.close()


class TagClient:
    """Tags by name over a :class:`RawClient` (the map's default big word order)."""

    def __init__(self, port: int, tagmap: TagMap, timeout: float | None = None) -> None:
        self.raw = RawClient(port, timeout=timeout)
        self.tagmap = tagmap

    def read(self, name: str) -> Value:
        tag = self.tagmap.tag(name)
        regs = self.raw.read(tag.address, tag.count)
        if tag.type == TagType.BOOL:
            return bool(regs[0] >> (tag.bit or 0) & 1)
        return decode(tag.type, regs)

    def write(self, name: str, value: Value) -> None:
        """A BOOL is written as its whole register (the other bits 0: command bits)."""
        tag = self.tagmap.tag(name)
        if tag.type == TagType.BOOL:
            self.raw.write(tag.address, (1 << (tag.bit or 0)) if value else 0)
        else:
            self.raw.write_many(tag.address, encode(tag.type, value))

    def close(self) -> None:
        self.raw.close()


# -- a server process -------------------------------------------------------------------------
class ServerProcess:
    """A server started as a user starts it, its standard error in a log file (read to
    find the port it bound; never a pipe, which would fill up and stall the server).

    ``found``: the first group of ``pattern`` in the log (the port, or the endpoint)."""

    def __init__(
        self,
        args: list[str],
        pattern: str = MODBUS_PORT,
        log: Path | None = None,
        cwd: Path | None = None,
        timeout: float = 300.0,
    ) -> None:
        if log is None:
            fd, name = tempfile.mkstemp(prefix="bench-server-", suffix=".log")
            os.close(fd)
            log = Path(name)
        self.log_path = log
        with log.open("wb") as f:
            self.proc = subprocess.Popen(
                [sys.executable, *args],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=f,
                cwd=cwd,
            )
        self.pid = self.proc.pid
        self.found = self.wait_for(pattern, timeout)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_for(self, pattern: str, timeout: float = 300.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = re.search(pattern, self.log())
            if m:
                return m.group(1)
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        self.kill()
        raise RuntimeError(f"the server did not log {pattern!r}:\n{self.log()[-3000:]}")

    @property
    def port(self) -> int:
        return int(self.found.rsplit(":", 1)[-1].strip("/"))

    def tree(self) -> list[int]:
        return process_tree(self.pid)

    def cpu(self) -> float:
        return cpu_seconds(self.pid)

    def stop(self, timeout: float = 30.0) -> int:
        """SIGTERM (motion-server: the programmed stop, then exit 0); SIGKILL after
        ``timeout``. Returns the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        return self.proc.returncode

    def kill(self) -> None:
        """SIGKILL to the whole tree (children first are orphaned otherwise)."""
        for pid in reversed(self.tree()):
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        self.proc.wait()


def start_server(args: list[str], pattern: str = MODBUS_PORT) -> tuple[ServerProcess, int]:
    """Start a server process and return it with the port it logged."""
    server = ServerProcess(args, pattern)
    return server, server.port


def stop_server(server: ServerProcess) -> None:
    server.stop()


# -- what a process tree costs ----------------------------------------------------------------
def children(pid: int) -> list[int]:
    """The direct children of ``pid`` (every thread's, Linux /proc)."""
    out: list[int] = []
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tasks:
        try:
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                out += [int(p) for p in f.read().split()]
        except OSError:
            continue
    return out


def process_tree(pid: int) -> list[int]:
    """``pid`` and all its live descendants, parents before their children."""
    out = [pid]
    i = 0
    while i < len(out):
        out += children(out[i])
        i += 1
    return out


def _stat_fields(pid: int) -> list[str]:
    with open(f"/proc/{pid}/stat") as f:
        return f.read().rsplit(")", 1)[1].split()


def own_cpu_seconds(pid: int) -> float:
    """User + system CPU time of one process so far, with its reaped children's."""
    try:
        fields = _stat_fields(pid)
    except OSError:
        return 0.0  # gone meanwhile
    ticks = sum(int(fields[k]) for k in (11, 12, 13, 14))  # utime stime cutime cstime
    return ticks / os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """CPU time of ``pid`` and its descendants so far (the supervisor and its children)."""
    return sum(own_cpu_seconds(p) for p in process_tree(pid))


def role(pid: int) -> str:
    """What a process of a motion-server tree is: "scan", "modbus", "opcua" (front-ends),
    or its command's last word (the supervisor: "run" or the site map)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = [a.decode(errors="replace") for a in f.read().split(b"\0") if a]
    except OSError:
        return "gone"
    if "motion_server.scan" in argv:
        return "scan"
    if "motion_server.frontends" in argv:
        i = argv.index("motion_server.frontends")
        return argv[i + 1] if i + 1 < len(argv) else "front-end"
    if "motion_server.cli" in argv:
        return "supervisor"
    return Path(argv[-1]).name if argv else str(pid)


def cpu_by_role(pid: int) -> dict[str, float]:
    """CPU seconds so far of each process of the tree, by :func:`role`."""
    out: dict[str, float] = {}
    for p in process_tree(pid):
        name = role(p)
        out[name] = out.get(name, 0.0) + own_cpu_seconds(p)
    return out


def rss_kib(pid: int) -> int:
    """Resident memory of ``pid`` and its descendants (KiB, summed)."""
    total = 0
    for p in process_tree(pid):
        try:
            with open(f"/proc/{p}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        total += int(line.split()[1])
                        break
        except OSError:
            continue
    return total


def open_fds(pid: int) -> dict[str, str]:
    """Open descriptors of ``pid`` and its descendants: ``"<pid>:<fd>"`` -> target."""
    out: dict[str, str] = {}
    for p in process_tree(pid):
        try:
            fds = os.listdir(f"/proc/{p}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                out[f"{p}:{fd}"] = os.readlink(f"/proc/{p}/fd/{fd}")
            except OSError:
                continue
    return out


def percentile(samples: list[float], q: float) -> float:
    s = sorted(samples)
    return s[min(len(s) - 1, int(q * len(s)))]


def load_average() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())
