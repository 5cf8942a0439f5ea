"""``[[cams]]`` in the site map: defaults, the register layout computed by hand from the
documented formula, and one error per bad field naming file, line and field.

The formula (tagmap/layout.py, docs/modbus.md): tables from ``[modbus] cam_base`` (default
30000) in ``[[cams]]`` order, each block 8 + 6·capacity registers rounded up to a multiple
of 100; in a block at B: ProfileStatus B, Capacity B+2, Number B+4 (read-only), Length
B+6, element k's Master B+8+6k, Slave B+10+6k, SegmentType B+12+6k (writable).
"""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.config import SiteMapError
from motion_server.instructions.schema import TagType
from motion_server.safety.roles import Role, RoleRegisters, required_role
from motion_server.tagmap import Access, build_tagmap
from motion_server.tagmap.image import TagImage

HEAD = """
[[groups]]
name = "Group1"
axes = ["Axis1"]

[[axes]]
name = "Axis1"
"""


def parse(text: str) -> config.SiteMap:
    return config.parse(HEAD + text, "cams.toml")


def test_defaults_number_capacity_and_length_follow_the_points() -> None:
    site = parse(
        """
[[cams]]
name = "A"
points = [[0, 0, 0], [1, 2, 1], [2, 3, 0]]

[[cams]]
name = "B"

[[cams]]
name = "C"
number = 7
capacity = 10
length = 4
"""
    )
    a, b, c = site.cam_configs()
    assert (a.number, a.capacity, a.length) == (1, 3, 3)
    assert (b.number, b.capacity, b.length, b.points) == (2, 2, 0, ())
    assert (c.number, c.capacity, c.length) == (7, 10, 4)
    table = site.build().ctl.cams.tables[1]
    assert (table.master, table.slave, table.segment) == (
        [0.0, 1.0, 2.0],
        [0.0, 2.0, 3.0],
        [0, 1, 0],
    )


def test_initial_points_are_reals() -> None:
    # 0.1 is no float32: the table holds the REAL a client reading the tag sees
    site = parse('[[cams]]\nname = "A"\npoints = [[0, 0.1, 0], [1, 1, 0]]\n')
    assert site.build().ctl.cams.tables[1].slave[0] == 0.10000000149011612


def test_the_layout_is_the_documented_formula() -> None:
    site = parse(
        """
[[cams]]
name = "Cam1"
capacity = 16

[[cams]]
name = "Cam2"
capacity = 3
number = 9
"""
    )
    tm = build_tagmap(site)
    # Cam1: 8 + 96 = 104 registers -> 200; Cam2 at 30200 (8 + 18 = 26 -> 100)
    assert (tm.block("Cam1").base, tm.block("Cam1").end) == (30000, 30200)
    assert (tm.block("Cam2").base, tm.block("Cam2").end) == (30200, 30300)
    expected = {
        "Cam1.ProfileStatus": (30000, Access.READ, TagType.DINT),
        "Cam1.Capacity": (30002, Access.READ, TagType.DINT),
        "Cam1.Number": (30004, Access.READ, TagType.DINT),
        "Cam1.Length": (30006, Access.READ_WRITE, TagType.DINT),
        "Cam1.Master[0]": (30008, Access.READ_WRITE, TagType.REAL),
        "Cam1.Slave[0]": (30010, Access.READ_WRITE, TagType.REAL),
        "Cam1.SegmentType[0]": (30012, Access.READ_WRITE, TagType.DINT),
        "Cam1.Master[15]": (30098, Access.READ_WRITE, TagType.REAL),
        "Cam1.SegmentType[15]": (30102, Access.READ_WRITE, TagType.DINT),
        "Cam2.Length": (30206, Access.READ_WRITE, TagType.DINT),
        "Cam2.Slave[2]": (30222, Access.READ_WRITE, TagType.REAL),
    }
    for name, (address, access, tag_type) in expected.items():
        tag = tm.tag(name)
        assert (tag.address, tag.access, tag.type, tag.count) == (address, access, tag_type, 2)
        assert tag.node_id == f"Cams.{name}"
    assert len(tm.owned_by("Cam1")) == 4 + 3 * 16
    image = TagImage(tm, site.build())
    assert [image.read(f"Cam{n}.{f}") for n in (1, 2) for f in ("Capacity", "Number")] == [
        16,
        1,
        3,
        9,
    ]


