"""``motion-server probe``: readiness and liveness of a running server, for an orchestrator.

A Kubernetes exec probe (or any supervisor) runs this inside the server's container, next
to ``motion-server run --ready-file PATH``. Both checks start from the ready file the
server writes once every front-end listens and removes when it begins to stop
(docs/container.md):

- ``--ready``: the ready file exists and names this format, its process is alive, and
  every port it lists (Modbus, Modbus/TCP Security, OPC UA, and whatever later front-end
  adds an entry with a ``port``) accepts a TCP connection on the loopback address. A
  server that starts or stops is therefore not ready, as ``Diagnostics.Ready`` says.
- ``--live``: the scan works. The supervisor's shared image (an anonymous memory file
  the server process holds open) carries two counters: the publish count, one per cycle,
  and the scan's beat, one per pass of its loop, idle included. Read twice ``--interval``
  seconds apart, one of them must have moved: the cycle counter in every clock mode
  where time runs, the beat with the manual clock, where cycles run only when a client
  asks for them and an idle controller is not a hung one (docs/deployment.md). It reads
  the supervisor's own evidence (:class:`~motion_server.image.buffer.Progress`), over no
  network and with no tag map, so the probe costs a few tens of milliseconds of CPU, not
  the seconds of a Modbus client that first loads the map.

Exit status 0 when the check passes, 1 otherwise, with one line on standard error naming
what failed (never a traceback). This module imports only the standard library and the
image layout, so that a probe every few seconds does not take the scan's CPU.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import mmap
import os
import socket
import sys
import time
from pathlib import Path
from typing import Any

from .image.buffer import CONTROL_WORDS, MAGIC, Progress

#: the ``format`` of the ready file this probe understands (supervisor.READY_FORMAT)
READY_FORMAT = "motion-server-ready/1"
#: the link name of the shared image's memory file (image.buffer.create_shared)
IMAGE_LINK = "/memfd:motion-server-image"
#: default seconds between the two reads of ``--live``: two beats of an idle scan
#: (liveness.SCAN_BEAT is 0.25 s)
LIVE_INTERVAL = 0.6
#: default seconds a port may take to accept a connection
CONNECT_TIMEOUT = 2.0


class ProbeFailed(Exception):
    """The server is not ready, or not live (the message says why, in one line)."""


def read_ready(path: Path) -> dict[str, Any]:
    """The ready file's content, checked for its format and a live process."""
    try:
        text = path.read_text("utf-8")
    except FileNotFoundError:
        raise ProbeFailed(f"no ready file {path}: the server starts or stops") from None
    except OSError as exc:
        raise ProbeFailed(f"cannot read the ready file {path}: {exc.strerror or exc}") from None
    try:
        info = json.loads(text)
    except ValueError:
        raise ProbeFailed(f"the ready file {path} is not JSON") from None
    if not isinstance(info, dict) or info.get("format") != READY_FORMAT:
        raise ProbeFailed(f"the ready file {path} is not in the format {READY_FORMAT}")
    pid = info.get("pid")
    if not isinstance(pid, int) or pid <= 0:
        raise ProbeFailed(f"the ready file {path} names no process")
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        raise ProbeFailed(f"the server process {pid} of {path} is gone") from None
    except PermissionError:
        pass  # it exists, under another user
    return info


def listed_ports(info: dict[str, Any]) -> list[tuple[str, int]]:
    """(what, port) of every port the ready file lists: each protocol's ``port`` and
    ``tls_port`` (0 means not served)."""
    ports: list[tuple[str, int]] = []
    for role, entry in sorted(info.items()):
        if not isinstance(entry, dict):
            continue
        for key in ("port", "tls_port"):
            port = entry.get(key)
            if isinstance(port, int) and 0 < port < 65536:
                ports.append((role if key == "port" else f"{role} TLS", port))
    return ports


