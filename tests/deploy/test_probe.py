"""``motion-server probe``: the exec probes of the Kubernetes manifests, against a real server.

Readiness is the ready file plus its ports accepting connections; liveness is the scan's
cycle counter (or, with the manual clock, its beat) moving between two reads of the
shared image. A scan that is stopped (SIGSTOP) must fail liveness: that is what a
liveness probe exists to see.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from motion_server import probe as probe_module
from motion_server.supervisor import READY_FORMAT
from motion_server.testing import MotionServer, ServerFactory


def probe(*args: str) -> subprocess.CompletedProcess[str]:
    """``motion-server probe ARGS`` in a process of its own, as an exec probe runs it."""
    cmd = [sys.executable, "-m", "motion_server.cli", "probe", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=False)


def scan_pid(server: MotionServer) -> int:
    """The scan process: the supervisor's child running ``motion_server.scan``."""
    pid = server.info["pid"]
    children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    for child in children:
        cmdline = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
        if b"motion_server.scan" in cmdline:
            return int(child)
    raise AssertionError(f"no scan among the children {children} of {pid}")


@pytest.fixture
def realtime(motion_server_factory: ServerFactory) -> MotionServer:
    return motion_server_factory(clock="realtime", opcua=False)


def test_a_running_server_is_ready_and_live(realtime: MotionServer) -> None:
    ready = probe("--ready", "--ready-file", str(realtime.ready_file))
    assert ready.returncode == 0, ready.stderr
    assert f"modbus {realtime.info['modbus']['port']}" in ready.stdout
    live = probe("--live", "--ready-file", str(realtime.ready_file), "--interval", "0.5")
    assert live.returncode == 0, live.stderr
    # the default period is 2 ms: about 250 cycles in 0.5 s, at least one on any machine
    assert "cycles in 0.5 s" in live.stdout


def test_a_stopped_scan_is_not_live(realtime: MotionServer) -> None:
    pid = scan_pid(realtime)
    os.kill(pid, signal.SIGSTOP)
    try:
        live = probe("--live", "--ready-file", str(realtime.ready_file), "--interval", "0.5")
    finally:
        os.kill(pid, signal.SIGCONT)
    assert live.returncode == 1
    assert live.stderr.startswith("motion-server probe: the scan did not move in 0.5 s")
    assert "Traceback" not in live.stderr
    again = probe("--live", "--ready-file", str(realtime.ready_file))
    assert again.returncode == 0, again.stderr


def test_the_manual_clock_is_live_by_its_beat(motion_server_factory: ServerFactory) -> None:
    server = motion_server_factory(clock="manual", opcua=False)
    live = probe("--live", "--ready-file", str(server.ready_file))
    assert live.returncode == 0, live.stderr
    assert "no cycle" in live.stdout


def test_a_stopping_server_is_neither_ready_nor_live(motion_server_factory: ServerFactory) -> None:
    server = motion_server_factory(clock="realtime", opcua=False)
    path = server.ready_file
    assert server.stop() == 0
    for which in ("--ready", "--live"):
        out = probe(which, "--ready-file", str(path))
        assert out.returncode == 1
        assert (
            out.stderr == f"motion-server probe: no ready file {path}: the server starts or stops\n"
        )


def write_ready(path: Path, **info: object) -> Path:
    path.write_text(json.dumps({"format": "motion-server-ready/1", **info}), "utf-8")
    return path


def test_a_ready_file_whose_process_is_gone_is_not_ready(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    gone = int(done.stdout)
    path = write_ready(tmp_path / "ready.json", pid=gone, site="x")
    out = probe("--ready", "--ready-file", str(path))
    assert out.returncode == 1
    assert f"the server process {gone}" in out.stderr


def test_a_port_that_does_not_listen_is_not_ready(tmp_path: Path) -> None:
    with socket.socket() as s:  # a port that was free a moment ago and listens nowhere
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    path = write_ready(
        tmp_path / "r.json", pid=os.getpid(), modbus={"host": "0.0.0.0", "port": port}
    )
    out = probe("--ready", "--ready-file", str(path))
    assert out.returncode == 1
    assert out.stderr.startswith(f"motion-server probe: modbus port {port} does not accept")


def test_a_process_without_an_image_is_not_live(tmp_path: Path) -> None:
    path = write_ready(tmp_path / "r.json", pid=os.getpid())
    out = probe("--live", "--ready-file", str(path))
    assert out.returncode == 1
    assert (
        out.stderr == f"motion-server probe: process {os.getpid()} holds no motion-server image\n"
    )


@pytest.mark.parametrize(
    ("args", "status"),
    [
        (["--ready"], 2),  # no --ready-file
        (["--ready", "--live", "--ready-file", "x"], 2),
        (["--live", "--ready-file", "x", "--interval", "0"], 1),
        (["--live", "--ready-file", "x", "--interval", "nan"], 1),
    ],
)
def test_bad_arguments_are_one_line(args: list[str], status: int) -> None:
    out = probe(*args)
    assert out.returncode == status
    assert len(out.stderr.splitlines()) == 1, out.stderr


def test_the_probe_reads_the_format_the_supervisor_writes() -> None:
    assert probe_module.READY_FORMAT == READY_FORMAT
