"""Supervision by liveness, over real processes: ``motion-server run`` as deployed (the
supervisor, the scan, one process per front-end), its children signalled from outside.

- a scan that ends at any moment, start-up included, stops the server at once: one line
  naming the scan, every process gone, exit status not 0;
- a front-end whose event loop stands still (SIGSTOP: it accepts connections and answers
  nothing) is killed and replaced while motion goes on;
- a scan that stands still (SIGSTOP: no cycle, no heartbeat, deaf to SIGTERM) stops the
  server: one line, every process killed, the retain file as it was.

The bounds are generous (a loaded 2-core machine): each test polls and ends as soon as
what it waits for happened. The supervisor's constants are in
:mod:`motion_server.liveness` (docs/architecture.md, docs/safety.md).
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
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_server import config
from motion_server.liveness import FRONTEND_HANG, SCAN_HANG
from motion_server.tagmap import build_tagmap
from motion_server.tagmap.codec import decode
from motion_server.testing import MotionServer

SITE = """
[site]
name = "liveness"
namespace_uri = "urn:motion-server:liveness-test"

[controller]
status_log_interval = 0.0

[modbus]
port = 0

[opcua]
port = 0
data_dir = "opcua-data"
allow_anonymous = true
anonymous_role = "operator"
allow_none_endpoint = true

[retain]
enabled = true
interval = 0.0
axes = ["Axis1"]

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Axis1"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0
"""
TAGS = build_tagmap(config.parse(SITE, "site.toml"))

#: seconds a server has to end once one of its processes died or hung: the supervisor
#: sees it within a poll (0.5 s) or the hang bound, gives a hung scan 2 s to stop, then
#: stops the front-ends (SIGTERM; SIGKILL after 10 s). Generous: a loaded machine
END_BOUND = SCAN_HANG + 25.0
#: seconds until a Modbus client is answered again after its front-end stood still: the
#: hang bound, the supervisor's poll, the first restart delay (0.5 s), then the new
#: process's start (about a second; several on a loaded machine)
ANSWER_BOUND = FRONTEND_HANG["modbus"] + 15.0


@pytest.fixture
def site_dir(tmp_path: Path) -> Path:
    (tmp_path / "site.toml").write_text(SITE)
    return tmp_path


def children(pid: int) -> dict[str, int]:
    """role ("scan", "modbus", "opcua") -> pid of the live children of ``pid``."""
    out: dict[str, int] = {}
    try:
        listed = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return out
    for child in listed:
        try:
            cmd = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"motion_server.scan" in cmd:
            out["scan"] = int(child)
        elif b"motion_server.frontends" in cmd:
            out[cmd[cmd.index(b"motion_server.frontends") + 1].decode()] = int(child)
    return out


def gone(pid: int) -> bool:
    """The process has ended (a zombie not yet reaped counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def continue_all(pids: Iterator[int] | list[int]) -> None:
    """SIGCONT what a failed test left stopped (so that its clean-up can end it)."""
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGCONT)


def read_register_value(port: int, name: str, timeout: float = 1.0) -> float | None:
    """FC3 of tag ``name`` on a fresh connection; None when nothing answers in time."""
    tag = TAGS.tag(name)
    frame = struct.pack(">HHHBBHH", 7, 0, 6, 1, 3, tag.address, tag.count)
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
            s.sendall(frame)
            answer = b""
            while len(answer) < 9 + 2 * tag.count:
                data = s.recv(256)
                if not data:
                    return None
                answer += data
    except OSError:  # a timeout, a refused or reset connection
        return None
    regs = struct.unpack(f">{tag.count}H", answer[9 : 9 + 2 * tag.count])
    return float(decode(tag.type, regs))


def lines(log: str, pattern: str) -> list[str]:
    return [line for line in log.splitlines() if re.search(pattern, line)]


