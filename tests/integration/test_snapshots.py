"""Snapshots: save the controller state at cycle k, run on, restore, run on again: the same
trace, value by value (``scan/snapshots.py``). And refusals in one line.

The scenario runs on the demo map with the manual clock, every write going through a
front-end view like a client's: Axis1 (virtual) jogs with an S-curve (ruckig), Axis2
(servo) is geared to it by MAG with the clutch (a catch-up ramp, then locked), Axis3
(rotary servo) makes an S-curve move; after the snapshot the script stops and reverses
the master, injects a soft overtravel on the slave, resets it and stops the group. The
trace is every published value of the axes, groups, instances and watchdogs, and the
clock's cycle and time, after every cycle.
"""

from __future__ import annotations

import gc
import json
import time
import tracemalloc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from motion_server import config
from motion_server.instructions import MotionSystem
from motion_server.kernel import Controller
from motion_server.runtime import Runtime
from motion_server.scan import snapshots
from motion_server.tagmap import Folder

K = 400  # the snapshot's cycle
AFTER = 1000  # cycles traced after it

S_CURVE = {"Profile": 1, "AccelJerk": 100.0, "DecelJerk": 100.0, "JerkUnits": 2}


def demo_site(tmp: Path, **controller: Any) -> config.SiteMap:
    site = config.load(None)
    ctl = site.controller.model_copy(
        update={"clock": "manual", "status_log_interval": 0.0, **controller}
    )
    return site.model_copy(update={"controller": ctl, "data_dir": str(tmp)})


def trigger(rt: Runtime, instance: str, **operands: Any) -> None:
    rt.image.write_many({f"{instance}.{k}": v for k, v in operands.items()}.items())
    rt.image.write(f"{instance}.Execute", True)
    rt.cycle(1)
    rt.image.write(f"{instance}.Execute", False)
    rt.cycle(1)  # scanned low: the next trigger is a rising edge again


def traced(rt: Runtime) -> np.ndarray:
    """The slots of the trace: every tag but the diagnostics and the Clock's commands."""
    keep = [
        i
        for i, t in enumerate(rt.layout.tags)
        if t.folder not in (Folder.DIAGNOSTICS, Folder.CLOCK) or t.field in ("Cycle", "SimTime")
    ]
    return np.array(keep)


def before(rt: Runtime) -> None:
    """Cycles 0..K: enable, jog, gear with the clutch, move."""
    for axis in (1, 2, 3):
        trigger(rt, "MSO_1", Axis=axis)
    trigger(rt, "MAJ_1", Axis=1, Speed=200.0, AccelRate=2000.0, DecelRate=2000.0, **S_CURVE)
    trigger(
        rt,
        "MAG_1",
        SlaveAxis=2,
        MasterAxis=1,
        Ratio=0.5,
        MasterReference=0,
        Clutch=0,
        AccelRate=1500.0,
    )
    trigger(rt, "MAM_1", Axis=3, Position=270.0, Speed=720.0, AccelRate=3600.0,
            DecelRate=3600.0, **S_CURVE)  # fmt: skip
    rt.cycle(K - rt.cycle_count)
    assert rt.cycle_count == K


def pulse(at: int, instance: str, **operands: Any) -> dict[int, list[tuple[str, Any]]]:
    """Writes that trigger ``instance``: operands and Execute at ``at``, Execute low after."""
    writes = [(f"{instance}.{k}", v) for k, v in operands.items()]
    return {at: [*writes, (f"{instance}.Execute", True)], at + 1: [(f"{instance}.Execute", False)]}


#: cycle after the snapshot -> the writes made then (before that cycle runs)
SCRIPT: dict[int, list[tuple[str, Any]]] = {
    **pulse(100, "MAS_1", Axis=1, StopType=0),
    **pulse(300, "MAJ_1", Axis=1, Direction=1, Speed=150.0, AccelRate=2000.0, DecelRate=2000.0),
    500: [("Axis2.InjectPosSoftOvertravel", True)],
    **pulse(600, "MAFR_1", Axis=2),
    **pulse(800, "MGS_1", Group=1, StopMode=1),
}


