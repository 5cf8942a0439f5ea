"""Snapshots through ``motion-server run`` (the scan in a process of its own) over Modbus:
the Clock tags save and restore, the write is answered once it is done, a restore the
scan refuses answers exception 04 and changes nothing, ``motion-server snapshot list``
shows what was saved.

The scenario (demo map, manual clock): Axis1 jogs with an S-curve, Axis2 is geared to it
with the clutch; snapshot at cycle k; then a stop of the master at k + 200 and 1,000
cycles traced one by one; restored, the same again: the same values.
"""

from __future__ import annotations

import subprocess
import sys
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
    listed = subprocess.run(
        [sys.executable, "-m", "motion_server.cli", "snapshot", "list"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert listed.returncode == 0, listed.stderr
    line = next(x for x in listed.stdout.splitlines() if x.startswith("41 "))
    assert f"cycle {k}" in line and "demo" in line