# -- a scan that ends during start-up -------------------------------------------------------
def test_a_scan_terminated_while_the_front_ends_start_stops_the_server(site_dir: Path) -> None:
    """SIGTERM to the scan once it runs, while the OPC UA front-end still builds its
    address space: before, the supervisor restarted the front-ends for 120 s ("link to
    the scan lost") and then failed with "did not listen within 120 s"."""
    log_file = site_dir / "server.log"
    cmd = [sys.executable, "-m", "motion_server.cli", "run", "site.toml"]
    cmd += ["--clock", "realtime", "--modbus-port", "0", "--opcua-port", "0"]
    with log_file.open("wb") as out:
        proc = subprocess.Popen(cmd, cwd=site_dir, stdin=subprocess.DEVNULL, stdout=out, stderr=out)
    seen: set[int] = set()
    try:
        # the scan says it runs (its start line) before the supervisor starts the front-ends
        give_up = time.monotonic() + 120.0
        while "axes, 1 groups" not in log_file.read_text():
            seen |= set(children(proc.pid).values())
            assert proc.poll() is None, log_file.read_text()
            assert time.monotonic() < give_up, "the scan did not start"
            time.sleep(0.02)
        scan = children(proc.pid)["scan"]
        os.kill(scan, signal.SIGTERM)
        t0 = time.monotonic()
        while proc.poll() is None and time.monotonic() - t0 < END_BOUND:
            seen |= set(children(proc.pid).values())
            time.sleep(0.05)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    log = log_file.read_text()
    assert proc.returncode not in (None, 0), log[-3000:]
    assert took < END_BOUND, log[-3000:]
    named = lines(log, r"supervisor: the scan process")
    assert len(named) == 1, log[-3000:]
    assert "motion has stopped" in named[0]
    assert not lines(log, r"front-end died|restarting it|did not listen"), log[-3000:]
    assert "serving:" not in log  # it happened during start-up
    assert all(gone(pid) for pid in seen), [p for p in seen if not gone(p)]
    assert "Traceback" not in log


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_a_scan_that_ends_once_modbus_listens_while_opc_ua_starts_stops_the_server(
    site_dir: Path, sig: signal.Signals
) -> None:
    """Later in the start-up: the Modbus front-end listens (connected to the scan), the
    OPC UA front-end is still starting. Before, the Modbus front-end lost its link and was
    restarted again and again for 120 s. (SIGTERM exactly 2 s after ``motion-server
    run`` starts lands, on this machine, before the scan even installed its handler:
    that case was already named, "the scan process could not start".)"""
    log_file = site_dir / "server.log"
    cmd = [sys.executable, "-m", "motion_server.cli", "run", "site.toml"]
    cmd += ["--clock", "realtime", "--modbus-port", "0", "--opcua-port", "0"]
    with log_file.open("wb") as out:
        proc = subprocess.Popen(cmd, cwd=site_dir, stdin=subprocess.DEVNULL, stdout=out, stderr=out)
    seen: set[int] = set()
    try:
        give_up = time.monotonic() + 120.0
        while "Modbus TCP on" not in log_file.read_text():
            seen |= set(children(proc.pid).values())
            assert proc.poll() is None, log_file.read_text()
            assert time.monotonic() < give_up, "Modbus did not listen"
            time.sleep(0.02)
        seen |= set(children(proc.pid).values())
        os.kill(children(proc.pid)["scan"], sig)
        t0 = time.monotonic()
        while proc.poll() is None and time.monotonic() - t0 < END_BOUND:
            seen |= set(children(proc.pid).values())
            time.sleep(0.05)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    log = log_file.read_text()
    assert proc.returncode not in (None, 0), log[-3000:]
    assert took < END_BOUND, log[-3000:]
    named = lines(log, r"supervisor: the scan process")
    assert len(named) == 1, log[-3000:]
    if sig == signal.SIGKILL:
        assert "died (killed by SIGKILL)" in named[0]
    else:
        assert "stopped without being asked to" in named[0]
    assert not lines(log, r"front-end died|restarting it|did not listen"), log[-3000:]
    assert all(gone(pid) for pid in seen), [p for p in seen if not gone(p)]
    assert "Traceback" not in log


# -- a front-end that stands still ----------------------------------------------------------
def test_a_modbus_front_end_that_stands_still_is_replaced_while_motion_goes_on(
    site_dir: Path,
) -> None:
    server = MotionServer.start(site_dir, site_dir / "site.toml", clock="realtime", opcua=False)
    stopped = children(server.pid)["modbus"]
    try:
        port = server.modbus_port
        before = read_register_value(port, "Clock.Cycle")
        assert before is not None
        os.kill(stopped, signal.SIGSTOP)
        t0 = time.monotonic()
        assert read_register_value(port, "Clock.Cycle", timeout=0.5) is None  # deaf now
        answered = None
        while answered is None and time.monotonic() - t0 < ANSWER_BOUND:
            answered = read_register_value(port, "Clock.Cycle", timeout=0.5)
            if answered is None:
                time.sleep(0.1)
        took = time.monotonic() - t0
        log = server.log()
        assert answered is not None, f"no answer within {ANSWER_BOUND} s\n{log[-3000:]}"
        print(f"\nModbus answered again {took:.2f} s after its front-end stood still")
        assert gone(stopped)  # killed, not continued
        assert children(server.pid)["modbus"] != stopped
        hung = lines(log, r"the modbus front-end")
        assert len(hung) == 1 and "hung" in hung[0] and "motion goes on" in hung[0], log[-3000:]
        # motion went on: the scan ran its cycles meanwhile (2 ms each)
        assert answered > before + 0.5 * (FRONTEND_HANG["modbus"] / 0.002)
        assert server.read("Diagnostics.FrontendRestarts") == 1
        assert "scan process" not in log
    finally:
        continue_all([stopped])
        code = server.stop()
    assert code == 0, server.log()[-3000:]
    assert "Traceback" not in server.log()