def test_cam_base_moves_the_tables_and_past_other_blocks_by_default() -> None:
    tm = build_tagmap(parse('[modbus]\ncam_base = 40000\n\n[[cams]]\nname = "A"\n'))
    assert tm.tag("A.Master[1]").address == 40000 + 8 + 6
    # 260 declared instances reach 5000 + 100·260 = 31000: the tables go to the next 1000
    many = "".join(
        f'[[instructions.instances]]\nname = "MSO_{k}"\ntype = "MSO"\n\n' for k in range(260)
    )
    tm = build_tagmap(parse(many + '[[cams]]\nname = "A"\n'))
    assert tm.block("A").base == 31000


BAD: list[tuple[str, str, str]] = [
    ('[[cams]]\nname = "1x"\n', "cams.0.name", "should match pattern"),
    ('[[cams]]\nname = "A"\n\n[[cams]]\nname = "A"\n', "cams.1.name", "duplicate name 'A'"),
    ('[[cams]]\nname = "A"\n\n[[cams]]\nname = "B"\nnumber = 1\n', "cams.1.number", "taken"),
    ('[[cams]]\nname = "A"\nnumber = 0\n', "cams.0.number", "greater than or equal to 1"),
    ('[[cams]]\nname = "A"\ncapacity = 1\n', "cams.0.capacity", "greater than or equal to 2"),
    ('[[cams]]\nname = "A"\ncapacity = 1001\n', "cams.0.capacity", "less than or equal to 1000"),
    (
        '[[cams]]\nname = "A"\ncapacity = 2\npoints = [[0, 0, 0], [1, 1, 0], [2, 2, 0]]\n',
        "cams.0.capacity",
        "3 points do not fit 2",
    ),
    ('[[cams]]\nname = "A"\nlength = 1\n', "cams.0.length", "greater than or equal to 2"),
    (
        '[[cams]]\nname = "A"\ncapacity = 4\nlength = 5\n',
        "cams.0.length",
        "5 exceeds its capacity 4",
    ),
    ('[[cams]]\nname = "A"\npoints = [[0, 0]]\n', "cams.0.points.0", "is not a point"),
    ('[[cams]]\nname = "A"\npoints = [[0, "1", 0]]\n', "cams.0.points.0.1", "valid number"),
    ('[[cams]]\nname = "A"\npoints = [[0, 1, 0.5]]\n', "cams.0.points.0.2", "valid integer"),
    ('[[cams]]\nname = "A"\npoints = [[inf, 1, 0]]\n', "cams.0.points.0.0", "finite"),
    ('[[cams]]\nname = "A"\npoints = [[1e39, 1, 0]]\n', "cams.0.points.0.0", "outside"),
    ('[[cams]]\nname = "A"\npoints = [[0, 1, 4294967296]]\n', "cams.0.points.0.2", "less than"),
    ('[[cams]]\nname = "Axis1"\n', "cams.0.name", "already used by axis"),
    ('[modbus]\ncam_base = 30001\n[[cams]]\nname = "A"\n', "modbus.cam_base", "multiple of 2"),
    ('[modbus]\ncam_base = 1000\n[[cams]]\nname = "A"\n', "modbus.cam_base", "overlap"),
    ('[[cams]]\nname = "A"\nsize = 3\n', "cams.0.size", "Extra inputs"),
]


@pytest.mark.parametrize(("text", "field", "message"), BAD, ids=[f for _, f, _ in BAD])
def test_each_bad_field_is_named_with_its_line(text: str, field: str, message: str) -> None:
    with pytest.raises(SiteMapError) as info:
        parse(text)
    lines = str(info.value).splitlines()
    hit = [line for line in lines if f": {field}: " in line]
    assert hit, lines
    assert message in hit[0]
    # cams.toml:<line>: the line of the entry (the HEAD takes 7 lines)
    file, line = hit[0].split(":")[:2]
    assert file == "cams.toml" and int(line) > 7


def test_operators_write_the_points_viewers_do_not() -> None:
    tm = build_tagmap(parse('[[cams]]\nname = "A"\ncapacity = 2\n'))
    registers = RoleRegisters(tm)
    # Length and element 0 (30006..30013): the whole writable part but for element 1
    assert registers.write_refused(Role.OPERATOR, 30006, 8) is None
    assert registers.write_refused(Role.VIEWER, 30006, 8) == "role viewer may not write"
    assert all(required_role(t) == Role.OPERATOR for t in tm.owned_by("A") if t.writable)
