"""Snapshots through ``motion-server run`` (the scan in a process of its own) over Modbus:
the Clock tags save and restore, the write is answered once it is done, a restore the
scan refuses answers exception 04 and changes nothing, ``motion-server snapshot list``
shows what was saved.

The scenario (demo map, manual clock): Axis1 jogs with an S-curve, Axis2 is geared to it
with the clutch; snapshot at cycle k; then a stop of the master at k + 200 and 1,000
cycles traced one by one; restored, the same again: the same values.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from motion_clients import ClientError, MotionClient
from motion_server.testing import MotionServer

TRACE = [
    f"Axis{n}.{f}"
    for n in (1, 2)
    for f in ("ActualPosition", "CommandPosition", "ActualVelocity", "CommandVelocity")
] + ["MAG_1.IP", "MAG_1.FLAGS", "Axis2.MotionStatus", "Clock.Cycle"]


async def script(mc: MotionClient, cycles: int) -> list[dict[str, Any]]:
    rows = []
    for n in range(cycles):
        if n == 200:
            await mc.write_many({"MAS_1.Axis": 1, "MAS_1.StopType": 0, "MAS_1.Execute": True})
        elif n == 201:
            await mc.write("MAS_1.Execute", False)
        await mc.step(1)
        rows.append(await mc.read_many(TRACE))
    return rows


@pytest.mark.slow
async def test_snapshot_save_and_restore_over_modbus(tmp_path: Path) -> None:
    server = MotionServer.start(tmp_path, None, clock="manual", opcua=False)
    try:
        async with server.client() as mc:
            for axis in (1, 2):
                assert (await mc.trigger("MSO_1", Axis=axis)).ok
            assert (
                await mc.trigger(
                    "MAJ_1", Axis=1, Speed=100.0, AccelRate=1000.0, DecelRate=1000.0,
                    Profile=1, AccelJerk=100.0, DecelJerk=100.0, JerkUnits=2,
                )
            ).ok  # fmt: skip
            assert (
                await mc.trigger(
                    "MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5, MasterReference=0, Clutch=0,
                    AccelRate=1000.0,
                )
            ).ok  # fmt: skip
            await mc.step(50)
            k = await mc.cycle()
            await mc.write_many({"Clock.Snapshot": 41, "Clock.SnapshotSave": True})
            assert await mc.read("Clock.SnapshotSave") is False
            assert (tmp_path / "snapshots" / "41.snap").is_file()
            first = await script(mc, 1000)
            assert await mc.cycle() == k + 1000

            # a restore the scan refuses: exception 04, nothing changed
            await mc.write("Clock.Snapshot", 42)
            with pytest.raises(ClientError):
                await mc.write("Clock.SnapshotRestore", True)
            assert await mc.cycle() == k + 1000
            assert "snapshots/42.snap: no such snapshot" in server.log()

            await mc.write_many({"Clock.Snapshot": 41, "Clock.SnapshotRestore": True})
            assert await mc.cycle() == k
            second = await script(mc, 1000)
        assert second == first
        assert first[300]["MAG_1.IP"] is True  # the gear still runs behind the stopping master
    finally:
        server.stop()
    listed = cli("list", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    line = next(x for x in listed.stdout.splitlines() if x.startswith("41 "))
    assert f"cycle {k}" in line and "demo" in line


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``motion-server snapshot ...`` on this machine, with the data directory the plugin
    gives the server (its own directory, ``cwd`` here)."""
    return subprocess.run(
        [sys.executable, "-m", "motion_server.cli", "snapshot", *args],
        cwd=cwd,
        env={**os.environ, "MOTION_SERVER_DATA_DIR": str(cwd.resolve())},
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_snapshot_numbers_the_clock_tag_cannot_hold_are_one_line(tmp_path: Path) -> None:
    for args in (("save", "²"), ("restore", "4294967296"), ("save", "-1"), ("save",)):
        done = cli(*args, cwd=tmp_path)
        assert done.returncode == 1, done
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
        assert "the snapshot's number, 0 to 4294967295" in lines[0]


async def run_fast(mc: MotionClient, seconds: float) -> int:
    """Cycles as fast as the CPU allows for ``seconds``, then the manual clock again."""
    await mc.write("Clock.Mode", 3)
    await asyncio.sleep(seconds)
    await mc.write("Clock.Mode", 1)
    return int(await mc.cycle())


@pytest.mark.slow
async def test_crafted_files_and_a_long_history_over_modbus(tmp_path: Path) -> None:
    """A junk file is refused in one line and the scan goes on; a snapshot after a long
    run of the fast clock restores at once (the old design ran every cycle again inside
    one cycle: the scan answered nothing meanwhile)."""
    server = MotionServer.start(tmp_path, None, clock="manual", opcua=False)
    try:
        async with server.client() as mc:
            folder = tmp_path / "snapshots"
            folder.mkdir(mode=0o700)
            (folder / "5.snap").write_text('{"format": "junk"}\n')
            await mc.write("Clock.Snapshot", 5)
            with pytest.raises(ClientError):
                await mc.write("Clock.SnapshotRestore", True)
            assert "5.snap: not a motion-server-snapshot/2 file" in server.log()
            assert "Traceback" not in server.log()

            assert (await mc.trigger("MSO_1", Axis=1)).ok
            t0 = time.perf_counter()
            k = await run_fast(mc, 3.0)
            fast = time.perf_counter() - t0
            assert k > 10000
            await mc.write_many({"Clock.Snapshot": 6, "Clock.SnapshotSave": True})
            saved = json.loads((folder / "6.snap").read_bytes().split(b"\n")[0])["tick"]
            assert saved >= k
            await mc.step(10)
            t0 = time.perf_counter()
            await mc.write_many({"Clock.Snapshot": 6, "Clock.SnapshotRestore": True})
            restore = time.perf_counter() - t0
            assert await mc.cycle() == saved
            assert restore < fast / 10, f"{k} cycles: restored in {restore:.3f} s"
        assert server.stop() == 0
    finally:
        server.stop()


@pytest.mark.slow
async def test_a_restore_on_a_realtime_server_is_not_a_late_cycle(tmp_path: Path) -> None:
    """Realtime clock: a restore drops no cycle and counts no overrun burst; the CLI
    prints the cycle of the snapshot itself, not one read after it."""
    server = MotionServer.start(tmp_path, None, clock="realtime", opcua=False)
    try:
        async with server.client() as mc:
            await run_fast(mc, 2.0)  # a long history: the old design ran it all again
            await mc.write("Clock.Mode", 0)
            await asyncio.sleep(0.5)
            saved = cli("save", "8", "--port", str(server.modbus_port), cwd=tmp_path)
            assert saved.returncode == 0, saved.stderr
            tick = json.loads((tmp_path / "snapshots" / "8.snap").read_bytes().split(b"\n")[0])
            assert saved.stdout.strip() == f"snapshot 8 saved: cycle {tick['tick']}"
            await asyncio.sleep(0.5)
            counts = ["Diagnostics.Overruns", "Diagnostics.DroppedCycles"]
            first = await mc.read_many(counts)
            done = cli("restore", "8", "--port", str(server.modbus_port), cwd=tmp_path)
            assert done.returncode == 0, done.stderr
            assert done.stdout.strip() == f"snapshot 8 restored: cycle {tick['tick']}"
            await asyncio.sleep(0.5)
            second = await mc.read_many(counts)
            missing = cli("restore", "77", "--port", str(server.modbus_port), cwd=tmp_path)
            assert missing.returncode == 1
            assert missing.stderr.strip().splitlines() == [
                f"motion-server: snapshot 77 not restored: {tmp_path.resolve()}/snapshots/77.snap: "
                "no such snapshot"
            ]
        assert second["Diagnostics.DroppedCycles"] == first["Diagnostics.DroppedCycles"]
        assert second["Diagnostics.Overruns"] - first["Diagnostics.Overruns"] < 50
        assert "snapshot 8 restored" in server.log()
    finally:
        server.stop()


@pytest.mark.slow
def test_a_server_run_in_a_source_tree_leaves_no_files_there(tmp_path: Path) -> None:
    """``motion-server run`` (the demo map, which sets no data_dir) started in a clone's
    root, a snapshot saved: nothing appears in that directory; the snapshot and its key
    are in the user's state directory."""
    clone, home = tmp_path / "clone", tmp_path / "home"
    clone.mkdir()
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOTION_SERVER_")}
    env.pop("XDG_STATE_HOME", None)
    env["HOME"] = str(home)
    ready = tmp_path / "ready.json"
    cmd = [sys.executable, "-m", "motion_server.cli", "run", "--clock", "manual",
           "--modbus-port", "0", "--no-opcua", "--no-ethernetip",
           "--ready-file", str(ready)]  # fmt: skip
    log = (tmp_path / "server.log").open("wb")
    proc = subprocess.Popen(cmd, cwd=clone, env=env, stdout=log, stderr=log)
    try:
        give_up = time.monotonic() + 120
        while not ready.exists():
            assert proc.poll() is None and time.monotonic() < give_up
            time.sleep(0.05)
        port = json.loads(ready.read_text())["modbus"]["port"]
        done = subprocess.run(
            [sys.executable, "-m", "motion_server.cli", "snapshot", "save", "3",
             "--port", str(port)],
            cwd=clone, env=env, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)
        log.close()
    assert sorted(p.name for p in clone.iterdir()) == []
    state = home / ".local" / "state" / "motion-server" / "demo"
    assert (state / "snapshots" / "3.snap").is_file()
    assert (state / "snapshot.key").stat().st_mode & 0o777 == 0o600