def after(rt: Runtime, slots: np.ndarray) -> np.ndarray:
    """The script from the snapshot on; the trace (one row per cycle)."""
    rows = []
    start = rt.cycle_count
    for n in range(AFTER):
        writes = SCRIPT.get(n)
        if writes:
            rt.image.write_many(writes)
        rt.cycle(1)
        rows.append(rt.image.values()[slots].copy())
    assert rt.cycle_count == start + AFTER
    return np.array(rows)


def build(site: config.SiteMap, lanes: bool | None) -> MotionSystem:
    """The site's system with the fast lanes forced on or off (None: the kernel's choice;
    the demo's four axes compose in Python then)."""
    ctl = Controller(
        site.axis_configs(), site.group_configs(), lanes=lanes, cams=site.cam_configs()
    )
    system = MotionSystem(ctl)
    for inst in site.instances():
        system.add(inst.type, inst.name, inst.operands)
    return system


@pytest.fixture(params=[None, True, False], ids=["lanes-default", "lanes-on", "lanes-off"])
def rt(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[Runtime]:
    site = demo_site(tmp_path)
    yield Runtime(site, build(site, request.param))


def test_a_restored_snapshot_runs_on_exactly_as_the_original(rt: Runtime) -> None:
    slots = traced(rt)
    before(rt)
    rt.image.write_many([("Clock.Snapshot", 7), ("Clock.SnapshotSave", True)])
    assert rt.image.read("Clock.SnapshotSave") is False  # the command bit reads 0 again
    first = after(rt, slots)
    assert rt.cycle_count == K + AFTER
    # the scenario did what it says: the slave locked, the overtravel fault came and went
    names = [rt.layout.tags[i].name for i in slots]
    col = {n: k for k, n in enumerate(names)}
    fault = first[:, col["Axis2.AxisFault"]]
    assert fault.max() > 0 and fault[-1] == 0
    assert first[:, col["MAG_1.IP"]].max() == 1.0
    assert first[-1, col["Axis1.CommandVelocity"]] == 0.0  # the group stop ended it all

    rt.image.write("Clock.SnapshotRestore", True)
    assert rt.cycle_count == K
    assert rt.image.read("Clock.Cycle") == K
    assert rt.image.read("Clock.SnapshotRestore") is False
    second = after(rt, slots)
    assert second.shape == first.shape == (AFTER, slots.size)
    differs = [
        (names[c], int(np.flatnonzero(first[:, c] != second[:, c])[0]))
        for c in range(slots.size)
        if not np.array_equal(first[:, c], second[:, c])
    ]
    assert differs == []


def test_a_snapshot_restored_after_a_restart(tmp_path: Path) -> None:
    """Saved by one server, restored by a fresh one (another process state entirely)."""
    site = demo_site(tmp_path)
    one = Runtime(site)
    slots = traced(one)
    before(one)
    one.scan.save_snapshot("mid-jog")
    first = after(one, slots)
    two = Runtime(site)
    two.scan.restore_snapshot("mid-jog")
    assert two.cycle_count == K
    second = after(two, slots)
    assert np.array_equal(first, second)


def _resign(site: config.SiteMap, path: Path, change: dict[str, Any]) -> None:
    """Change header fields and sign the file again with the installation's key (a file
    this installation made with another version, say)."""
    data = path.read_bytes()
    end = data.index(b"\n")
    head, body = json.loads(data[:end]), data[end + 1 :]
    head.update(change)
    del head["hmac"]
    key = snapshots.installation_key(site, create=False)
    head["hmac"] = snapshots._mac(key, snapshots._canonical(head), body)
    path.write_bytes(json.dumps(head).encode() + b"\n" + body)


def test_snapshots_of_another_site_map_or_version_are_refused_in_one_line(
    tmp_path: Path,
) -> None:
    site = demo_site(tmp_path)
    rt = Runtime(site)
    before(rt)
    path = rt.scan.save_snapshot("3")
    rt.cycle(10)

    def refusal(runtime: Runtime, name: str = "3") -> str:
        with pytest.raises(snapshots.SnapshotError) as err:
            runtime.scan.restore_snapshot(name)
        text = str(err.value)
        assert "\n" not in text
        assert runtime.cycle_count == K + 10  # nothing changed
        return text

    assert "no such snapshot" in refusal(rt, "4")
    # another site map: the same site name, Axis2 with another maximum velocity
    other = config.load(None)
    axes = list(other.axes)
    axes[1] = axes[1].model_copy(update={"max_velocity": 900.0})
    changed = site.model_copy(update={"axes": axes})
    rt2 = Runtime(changed)
    rt2.cycle(K + 10)
    assert "made for another site map" in refusal(rt2)
    # another version
    _resign(site, path, {"version": "0.0.1"})
    text = refusal(rt)
    assert "made with motion-server 0.0.1" in text and str(path) in text
    # a torn file
    path.write_bytes(path.read_bytes()[:-40])
    assert "truncated" in refusal(rt)


def test_a_refused_restore_over_the_clock_tags_changes_nothing(rt: Runtime) -> None:
    before(rt)
    ticket = rt.image.write_many([("Clock.Snapshot", 12), ("Clock.SnapshotRestore", True)])
    assert ticket.ack is not None and ticket.ack.result.name == "REFUSED"
    assert rt.cycle_count == K
    assert rt.image.read("Clock.SnapshotRestore") is False


def test_client_writes_are_not_kept(tmp_path: Path) -> None:
    """The old design kept every applied client write (571 B each) for as long as the
    server ran. 4,000 writes now leave no trace in the scan's memory."""
    rt = Runtime(demo_site(tmp_path))
    rt.image.write("MAJ_1.Speed", 1.0)
    rt.cycle(1)
    gc.collect()
    tracemalloc.start()
    try:
        start, _ = tracemalloc.get_traced_memory()
        for n in range(4000):  # an HMI heartbeat: one write, one cycle
            rt.image.write("MAJ_1.Speed", float(n % 7))
            rt.cycle(1)
        gc.collect()
        end, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert end - start < 4000 * 571 / 10, f"{end - start} bytes kept after 4,000 writes"


def test_a_restore_runs_no_cycle_whatever_the_history(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A restore loads the state: it costs no cycle, however long the server ran (the
    old design ran every cycle again, inside one cycle of the live scan)."""
    rt = Runtime(demo_site(tmp_path))
    before(rt)
    rt.cycle(20000)
    rt.scan.save_snapshot("long")
    calls = 0
    original = MotionSystem.cycle

    def counted(self: MotionSystem) -> None:
        nonlocal calls
        calls += 1
        original(self)

    monkeypatch.setattr(MotionSystem, "cycle", counted)
    rt.cycle(5)
    assert calls == 5
    rt.scan.restore_snapshot("long")
    assert calls == 5
    assert rt.cycle_count == K + 20000


def test_a_snapshot_at_cycle_a_billion_restores_at_once(tmp_path: Path) -> None:
    """A state at cycle 10^9 (the tick that hung the old design) restores in the time of
    any other: the cycle is a number in the state, not cycles to run."""
    rt = Runtime(demo_site(tmp_path))
    before(rt)
    state = snapshots.capture(rt.scan.system, rt.scan.watchdogs)
    body = snapshots.encode(state)
    far = snapshots.decode(rt.site, body, K)
    far.system.ctl.tick = far.tick = 10**9
    snapshots.write(rt.site, rt.layout, "far", 10**9, snapshots.encode(far))
    t0 = time.perf_counter()
    rt.scan.restore_snapshot("far")
    assert time.perf_counter() - t0 < 2.0
    assert rt.cycle_count == 10**9
    assert rt.image.read("Clock.Cycle") == 10**9
    rt.cycle(3)
    assert rt.cycle_count == 10**9 + 3
