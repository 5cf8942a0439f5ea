"""Snapshots: the controller's state at a cycle, saved under a name and loaded back.

A snapshot is the state itself, not the history that made it: the kernel (axis arrays,
axes, groups, motion processes, fast lanes, MDAC links, homing, fault injection, clock and
tick), every instruction instance (operands, outputs, latched values and edges) and the
watchdogs, captured with :mod:`.statecodec` (pickle, protocol 5). Restoring loads that
state and swaps it in between two cycles: it costs time in proportion to the size of the
controller, not to how long it ran, and the cycles after it give, value by value, the
trace the original gave (the kernel is deterministic). The Clock tags (mode, step,
snapshots, communication faults) are the host's, not the controller's: they are neither
saved nor restored.

A file ``<data_dir>/snapshots/<name>.snap`` (0600, in a folder of mode 0700) is one line
of JSON, the header, then the state's bytes. The header holds the format, the server
version, the versions of Python, numpy and ruckig (the floating-point results depend on
them), the site name, a digest of everything in the site map that shapes the controller,
the cycle, the size of the state and an HMAC-SHA256 of the header and the state with the
installation's key (``<data_dir>/snapshot.key``, 32 random bytes made on first use, 0600):
a file copied in from elsewhere (a shared volume) or edited is refused before a byte of it
is unpickled. Links are not followed, neither for the folder nor for a file. Reading,
checking and unpickling a file (:func:`load`) is done off the scan's cycle
(:class:`Job`); every refusal is one line naming the file and the reason, and the live
controller is not touched until the new state was built and checked whole.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import math
import os
import platform
import re
import secrets
import stat
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import ruckig

from .. import __version__
from ..config import SiteMap
from ..image.layout import ImageLayout
from ..instructions import MotionSystem
from ..kernel import Controller
from ..safety.watchdog import Watchdog
from . import statecodec

FORMAT = "motion-server-snapshot/2"
SUFFIX = ".snap"
#: snapshot names: what a ``Clock.Snapshot`` number spells, or a word of these characters
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
#: the largest snapshot file read
MAX_BYTES = 256 * 2**20
#: the longest header line
MAX_HEADER = 64 * 1024
KEY_FILE = "snapshot.key"
KEY_BYTES = 32


class SnapshotError(RuntimeError):
    """A snapshot that cannot be saved or restored; the message is one line."""


@dataclass
class State:
    """What a snapshot holds: the system (kernel and instances) and the watchdogs' state."""

    tick: int
    system: MotionSystem
    #: the watchdogs by name (pickled without their configuration)
    watchdogs: dict[str, Watchdog]


@dataclass(frozen=True)
class Loaded:
    """A snapshot read, checked and unpickled, ready to be swapped in."""

    name: str
    path: Path
    state: State


def environment() -> dict[str, str]:
    """The versions a snapshot depends on."""
    return {
        "version": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "ruckig": getattr(ruckig, "__version__", "?"),
    }