def check_ready(path: Path, timeout: float = CONNECT_TIMEOUT) -> str:
    """Raise :class:`ProbeFailed` unless the server is ready; else say what was checked."""
    info = read_ready(path)
    ports = listed_ports(info)
    for what, port in ports:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=timeout):
                pass
        except OSError as exc:
            reason = exc.strerror or type(exc).__name__
            raise ProbeFailed(
                f"{what} port {port} does not accept connections ({reason})"
            ) from None
    listing = ", ".join(f"{what} {port}" for what, port in ports) or "no port"
    return f"ready: {info.get('site', '?')} (pid {info['pid']}), listening: {listing}"


def open_image(pid: int) -> mmap.mmap:
    """Map, read-only, the shared image that process ``pid`` holds open."""
    fd_dir = Path(f"/proc/{pid}/fd")
    try:
        entries = sorted(fd_dir.iterdir())
    except OSError as exc:
        raise ProbeFailed(f"cannot list {fd_dir}: {exc.strerror or exc}") from None
    for entry in entries:
        try:
            if not os.readlink(entry).startswith(IMAGE_LINK):
                continue
            fd = os.open(entry, os.O_RDONLY)
        except OSError:
            continue  # closed meanwhile, or not ours to open
        try:
            size = os.fstat(fd).st_size
            if size < 8 * CONTROL_WORDS:
                continue
            return mmap.mmap(fd, size, flags=mmap.MAP_SHARED, prot=mmap.PROT_READ)
        finally:
            os.close(fd)
    raise ProbeFailed(f"process {pid} holds no motion-server image")


def check_live(path: Path, interval: float = LIVE_INTERVAL) -> str:
    """Raise :class:`ProbeFailed` unless the scan's publish count or beat moves within
    ``interval`` seconds; else say which moved."""
    info = read_ready(path)
    image = open_image(int(info["pid"]))
    try:
        if int.from_bytes(image[:8], sys.byteorder, signed=True) != MAGIC:
            raise ProbeFailed("the shared image is not initialised")
        progress = Progress(image)
        count, beat = progress.marker()
        time.sleep(interval)
        count2, beat2 = progress.marker()
        del progress  # its array views must go before the map closes
    finally:
        with contextlib.suppress(BufferError):  # a view still held: it goes with the process
            image.close()
    if count2 > count:
        return f"live: {count2 - count} cycles in {interval:g} s"
    if beat2 > beat:
        return f"live: the scan's loop passed {beat2 - beat} times in {interval:g} s, no cycle"
    raise ProbeFailed(
        f"the scan did not move in {interval:g} s (cycle count {count2}, beat {beat2})"
    )


def build_parser(prog: str = "motion-server probe") -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The probe's options (``motion-server probe`` takes the same)."""
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--ready", action="store_true", help="the server listens on its ports")
    which.add_argument("--live", action="store_true", help="the scan's cycle counter moves")
    p.add_argument(
        "--ready-file",
        required=True,
        metavar="PATH",
        help="the file `motion-server run --ready-file` writes",
    )
    p.add_argument(
        "--interval",
        type=float,
        default=LIVE_INTERVAL,
        help=f"--live: seconds between the two reads (default {LIVE_INTERVAL:g})",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=CONNECT_TIMEOUT,
        help=f"--ready: seconds a port may take to accept (default {CONNECT_TIMEOUT:g})",
    )
    p.add_argument("--quiet", action="store_true", help="print nothing when the check passes")


def run(args: argparse.Namespace) -> int:
    """Run the check the arguments name: 0 when it passes, else 1 and one line."""
    path = Path(args.ready_file)
    try:
        if not (0.0 < args.interval <= 60.0 and 0.0 < args.timeout <= 60.0):
            raise ProbeFailed("--interval and --timeout are seconds in (0, 60]")
        message = check_ready(path, args.timeout) if args.ready else check_live(path, args.interval)
    except ProbeFailed as exc:
        print(f"motion-server probe: {exc}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(message)
    return 0


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
