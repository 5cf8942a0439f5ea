"""The supervisor's liveness bookkeeping (:mod:`motion_server.liveness`), clocked by
numbers: a watched process is hung once it showed nothing for longer than its limit, and
the supervisor's own stalls are not blamed on the others."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from motion_server.image.buffer import META_WORDS, ImageWriter, Progress, image_bytes
from motion_server.liveness import (
    FRONTEND_BEAT,
    FRONTEND_HANG,
    SCAN_BEAT,
    SCAN_HANG,
    SELF_STALL,
    Liveness,
)


def test_silent_beyond_the_limit_is_hung_and_progress_resets_the_window() -> None:
    live = Liveness()
    live.watch("scan", 3.0, now=100.0)
    t = 100.0
    while t < 103.0:  # looked at every 0.5 s, as the supervisor does
        assert live.hung(t) == []
        t += 0.5
    assert live.hung(103.0) == []  # exactly the limit: not yet
    assert [(n, round(silent, 6)) for n, silent in live.hung(103.4)] == [("scan", 3.4)]
    live.seen("scan", 103.5)
    assert live.hung(103.9) == []


def test_each_process_has_its_own_limit_and_a_forgotten_one_is_not_watched() -> None:
    live = Liveness()
    live.watch("modbus", FRONTEND_HANG["modbus"], now=0.0)
    live.watch("opcua", FRONTEND_HANG["opcua"], now=0.0)
    for k in range(1, 9):
        live.hung(0.5 * k)
    assert [name for name, _ in live.hung(4.5)] == ["modbus"]
    live.forget("modbus")
    assert not live.watching("modbus")
    live.seen("modbus", 5.0)  # a line from a process no longer watched: nothing
    for k in range(10, 22):
        live.hung(0.5 * k)
    assert [name for name, _ in live.hung(11.0)] == ["opcua"]


def test_the_supervisors_own_stall_starts_every_window_again() -> None:
    """Stopped for 10 s itself (or the whole machine was): the scan ran no cycle in that
    time either, but it gets a full window from when the supervisor looks again."""
    live = Liveness()
    live.watch("scan", SCAN_HANG, now=0.0)
    assert live.hung(0.5) == []
    assert live.hung(10.5) == []  # a gap of 10 s > SELF_STALL: forgiven
    t = 10.5
    while t < 10.5 + SCAN_HANG - 0.25:  # looked at every 0.5 s again
        t += 0.5
        assert live.hung(t) == [], t
    assert [n for n, _ in live.hung(10.5 + SCAN_HANG + 0.25)] == ["scan"]


def test_a_gap_within_the_stall_bound_is_not_forgiven() -> None:
    live = Liveness()
    live.watch("scan", SCAN_HANG, now=0.0)
    t = 0.0
    while t < SCAN_HANG + 1.0:
        t += SELF_STALL * 0.9
        hung = live.hung(t)
    assert [n for n, _ in hung] == ["scan"]


def test_the_limits_leave_room_for_several_missed_beats() -> None:
    assert SCAN_HANG >= 8 * SCAN_BEAT
    assert min(FRONTEND_HANG.values()) >= 4 * FRONTEND_BEAT
    assert min(SCAN_HANG, *FRONTEND_HANG.values()) / 2 > SELF_STALL


def test_the_image_shows_publishes_and_beats_to_the_supervisor() -> None:
    buf = bytearray(image_bytes(4))
    writer = ImageWriter(buf, 4, fingerprint=7)
    progress = Progress(buf)
    first = progress.marker()
    writer.beat()  # an idle pass: no publish, but the scan's loop runs
    second = progress.marker()
    assert second != first and second[0] == first[0]
    writer.publish(np.zeros(4), np.zeros(META_WORDS, dtype=np.int64))
    third = progress.marker()
    assert third[0] == second[0] + 1 and third[1] == second[1]  # a cycle published


def test_a_child_whose_supervisor_is_already_gone_exits_at_once() -> None:
    """Between its start and asking the kernel to follow the supervisor, the supervisor
    may end: the child then exits in one line instead of living on unwatched."""
    dead = subprocess.Popen(["true"])  # a pid that no longer runs
    dead.wait()
    probe = (
        "from motion_server.launch import LaunchSpec, follow_supervisor\n"
        f"spec = LaunchSpec({{}}, '', 'INFO', -1, 0, {{}}, supervisor={dead.pid})\n"
        "follow_supervisor(spec)\n"
        "print('still here')\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert out.returncode == 1
    assert out.stderr.strip() == "motion-server: the supervisor is gone"
    assert "still here" not in out.stdout
    # its own parent, alive: it runs on (and dies with that parent)
    probe = probe.replace(f"supervisor={dead.pid}", "supervisor=__import__('os').getppid()")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "still here", out.stderr