# -- a scan that stands still ---------------------------------------------------------------
def test_a_scan_that_stands_still_stops_the_server_and_leaves_the_retain_file(
    site_dir: Path,
) -> None:
    # a clean run leaves a retain file (10 cycles stepped, then the programmed stop)
    first = MotionServer.start(site_dir, site_dir / "site.toml", clock="manual", opcua=False)
    first.step(10)
    assert first.stop() == 0, first.log()[-3000:]
    retain_file = site_dir / "retain.json"
    saved = retain_file.read_bytes()
    server = MotionServer.start(site_dir, site_dir / "site.toml", clock="manual", opcua=False)
    pids = children(server.pid)
    try:
        server.step(25)  # a retain written now would differ (another cycle count)
        # the manual clock runs no cycle unless stepped: an idle scan is not a hung one
        idle_until = time.monotonic() + 2 * SCAN_HANG
        while time.monotonic() < idle_until:
            assert server.proc.poll() is None, server.log()[-3000:]
            time.sleep(0.2)
        assert server.read("Clock.Cycle") == 25
        assert "scan process hung" not in server.log()
        os.kill(pids["scan"], signal.SIGSTOP)
        t0 = time.monotonic()
        try:
            code = server.proc.wait(END_BOUND)
        except subprocess.TimeoutExpired:
            code = None
        took = time.monotonic() - t0
        log = server.log()
        assert code is not None, f"still running {END_BOUND} s later\n{log[-3000:]}"
        print(f"\nthe server ended {took:.2f} s after its scan stood still")
        assert code != 0
        named = lines(log, r"supervisor: the scan process")
        assert len(named) == 1 and "hung" in named[0], log[-3000:]
        assert all(gone(pid) for pid in pids.values()), pids
        assert retain_file.read_bytes() == saved  # not overwritten
        assert "Traceback" not in log
    finally:
        continue_all(pids.values())
        server.stop(timeout=15.0)


def test_a_hung_scan_that_comes_back_runs_its_programmed_stop_but_writes_no_retain(
    site_dir: Path,
) -> None:
    """Declared hung, the scan is asked for its programmed stop; one that can still run
    it (here: continued right after the line) does, and ends by itself within the grace.
    What it hands over then is not written: the retain file stays as it was."""
    first = MotionServer.start(site_dir, site_dir / "site.toml", clock="manual", opcua=False)
    first.step(10)
    assert first.stop() == 0, first.log()[-3000:]
    retain_file = site_dir / "retain.json"
    saved = retain_file.read_bytes()
    server = MotionServer.start(site_dir, site_dir / "site.toml", clock="manual", opcua=False)
    pids = children(server.pid)
    try:
        server.step(25)
        offset = len(server.log())
        os.kill(pids["scan"], signal.SIGSTOP)
        give_up = time.monotonic() + END_BOUND
        while "scan process hung" not in server.log()[offset:]:
            assert time.monotonic() < give_up, server.log()[-3000:]
            time.sleep(0.05)
        os.kill(pids["scan"], signal.SIGCONT)
        code = server.proc.wait(END_BOUND)
        log = server.log()[offset:]
        assert code != 0
        assert "programmed stop complete" in log, log
        assert "did not stop: killed" not in log
        assert "retain: the state a hung scan handed over is not written" in log
        assert retain_file.read_bytes() == saved
        assert all(gone(pid) for pid in pids.values()), pids
    finally:
        continue_all(pids.values())
        server.stop(timeout=15.0)


def test_a_stop_asked_of_a_server_whose_scan_stands_still_ends_without_orphans(
    site_dir: Path,
) -> None:
    """SIGTERM to the supervisor while the scan stands still: before, the supervisor
    waited for a programmed stop that never came (and had to be killed)."""
    server = MotionServer.start(site_dir, site_dir / "site.toml", clock="realtime", opcua=False)
    pids = children(server.pid)
    try:
        os.kill(pids["scan"], signal.SIGSTOP)
        server.proc.send_signal(signal.SIGTERM)
        try:
            code = server.proc.wait(END_BOUND)
        except subprocess.TimeoutExpired:
            code = None
        log = server.log()
        assert code is not None, f"still running {END_BOUND} s later\n{log[-3000:]}"
        assert code != 0
        named = lines(log, r"supervisor: the scan process")
        assert len(named) == 1 and "hung" in named[0], log[-3000:]
        assert all(gone(pid) for pid in pids.values()), pids
    finally:
        continue_all(pids.values())
        server.stop(timeout=15.0)


def test_no_process_outlives_a_killed_supervisor(site_dir: Path) -> None:
    """The supervisor killed (SIGKILL, the OOM killer) while its scan stands still: the
    scan cannot read its lifeline, yet it ends with the supervisor, and so do the
    front-ends."""
    server = MotionServer.start(site_dir, site_dir / "site.toml", clock="realtime", opcua=False)
    pids = children(server.pid)
    try:
        os.kill(pids["scan"], signal.SIGSTOP)
        server.proc.kill()
        server.proc.wait(10)
        give_up = time.monotonic() + 20.0
        while not all(gone(pid) for pid in pids.values()) and time.monotonic() < give_up:
            time.sleep(0.1)
        assert all(gone(pid) for pid in pids.values()), pids
    finally:
        continue_all(pids.values())
        for pid in pids.values():  # what this test would otherwise leave behind
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
