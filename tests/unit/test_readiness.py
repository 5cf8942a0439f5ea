"""``Diagnostics.Ready``: 1 while the scan runs, 0 while it starts, stops or has stopped;
a BOOL of both protocols that moved no register of the Diagnostics block."""

from __future__ import annotations

from motion_server import config
from motion_server.image.buffer import ImageReader, ScanState
from motion_server.instructions.schema import TagType
from motion_server.runtime import Runtime
from motion_server.scan import Scan
from motion_server.tagmap import Access, build_tagmap

SITE = """
[site]
name = "ready_test"

[controller]
clock = "manual"
status_log_interval = 0.0

[[groups]]
name = "Group1"
axes = ["Axis1"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 100.0
max_acceleration = 1000.0
max_deceleration = 100.0

[[instructions.instances]]
name = "On"
type = "MSO"
operands = { Axis = 1 }

[[instructions.instances]]
name = "Jog"
type = "MAJ"
operands = { Axis = 1, Speed = 100.0, AccelRate = 1000.0, DecelRate = 100.0 }
"""


def site() -> config.SiteMap:
    return config.parse(SITE, "ready-test.toml")


def test_ready_is_a_read_only_bool_after_the_diagnostics_words() -> None:
    tagmap = build_tagmap(config.load())
    ready = tagmap.tag("Diagnostics.Ready")
    assert (ready.type, ready.access, ready.node_id) == (
        TagType.BOOL,
        Access.READ,
        "Diagnostics.Ready",
    )
    # the words keep the registers the map documented before Ready existed
    # (maps/demo-map.md: Heartbeat 50-51 ... FrontendRestarts 70-71)
    words = {
        "Heartbeat": 50,
        "CycleTime": 52,
        "MaxCycleTime": 54,
        "Overruns": 56,
        "DroppedCycles": 58,
        "VersionMajor": 60,
        "VersionMinor": 61,
        "VersionPatch": 62,
        "AxisCount": 63,
        "GroupCount": 64,
        "InstanceCount": 65,
        "ScanLoad": 66,
        "QueuedWrites": 68,
        "FrontendRestarts": 70,
    }
    assert {f: tagmap.tag(f"Diagnostics.{f}").address for f in words} == words
    # the next free register, bit 0, still inside the block (50-99)
    assert (ready.address, ready.bit) == (72, 0)
    assert tagmap.block("Diagnostics").base <= ready.address < tagmap.block("Diagnostics").end


def _published_ready(scan: Scan) -> bool:
    reader = ImageReader(scan.writer._buf, scan.layout.size, scan.layout.fingerprint)
    snap = reader.snapshot()
    return bool(snap.values[scan.layout.slot("Diagnostics.Ready")])


def test_ready_follows_the_scan_from_start_to_stop() -> None:
    scan = Scan(site())
    assert scan.state == ScanState.STARTING and not scan.ready
    assert scan.image.read("Diagnostics.Ready") is False
    scan.start(0.0)
    # the manual clock runs no cycle by itself: the first image already says ready
    assert scan.ctl.tick == 0
    assert _published_ready(scan)
    scan.cycle(3)
    assert _published_ready(scan)
    # a jog in progress makes the programmed stop take cycles: a fast stop at the axis's
    # 100 mm/s² from 100 mm/s takes 1 s = 500 cycles of 2 ms (the scan runs 50 a pass)
    scan.image.write("On.Execute", True)
    scan.cycle(1)
    scan.image.write("Jog.Execute", True)
    scan.cycle(60)
    assert scan.ctl.axis(1).command_velocity == 100.0
    scan.request_stop()
    scan.service(1.0)
    assert scan.state == ScanState.STOPPING
    assert not _published_ready(scan)
    passes = 1
    while not scan.finished:
        assert not _published_ready(scan)
        scan.service(1.0)
        passes += 1
    assert passes >= 500 // 50
    assert scan.ctl.axis(1).command_velocity == 0.0
    assert not _published_ready(scan)


def test_ready_falls_at_once_when_nothing_has_to_stop() -> None:
    """No motion: the programmed stop takes no cycle, and the last image says 0."""
    scan = Scan(site())
    scan.start(0.0)
    assert _published_ready(scan)
    scan.request_stop()
    while not scan.finished:
        scan.service(1.0)
    assert not _published_ready(scan)


def test_the_standalone_host_and_the_runtime_are_ready() -> None:
    rt = Runtime(site())
    assert rt.image.read("Diagnostics.Ready") is True
