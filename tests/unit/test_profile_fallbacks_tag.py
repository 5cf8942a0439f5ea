"""``Diagnostics.ProfileFallbacks``: the jerk-limited velocity targets the closed-form
S-curve left to ruckig (``Controller.profile_fallbacks``), a read-only UDINT of both
protocols that moved no other register of the Diagnostics block."""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.image.buffer import ImageReader
from motion_server.instructions.schema import TagType
from motion_server.kernel import Limits, scurve
from motion_server.kernel.scurve import SCurveProfile
from motion_server.scan import Scan
from motion_server.tagmap import Access, build_tagmap

SITE = """
[site]
name = "fallback_test"

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
max_deceleration = 1000.0

[[instructions.instances]]
name = "On"
type = "MSO"
operands = { Axis = 1 }

[[instructions.instances]]
name = "Jog"
type = "MAJ"
[instructions.instances.operands]
Axis = 1
Speed = 50.0
AccelRate = 1000.0
DecelRate = 1000.0
Profile = 1
AccelJerk = 20000.0
DecelJerk = 20000.0
JerkUnits = 0
"""


def test_the_tag_is_a_read_only_udint_after_ready() -> None:
    tagmap = build_tagmap(config.load())
    tag = tagmap.tag("Diagnostics.ProfileFallbacks")
    assert (tag.type, tag.access, tag.node_id) == (
        TagType.UDINT,
        Access.READ,
        "Diagnostics.ProfileFallbacks",
    )
    # Ready keeps register 72 (bit 0); the word takes the next even register, in the block
    ready = tagmap.tag("Diagnostics.Ready")
    assert (ready.address, ready.bit) == (72, 0)
    assert tag.address == 74
    block = tagmap.block("Diagnostics")
    assert block.base <= tag.address and tag.address + 2 <= block.end


def _published(scan: Scan, name: str) -> object:
    reader = ImageReader(scan.writer._buf, scan.layout.size, scan.layout.fingerprint)
    return reader.snapshot().values[scan.layout.slot(name)]


def test_a_fallback_to_ruckig_is_counted_in_the_tag(monkeypatch: pytest.MonkeyPatch) -> None:
    """A jerk-limited jog whose velocity target the closed form does not plan (every
    candidate refused, as in tests/unit/test_scurve.py) is planned by ruckig, and the
    published image counts it: one more than before the jog. A fallback counted in this
    process before the scan started is not the scan's."""
    monkeypatch.setattr(scurve, "_phases", lambda *args: None)
    earlier = scurve.FALLBACKS.count
    SCurveProfile(0.002, 5.0).to_velocity(80.0, Limits(100.0, 1000.0, 1000.0, 20_000.0))
    assert scurve.FALLBACKS.count == earlier + 1
    scan = Scan(config.parse(SITE, "fallback-test.toml"))
    scan.start(0.0)
    scan.cycle(1)
    # counted since this scan started, whatever ran before it in this process
    assert _published(scan, "Diagnostics.ProfileFallbacks") == 0
    before = 0
    scan.image.write("On.Execute", True)
    scan.cycle(1)
    scan.image.write("Jog.Execute", True)
    scan.cycle(2)
    assert scan.image.read("Jog.ER") is False
    assert scan.image.read("Diagnostics.ProfileFallbacks") == before + 1
    assert _published(scan, "Diagnostics.ProfileFallbacks") == before + 1
    # the jog runs (ruckig plans it): the axis moves forward
    scan.cycle(20)
    assert scan.ctl.axis(1).command_velocity > 0.0