def site_digest(site: SiteMap, layout: ImageLayout) -> str:
    """A digest of what shapes the controller: axes, groups, instances with their
    operands, watchdogs and the tag layout."""
    shape = {
        "axes": [repr(c) for c in site.axis_configs()],
        "groups": [repr(g) for g in site.group_configs()],
        "instances": [
            [i.type, i.name, sorted((k, repr(v)) for k, v in i.operands.items())]
            for i in site.instances()
        ],
        "watchdogs": [w.model_dump(mode="json") for w in site.watchdogs],
        "layout": layout.fingerprint,
        "retain_axes": list(site.retain.axes),
    }
    if site.cams:  # the initial points (a site without cams keeps its digest)
        shape["cams"] = [repr(c) for c in site.cam_configs()]
    text = json.dumps(shape, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def check_name(name: str) -> str:
    if not NAME.match(name):
        shown = name if len(name) <= 80 else name[:77] + "..."
        raise SnapshotError(
            f"snapshot name {shown!r}: 1 to 64 letters, digits, '_', '.', '-' "
            "(not starting with '_', '.' or '-')"
        )
    return name


def directory(site: SiteMap) -> Path:
    return Path(site.data_dir) / "snapshots"


def path_of(site: SiteMap, name: str) -> Path:
    return directory(site) / f"{check_name(name)}{SUFFIX}"


# -- the installation's key -------------------------------------------------------------------
def key_path(site: SiteMap) -> Path:
    return Path(site.data_dir) / KEY_FILE


def _read_key(path: Path) -> bytes:
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise SnapshotError(f"{path}: the snapshot key is not a regular file")
        if info.st_mode & 0o077:
            raise SnapshotError(
                f"{path}: the snapshot key may be read by others (mode "
                f"{stat.S_IMODE(info.st_mode):o}): chmod 600 it or delete it"
            )
        if hasattr(os, "getuid") and info.st_uid != os.getuid():
            raise SnapshotError(f"{path}: the snapshot key belongs to another user")
        key = os.read(fd, KEY_BYTES + 1)
    finally:
        os.close(fd)
    if len(key) != KEY_BYTES:
        raise SnapshotError(f"{path}: the snapshot key is not {KEY_BYTES} bytes")
    return key


def installation_key(site: SiteMap, create: bool) -> bytes:
    """The key files are signed with (made once, 0600, when ``create``)."""
    path = key_path(site)
    try:
        return _read_key(path)
    except FileNotFoundError:
        if not create:
            raise SnapshotError(
                f"{path}: no snapshot key: this installation has saved no snapshot"
            ) from None
    except OSError as exc:
        raise SnapshotError(f"{path}: cannot read the snapshot key: {exc.strerror}") from None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except FileExistsError:  # made meanwhile by another process: use it
        return _read_key(path)
    except OSError as exc:
        raise SnapshotError(f"{path}: cannot make the snapshot key: {exc.strerror}") from None
    try:
        key = secrets.token_bytes(KEY_BYTES)
        os.write(fd, key)
        os.fsync(fd)
    finally:
        os.close(fd)
    return key


def _mac(key: bytes, header: bytes, body: bytes) -> str:
    m = hmac.new(key, header, hashlib.sha256)
    m.update(b"\n")
    m.update(body)
    return m.hexdigest()


def _canonical(header: dict[str, Any]) -> bytes:
    return json.dumps(header, sort_keys=True, separators=(",", ":")).encode("utf-8")


# -- capture ----------------------------------------------------------------------------------
def capture(system: MotionSystem, watchdogs: dict[str, Watchdog]) -> State:
    """The state of ``system`` and ``watchdogs`` (shared, not copied: pickle it at once)."""
    return State(system.ctl.tick, system, dict(watchdogs))


def encode(state: State) -> bytes:
    """The state's bytes (SnapshotError when something in it cannot be captured)."""
    try:
        return statecodec.dumps(state)
    except statecodec.CodecError as exc:
        raise SnapshotError(str(exc)) from None


def decode(site: SiteMap, data: bytes, tick: int) -> State:
    """The state :func:`encode` made, checked against ``site`` (ValueError, CodecError)."""
    state = statecodec.loads(data)
    check(site, state, tick)
    return state


def write(site: SiteMap, layout: ImageLayout, name: str, tick: int, body: bytes) -> Path:
    """Write snapshot ``name`` (atomically, 0600, signed); its path."""
    path = path_of(site, name)
    key = installation_key(site, create=True)
    header: dict[str, Any] = {
        "format": FORMAT,
        "site": site.site.name,
        "digest": site_digest(site, layout),
        **environment(),
        "tick": tick,
        "saved": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "size": len(body),
    }
    header["hmac"] = _mac(key, _canonical(header), body)
    line = json.dumps(header, sort_keys=True).encode("utf-8")
    folder = path.parent
    tmp = folder / f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp"
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        _check_folder(folder)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
        try:
            with os.fdopen(fd, "wb", closefd=False) as f:
                f.write(line + b"\n")
                f.write(body)
                f.flush()
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise SnapshotError(f"{path}: cannot write the snapshot: {exc.strerror or exc}") from None
    return path


def _check_folder(folder: Path, name: Path | None = None) -> None:
    """The snapshot folder is a folder of its own (not a link to elsewhere)."""
    info = os.lstat(folder)
    if stat.S_ISLNK(info.st_mode) or not stat.S_ISDIR(info.st_mode):
        raise SnapshotError(f"{name or folder}: the snapshot folder is a link or not a folder")


# -- reading ----------------------------------------------------------------------------------
def _read(path: Path, limit: int = MAX_BYTES) -> bytes:
    try:
        _check_folder(path.parent, path)
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except FileNotFoundError:
        raise SnapshotError(f"{path}: no such snapshot") from None
    except OSError as exc:
        if os.path.islink(path):
            raise SnapshotError(f"{path}: a link: snapshots are not followed out") from None
        raise SnapshotError(f"{path}: cannot read the snapshot: {exc.strerror}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise SnapshotError(f"{path}: not a regular file")
        if info.st_size > MAX_BYTES:
            raise SnapshotError(f"{path}: larger than {MAX_BYTES // 2**20} MiB")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(limit + 1 if limit < MAX_BYTES else MAX_BYTES + 1)
    except OSError as exc:
        raise SnapshotError(f"{path}: cannot read the snapshot: {exc.strerror}") from None
    finally:
        os.close(fd)
    if len(data) > MAX_BYTES:
        raise SnapshotError(f"{path}: larger than {MAX_BYTES // 2**20} MiB")
    return data


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number a snapshot may hold")


def split(path: Path, data: bytes, whole: bool = True) -> tuple[dict[str, Any], bytes]:
    """The header (its fields checked for type) and the body of a snapshot file (``whole``:
    ``data`` is the whole file, its body of the size the header says)."""
    end = data.find(b"\n", 0, MAX_HEADER)
    if end < 0:
        raise SnapshotError(f"{path}: not a {FORMAT} file (no header line)")
    try:
        text = data[:end].decode("utf-8")
    except UnicodeDecodeError:
        raise SnapshotError(f"{path}: corrupt snapshot header (not UTF-8)") from None
    try:
        header = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise SnapshotError(f"{path}: corrupt snapshot header ({exc})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise SnapshotError(f"{path}: not a {FORMAT} file")
    kinds: dict[str, type] = {
        "site": str,
        "digest": str,
        "version": str,
        "python": str,
        "numpy": str,
        "ruckig": str,
        "saved": str,
        "hmac": str,
    }
    for k, kind in kinds.items():
        if not isinstance(header.get(k), kind):
            raise SnapshotError(f"{path}: malformed snapshot: header field {k!r}")
    for k in ("tick", "size"):
        v = header.get(k)
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < 2**63:
            raise SnapshotError(f"{path}: malformed snapshot: {k} {v!r}")
    body = data[end + 1 :]
    if whole and len(body) != header["size"]:
        raise SnapshotError(
            f"{path}: truncated or padded: {len(body)} bytes of state, the header says "
            f"{header['size']}"
        )
    return header, body


def header(path: Path) -> dict[str, Any]:
    """The header of a snapshot file (its signature not checked: for listings and the
    CLI; only the header line is read)."""
    head, _ = split(path, _read(path, MAX_HEADER), whole=False)
    return head


def load(site: SiteMap, layout: ImageLayout, name: str) -> Loaded:
    """Snapshot ``name`` of this site read, verified, unpickled and checked against the
    site map (SnapshotError in one line). Slow for a large file: off the cycle."""
    path = path_of(site, name)
    head, body = split(path, _read(path))
    try:
        key = installation_key(site, create=False)
    except SnapshotError as exc:
        raise SnapshotError(f"{path}: cannot be verified: {exc}") from None
    claimed = head.pop("hmac")
    if not hmac.compare_digest(claimed, _mac(key, _canonical(head), body)):
        raise SnapshotError(
            f"{path}: signature mismatch: not saved by this installation, or altered"
        )
    if head["site"] != site.site.name:
        raise SnapshotError(f"{path}: a snapshot of site {head['site']!r}, not {site.site.name!r}")
    for k, value in environment().items():
        if head[k] != value:
            what = "motion-server" if k == "version" else k
            raise SnapshotError(f"{path}: made with {what} {head[k]}, this server runs {value}")
    if head["digest"] != site_digest(site, layout):
        raise SnapshotError(
            f"{path}: made for another site map (axes, groups, instances or watchdogs differ)"
        )
    try:
        state = decode(site, body, head["tick"])
    except (ValueError, TypeError, AttributeError, KeyError) as exc:  # CodecError included
        raise SnapshotError(f"{path}: malformed snapshot: {exc}") from None
    return Loaded(name, path, state)


def check(site: SiteMap, state: Any, tick: int) -> None:
    """``state`` is a controller of this site map at cycle ``tick`` (ValueError)."""
    if not isinstance(state, State) or not isinstance(state.system, MotionSystem):
        raise ValueError("not a controller state")
    ctl = state.system.ctl
    if not isinstance(ctl, Controller) or state.tick != tick or ctl.tick != tick:
        raise ValueError(f"a state of cycle {getattr(ctl, 'tick', '?')}, not {tick}")
    names = [a.name for a in site.axis_configs()]
    if [a.name for a in ctl.axes] != names:
        raise ValueError("its axes are not the site map's")
    if [g.number for g in ctl.groups] != [g.number for g in site.group_configs()]:
        raise ValueError("its groups are not the site map's")
    if sorted(state.system.instances) != sorted(i.name for i in site.instances()):
        raise ValueError("its instruction instances are not the site map's")
    s = ctl.arrays
    n = len(names)
    for field in ("kinematics", "drive_on", "axis_state", "fault", "busy", "plcopen_state"):
        a = getattr(s, field)
        if not isinstance(a, np.ndarray) or a.shape[-1] != n:
            raise ValueError(f"axis array {field} of the wrong shape")
    if not math.isfinite(ctl.time):
        raise ValueError("its clock is not finite")
    configs = {w.name: w for w in site.watchdogs}
    if not isinstance(state.watchdogs, dict) or set(state.watchdogs) != set(configs):
        raise ValueError("its watchdogs are not the site map's")
    for wname, wd in state.watchdogs.items():
        if not isinstance(wd, Watchdog) or wd.ctl is not ctl:
            raise ValueError(f"watchdog {wname} is not one of this controller")
        wd.configure(configs[wname])


def listing(site: SiteMap) -> list[tuple[str, dict[str, Any] | str]]:
    """Every snapshot file of the site: (name, its header) or (name, why it is unreadable)."""
    out: list[tuple[str, dict[str, Any] | str]] = []
    folder = directory(site)
    if not folder.is_dir() or folder.is_symlink():
        return out
    for path in sorted(folder.glob(f"*{SUFFIX}"), key=lambda p: p.name):
        name = path.stem
        try:
            out.append((name, header(path)))
        except SnapshotError as exc:
            out.append((name, str(exc)))
    return out


#: the interpreter's switch interval while a job runs in the background: the scan's
#: thread waits at most this long for the lock the job's Python code holds (5 ms by
#: default, more than a cycle)
JOB_SWITCH_INTERVAL = 0.0005


class Job:
    """Work on a snapshot file off the scan's cycle: ``work`` runs in a thread of its own
    (``background``) or at once; :attr:`done` tells when :attr:`result` or :attr:`error`
    is there."""

    def __init__(self, kind: str, name: str, work: Callable[[], Any], background: bool) -> None:
        self.kind = kind
        self.name = name
        self.result: Any = None
        self.error: SnapshotError | None = None
        self.started = time.perf_counter()
        self._work = work
        self._done = threading.Event()
        self._background = background
        if background:
            self._interval = sys.getswitchinterval()
            sys.setswitchinterval(min(self._interval, JOB_SWITCH_INTERVAL))
            threading.Thread(target=self._run, name=f"snapshot-{kind}", daemon=True).start()
        else:
            self._run()

    def _run(self) -> None:
        try:
            self.result = self._work()
        except SnapshotError as exc:
            self.error = exc
        except Exception as exc:  # anything else still ends in one line, never a traceback
            self.error = SnapshotError(f"snapshot {self.name}: {type(exc).__name__}: {exc}")
        finally:
            if self._background:
                sys.setswitchinterval(self._interval)
            self._done.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        return self._done.wait(timeout)
