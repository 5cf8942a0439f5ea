"""The tag map: every catalog field reachable, layout rules, site-map errors, units."""

from __future__ import annotations

import itertools
from collections import defaultdict

import pytest

from motion_server import config
from motion_server.instructions import TagType, catalog
from motion_server.instructions.registry import TYPE_CODES
from motion_server.tagmap import Access, Folder, RegisterAccess, TagMap, build_tagmap

AXES = """
[[groups]]
name = "Group1"
axes = ["Axis1", "Axis2"]

[[axes]]
name = "Axis1"
type = "virtual"
units = "mm"

[[axes]]
name = "Axis2"
units = "deg"
rollover = 360.0
"""


def site_map(extra: str = "", axes: str = AXES) -> config.SiteMap:
    return config.parse(axes + extra, "site.toml")


@pytest.fixture(scope="module")
def demo() -> TagMap:
    return build_tagmap(config.load())


def test_every_catalog_field_is_in_the_map_with_its_type_and_access(demo: TagMap) -> None:
    types = catalog()
    assert {"MAJ", "MAM", "MAS", "MSO", "MC_Power", "MC_MoveAbsolute", "MC_Stop"} <= set(types)
    for type_name, cls in types.items():
        owner = f"{type_name}_1"
        expected = {op.name: (op.type, Access.READ_WRITE) for op in cls.input_operands()}
        expected |= {f.name: (f.type, Access.READ) for f in cls.status_fields()}
        tags = {t.field: t for t in demo.owned_by(owner)}
        assert set(tags) == set(expected), type_name
        for name, (tag_type, access) in expected.items():
            tag = tags[name]
            assert (tag.type, tag.access) == (tag_type, access), tag.name
            assert tag.node_id == f"Instructions.{owner}.{name}"
            assert tag.instruction == type_name
            assert tag.count == tag_type.words


def test_operand_enumerations_and_ranges_are_carried(demo: TagMap) -> None:
    direction = demo.tag("MAJ_1.Direction")
    assert direction.enum_members() == {"FORWARD": 0, "REVERSE": 1}
    assert demo.tag("MC_MoveAbsolute_1.BufferMode").enum_members() == {
        "ABORTING": 0,
        "BUFFERED": 1,
    }
    assert demo.tag("MAJ_1.Speed").minimum == 0.0
    assert demo.tag("MAJ_1.Execute").bit == 0  # the trigger is bit 0 of the command bits


def test_alignment_no_overlap_and_separate_command_and_status_bits(demo: TagMap) -> None:
    words: dict[int, str] = {}
    bit_access: dict[int, set[Access]] = defaultdict(set)
    bits_used: set[tuple[int, int]] = set()
    for t in demo:
        if t.count >= 2:
            assert t.address % 2 == 0, f"{t.name} at odd register {t.address}"
        if t.type == TagType.BOOL:
            assert t.bit is not None and 0 <= t.bit < 16
            assert (t.address, t.bit) not in bits_used
            bits_used.add((t.address, t.bit))
            bit_access[t.address].add(t.access)
            assert t.address not in words, f"{t.name} shares a register with {words[t.address]}"
            continue
        for a in range(t.address, t.end):
            assert a not in words and a not in bit_access, f"{t.name} overlaps at {a}"
            words[a] = t.name
    assert all(len(access) == 1 for access in bit_access.values())


def test_tags_sit_in_their_blocks_and_access_follows_the_region(demo: TagMap) -> None:
    for t in demo:
        # the owner's block, or its second part (an axis's configuration block)
        block = demo.block_at(t.address)
        assert block is not None and block in demo.blocks_of(t.owner), t.name
        assert block.base <= t.address and t.end <= block.end
        for a in range(t.address, t.end):
            want = RegisterAccess.READ_WRITE if t.writable else RegisterAccess.READ
            assert demo.access(a) == want, t.name
    ordered = list(demo.blocks)
    for prev, cur in itertools.pairwise(ordered):
        assert prev.end <= cur.base


def test_documented_bases_of_the_demo_map(demo: TagMap) -> None:
    assert demo.block("Clock").base == 0
    assert demo.block("Diagnostics").base == 50
    assert demo.block("Group1").base == 100
    assert [demo.block(f"Axis{k}").base for k in (1, 2, 3, 4)] == [1000, 1050, 1100, 1150]
    # the demo's <TYPE>_1 instances sit at 20000 + 100·(type code − 1), fixed per type
    for name in demo.owners(Folder.INSTRUCTIONS):
        block = demo.block(name)
        assert block.base == 20000 + 100 * (TYPE_CODES[block.instruction or ""] - 1), name
    assert demo.block("MSO_1").base == 20000
    assert demo.block("MAJ_1").base == 20500
    assert demo.block("MC_Power_1").base == 22000
    assert demo.access(999) == RegisterAccess.NONE
    assert demo.access(19999) == RegisterAccess.NONE


def test_adding_an_instruction_type_moves_no_other_registers(demo: TagMap) -> None:
    """An integrator's register table stays valid when a new type appears."""
    from motion_server.instructions import registry

    before = {t.name: t.address for t in demo}
    codes = dict(registry.TYPE_CODES)
    # the same map, with MAJ renumbered as if it were a new type at the end
    registry.TYPE_CODES["MAJ"] = max(codes.values()) + 1
    try:
        after = {t.name: t.address for t in build_tagmap(config.load())}
    finally:
        registry.TYPE_CODES.clear()
        registry.TYPE_CODES.update(codes)
    moved = {n for n in before if before[n] != after[n]}
    assert moved and all(n.startswith("MAJ_1.") for n in moved)


