"""The scan's image of the cam tables: ProfileStatus is read every cycle, the points only
when a client writes them (a table of 1,000 points is 3,000 values nothing else changes:
reading them every cycle would cost the scan milliseconds), and at a full refill."""

from __future__ import annotations

from motion_server import config
from motion_server.image.layout import ImageLayout
from motion_server.scan.filler import ImageFiller
from motion_server.tagmap import build_tagmap
from motion_server.tagmap.image import TagImage

SITE = """
[[groups]]
name = "Group1"
axes = ["Axis1"]

[[axes]]
name = "Axis1"

[[cams]]
name = "Cam1"
capacity = 3
points = [[0, 0, 0], [10, 5, 0]]
"""


def test_profile_status_every_cycle_points_when_written() -> None:
    site = config.parse(SITE, "cams.toml")
    tagmap = build_tagmap(site)
    system = site.build()
    image = TagImage(tagmap, system)
    layout = ImageLayout(tagmap)
    filler = ImageFiller(image, layout)
    filler.fill_all()
    values = filler.values
    status, slave1 = layout.slot("Cam1.ProfileStatus"), layout.slot("Cam1.Slave[1]")
    assert (values[status], values[slave1]) == (0.0, 5.0)

    system.ctl.cams.calculate(1, 0, 2, 0.0, 0.0, 1)
    system.cycle()
    filler.fill()
    assert values[status] == 2.0

    written = tagmap.tag("Cam1.Slave[1]")
    image.write(written, 6.0)
    filler.refresh([written])
    assert values[slave1] == 6.0 and system.ctl.cams.tables[1].slave[1] == 6.0

    # nothing but a write changes a point: a cycle does not read them again
    system.ctl.cams.tables[1].slave[1] = 7.0
    system.cycle()
    filler.fill()
    assert values[slave1] == 6.0
    filler.fill_all()
    assert values[slave1] == 7.0