def test_axis_group_diagnostics_and_clock_tags(demo: TagMap) -> None:
    for name in (
        "ActualPosition",
        "CommandPosition",
        "ActualVelocity",
        "CommandVelocity",
        "CommandAcceleration",
        "PositionError",
    ):
        tag = demo.tag(f"Axis2.{name}")
        assert (tag.type, tag.access) == (TagType.LREAL, Access.READ)
    for name in ("AxisState", "PLCopenState", "MotionStatus", "AxisFault"):
        assert demo.tag(f"Axis1.{name}").access == Access.READ
    # only the hand wheel (feedback only, input signal) takes a writable feedback input
    assert demo.tag("Axis4.FeedbackInput").access == Access.READ_WRITE
    assert "Axis2.FeedbackInput" not in demo
    assert demo.tag("Axis2.ActualPosition").node_id == "Axes.Axis2.ActualPosition"
    assert demo.tag("Group1.GroupState").node_id == "Groups.Group1.GroupState"
    assert [demo.tag(f"Group1.Member{k}").field for k in (1, 2, 3, 4)] == [
        "Member1",
        "Member2",
        "Member3",
        "Member4",
    ]
    assert demo.tag("Diagnostics.Heartbeat").node_id == "Diagnostics.Heartbeat"
    for name in ("Step", "Mode", "StepCycles"):
        assert demo.tag(f"Clock.{name}").access == Access.READ_WRITE
    for name in ("Cycle", "SimTime", "Period"):
        assert demo.tag(f"Clock.{name}").access == Access.READ
    assert demo.by_node_id("Clock.Cycle").name == "Clock.Cycle"


def test_units_follow_the_axis_of_the_instance() -> None:
    m = build_tagmap(
        site_map(
            """
[[instructions.instances]]
name = "JogLinear"
type = "MAJ"

[[instructions.instances]]
name = "JogRotary"
type = "MAJ"
operands = { Axis = 2 }
"""
        )
    )
    assert m.tag("JogLinear.Speed").units == "mm/s"
    assert m.tag("JogLinear.AccelRate").units == "mm/s²"
    assert m.tag("JogLinear.AccelJerk").units == "mm/s³"
    assert m.tag("JogRotary.Speed").units == "deg/s"
    assert m.tag("Axis2.ActualPosition").units == "deg"
    assert m.tag("JogLinear.Direction").units == ""


def test_explicit_modbus_base_overrides_the_default() -> None:
    m = build_tagmap(
        site_map(
            """
[[instructions.instances]]
name = "First"
type = "MSO"

[[instructions.instances]]
name = "Placed"
type = "MAJ"
modbus_base = 20000

[[instructions.instances]]
name = "Third"
type = "MSO"
"""
        )
    )
    assert m.block("First").base == 5000
    assert m.block("Placed").base == 20000
    assert m.block("Third").base == 5200  # the default slot of Placed stays free
    assert m.tag("Placed.Execute").address >= 20000


def test_overlapping_blocks_are_a_site_map_error_naming_file_line_and_field() -> None:
    text = (
        AXES
        + """
[[instructions.instances]]
name = "First"
type = "MSO"

[[instructions.instances]]
name = "Clash"
type = "MAJ"
modbus_base = 5050
"""
    )
    with pytest.raises(config.SiteMapError) as err:
        config.parse(text, "site.toml")
    line = text.splitlines().index("modbus_base = 5050") + 1
    msg = str(err.value)
    assert msg.startswith(f"site.toml:{line}: instructions.instances.1.modbus_base:")
    assert "overlap" in msg and "First" in msg


def test_odd_modbus_base_and_clashing_names_are_errors() -> None:
    with pytest.raises(config.SiteMapError, match=r"modbus_base: .*must be even"):
        site_map('\n[[instructions.instances]]\nname = "X"\ntype = "MSO"\nmodbus_base = 6001\n')
    with pytest.raises(config.SiteMapError, match=r"instances.0.name: instance name 'Axis1'"):
        site_map('\n[[instructions.instances]]\nname = "Axis1"\ntype = "MSO"\n')
    with pytest.raises(config.SiteMapError, match=r"'Clock' is already used by the server"):
        site_map('\n[[instructions.instances]]\nname = "Clock"\ntype = "MSO"\n')


def test_remote_clock_false_makes_the_clock_read_only() -> None:
    m = build_tagmap(site_map("\n[controller]\nremote_clock = false\n"))
    assert all(t.access == Access.READ for t in m.in_folder(Folder.CLOCK))
    assert m.access(m.tag("Clock.Step").address) == RegisterAccess.READ


def test_kind_bases_come_from_the_modbus_section() -> None:
    m = build_tagmap(
        site_map(
            "\n[modbus]\naxis_base = 2000\ngroup_base = 400\ninstruction_base = 30000\n"
            '\n[[instructions.instances]]\nname = "X"\ntype = "MSO"\n'
        )
    )
    assert m.block("Group1").base == 400
    assert m.block("Axis1").base == 2000
    assert m.block("X").base == 30000


def test_owners_names_each_owner_once_in_block_order(demo: TagMap) -> None:
    # the demo's axes have more than one block each (their words and fault inputs)
    blocks = [b.owner for b in demo.blocks if b.folder == Folder.AXES]
    assert len(blocks) > len(set(blocks))
    assert demo.owners(Folder.AXES) == ["Axis1", "Axis2", "Axis3", "Axis4"]
