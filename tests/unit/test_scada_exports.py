"""Exports for SCADA and HMI tools: the KEPServerEX tag CSV, the Ignition tag JSON, the
bit layouts of the packed words, the axis configuration tags and the NodeSet2 export
against the official UANodeSet.xsd.

Vendor documents followed (see docs/scada.md): KEPServerEX server help, "CSV
Import/Export" (the tag CSV's heading record; Client Access RO / R/W), KEPServerEX Modbus
TCP/IP Ethernet driver addresses (``4xxxxx``, ``4xxxxx.bb`` for bit ``bb`` 0-15); Ignition
8.1 documentation, "Tag Properties" (tagType, valueSource, opcServer, opcItemPath,
dataType, engUnit, engLow, engHigh, readOnly, documentation, tooltip) and "Tag Data Types"
(Int1, Int2, Int4, Int8, Float4, Float8, Boolean, ...). Bit numbers: the MOTION_INSTRUCTION
word of the Logix seeds (EN 31, DN 29, ER 28, PC 27, IP 26, AC 23).
"""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import pytest

from motion_server import config
from motion_server.kernel import AxisFault, ProgrammedStopMode
from motion_server.safety.watchdog import WATCHDOG_FAULT
from motion_server.tagmap import TagMap, TagType, build_tagmap, export, to_dict
from motion_server.tagmap.cams import cam_tables, scada_name
from motion_server.tagmap.image import StandaloneHost, TagImage, is_static

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES_MAP = ROOT / "clients" / "examples" / "bench.toml"
XSD = ROOT / "tests/interop/node_opcua/node_modules/node-opcua-nodesets/nodesets/UANodeSet.xsd"
KEPWARE_HEADING = [
    "Tag Name",
    "Address",
    "Data Type",
    "Respect Data Type",
    "Client Access",
    "Scan Rate",
    "Scaling",
    "Raw Low",
    "Raw High",
    "Scaled Low",
    "Scaled High",
    "Scaled Data Type",
    "Clamp Low",
    "Clamp High",
    "Eng Units",
    "Description",
]
#: KEPServerEX Modbus data types and the registers each takes
KEPWARE_WORDS = {
    "Boolean": 1,
    "Short": 1,
    "Word": 1,
    "Long": 2,
    "DWord": 2,
    "Float": 2,
    "Double": 4,
}
IGNITION_TYPES = {"Boolean", "Int1", "Int2", "Int4", "Int8", "Float4", "Float8", "String"}


@pytest.fixture(scope="module")
def demo() -> TagMap:
    return build_tagmap(config.load(environ={}))


def test_kepware_csv_has_the_heading_record_and_addresses_of_the_driver(demo: TagMap) -> None:
    rows = list(csv.reader(io.StringIO(export(demo, "kepware"))))
    assert rows[0] == KEPWARE_HEADING
    by_name = {r[0]: dict(zip(KEPWARE_HEADING, r, strict=True)) for r in rows[1:]}
    # a cam element's brackets become an underscore (Cam1.Master[3] -> Cam1.Master_3)
    assert set(by_name) == {f"{t.owner}.{scada_name(t.field)}" for t in demo}
    assert not any("[" in name or "]" in name for name in by_name)
    assert by_name["Cam1.Master_3"]["Address"] == f"4{demo.tag('Cam1.Master[3]').address + 1:05d}"
    for tag in demo:
        row = by_name[f"{tag.owner}.{scada_name(tag.field)}"]
        m = re.fullmatch(r"4(\d{5})(?:\.(\d{1,2}))?", row["Address"])
        assert m is not None, row
        assert int(m.group(1)) == tag.address + 1  # 400001 is register 0
        assert (m.group(2) is not None) == (tag.type == TagType.BOOL)
        if m.group(2) is not None:
            assert int(m.group(2)) == tag.bit and 0 <= tag.bit <= 15
        assert KEPWARE_WORDS[row["Data Type"]] == tag.count
        assert row["Client Access"] == ("R/W" if tag.writable else "RO")
        assert row["Respect Data Type"] == "1" and row["Scan Rate"] == "100"
        assert len(row["Description"]) <= 255
    speed = by_name["MAJ_1.Speed"]
    # MAJ_1.Speed: register 20512 (test_tagmap_export), a REAL in mm/s
    assert (speed["Address"], speed["Data Type"], speed["Eng Units"]) == ("420513", "Float", "mm/s")
    assert by_name["MAJ_1.Execute"]["Address"] == "420507.0"
    assert "bits: 23=AC; 26=IP; 27=PC; 28=ER; 29=DN; 31=EN" in by_name["MAJ_1.FLAGS"]["Description"]


def _atomic(node: dict, path: str = "") -> list[tuple[str, dict]]:
    if node["tagType"] == "Folder":
        assert set(node) == {"name", "tagType", "tags"}
        out: list[tuple[str, dict]] = []
        for child in node["tags"]:
            out += _atomic(child, f"{path}/{node['name']}")
        return out
    return [(f"{path}/{node['name']}", node)]


def test_ignition_json_is_a_tag_tree_of_opc_tags(demo: TagMap) -> None:
    root = json.loads(export(demo, "ignition"))
    assert (root["name"], root["tagType"]) == ("motion-server-demo", "Folder")
    tags = _atomic(root)
    # every tag, and the three array views of each cam table
    cams = cam_tables(demo)
    assert len(tags) == len(demo) + 3 * len(cams)
    by_path = {t["opcItemPath"]: t for _, t in tags}
    for cam in cams:
        for view in cam.views:
            rec = by_path[f"nsu=urn:motion-server:demo;s={view.node_id}"]
            assert rec["dataType"] == (
                "Int4Array" if view.field == "SegmentType" else "Float4Array"
            )
            assert rec["readOnly"] is False
    for tag in demo:
        rec = by_path[f"nsu=urn:motion-server:demo;s={tag.node_id}"]
        assert rec["tagType"] == "AtomicTag" and rec["valueSource"] == "opc"
        assert rec["opcServer"] == "motion-server"
        assert rec["name"] == scada_name(tag.field)
        assert "[" not in rec["name"]
        assert rec["dataType"] in IGNITION_TYPES
        assert rec["readOnly"] is (not tag.writable)
        if "engLow" in rec:
            assert rec["engLow"] <= rec["engHigh"]
    speed = by_path["nsu=urn:motion-server:demo;s=Instructions.MAJ_1.Speed"]
    assert (speed["dataType"], speed["engUnit"], speed["engLow"], speed["engHigh"]) == (
        "Float4",
        "mm/s",
        0.0,
        500.0,  # Axis1's max_velocity in the demo map
    )
    paths = {p for p, _ in tags}
    assert "/motion-server-demo/Instructions/MAJ_1/Speed" in paths
    assert "/motion-server-demo/Clock/Cycle" in paths
    direction = by_path["nsu=urn:motion-server:demo;s=Instructions.MAJ_1.Direction"]
    assert "values: 0=FORWARD; 1=REVERSE" in direction["documentation"]


def test_every_packed_word_lists_its_bits(demo: TagMap) -> None:
    data = to_dict(demo)
    words = {(w["address"], w["kind"]): w for w in data["packed_words"]}
    flags = words[(demo.tag("MAJ_1.FLAGS").address, "FLAGS")]
    assert flags["tag"] == "MAJ_1.FLAGS"
    assert flags["bits"] == {"23": "AC", "26": "IP", "27": "PC", "28": "ER", "29": "DN", "31": "EN"}
    status = words[(demo.tag("MAJ_1.EN").address, "status bits")]
    assert status["access"] == "read"
    assert [status["bits"][str(demo.tag(f"MAJ_1.{n}").bit)] for n in ("EN", "DN", "ER")] == [
        "EN",
        "DN",
        "ER",
    ]
    command = words[(demo.tag("MAJ_1.Execute").address, "command bits")]
    assert command["access"] == "read_write" and command["bits"] == {"0": "Execute"}
    fault = words[(demo.tag("Axis2.AxisFault").address, "AxisFault")]
    assert fault["bits"] == {
        str(AxisFault.POSITION_ERROR.bit_length() - 1): "PositionError",
        str(AxisFault.PROFILE.bit_length() - 1): "Profile",
        str(WATCHDOG_FAULT.bit_length() - 1): "CommunicationWatchdog",
        str(AxisFault.NUMERIC.bit_length() - 1): "Numeric",
        str(AxisFault.DRIVE.bit_length() - 1): "DriveFault",
        str(AxisFault.FEEDBACK.bit_length() - 1): "FeedbackFault",
        str(AxisFault.POS_HARD_OVERTRAVEL.bit_length() - 1): "PosHardOvertravel",
        str(AxisFault.NEG_HARD_OVERTRAVEL.bit_length() - 1): "NegHardOvertravel",
        str(AxisFault.POS_SOFT_OVERTRAVEL.bit_length() - 1): "PosSoftOvertravel",
        str(AxisFault.NEG_SOFT_OVERTRAVEL.bit_length() - 1): "NegSoftOvertravel",
    }
    servo = words[(demo.tag("Axis2.ServoFault").address, "ServoFault")]
    # the Logix ServoFaultBits attribute (Rockwell MOTION-RM002)
    assert servo["bits"] == {
        "0": "PosSoftOvertravelFault",
        "1": "NegSoftOvertravelFault",
        "2": "PosHardOvertravelFault",
        "3": "NegHardOvertravelFault",
        "4": "FeedbackFault",
        "8": "PositionErrorFault",
        "9": "DriveFault",
    }
    motion = words[(demo.tag("Axis2.MotionStatus").address, "MotionStatus")]
    assert motion["bits"]["12"] == "GearingLock" and motion["bits"]["4"] == "Gearing"
    # every BOOL sits in a listed register, every listed bit is a BOOL or a documented bit
    bools = {(t.address, t.bit) for t in demo if t.type == TagType.BOOL}
    listed = {
        (w["address"], int(n)) for w in data["packed_words"] if "tag" not in w for n in w["bits"]
    }
    assert listed == bools
    md = export(demo, "md")
    assert "- Bits of `MAJ_1.FLAGS` (register 20502–20503): 23 AC, 26 IP" in md
    assert "- Bits of command bits (register 20506): 0 Execute." in md
    assert "(bit numbers below)" not in md
    rows = {r["name"]: r for r in csv.DictReader(io.StringIO(export(demo, "csv")))}
    assert rows["MAJ_1.FLAGS"]["bits"] == "23=AC; 26=IP; 27=PC; 28=ER; 29=DN; 31=EN"


def test_axis_configuration_tags_are_static_read_only_values_of_the_site_map(
    demo: TagMap,
) -> None:
    site = config.load(environ={})
    system = site.build()
    image = TagImage(demo, system, StandaloneHost(system))
    # demo.toml: Axis2 1000 counts/mm, 1000 mm/s, 20000 mm/s², fast_disable, 500 mm/s²
    # coast, 10 mm limit; Axis3 360° rollover; units mm and deg (UNECE MMT 5066068, DD 17476)
    expect = {
        "Axis2.ConversionConstant": 1000.0,
        "Axis2.MaxVelocity": 1000.0,
        "Axis2.MaxAcceleration": 20000.0,
        "Axis2.MaxDeceleration": 20000.0,
        "Axis2.MaxJerk": 0.0,
        "Axis2.ProgrammedStopMode": int(ProgrammedStopMode.FAST_DISABLE),
        "Axis2.CoastDeceleration": 500.0,
        "Axis2.FollowingErrorLimit": 10.0,
        "Axis2.Rollover": 0.0,
        "Axis2.PositionUnits": 5066068,
        "Axis3.Rollover": 360.0,
        "Axis3.PositionUnits": 17476,
    }
    for name, value in expect.items():
        tag = demo.tag(name)
        assert image.read(tag) == value, name
        assert not tag.writable and is_static(tag), name
        block = demo.block_at(tag.address)
        assert block is not None and block.part == "configuration" and block.owner == tag.owner
    assert demo.block_at(demo.tag("Axis1.ConversionConstant").address).base == 3000  # type: ignore[union-attr]
    assert "Axis1.ActualPositionREAL" not in demo  # mirrors only when asked for


def test_real_mirrors_copy_the_lreal_axis_values() -> None:
    site = config.load(environ={})
    site = site.model_copy(update={"modbus": site.modbus.model_copy(update={"real_mirrors": True})})
    tagmap = build_tagmap(site)
    system = site.build()
    image = TagImage(tagmap, system, StandaloneHost(system))
    system.ctl.set_feedback_input(system.ctl.axis("Axis4"), 12.25)
    system.cycle()
    for source in ("ActualPosition", "CommandPosition", "ActualVelocity", "PositionError"):
        mirror = tagmap.tag(f"Axis4.{source}REAL")
        assert mirror.type == TagType.REAL and not mirror.writable
        assert image.read(mirror) == image.read(f"Axis4.{source}")
    words = image.read_registers(tagmap.tag("Axis4.ActualPositionREAL").address, 2)
    assert words == [0x4144, 0x0000]  # 12.25 as IEEE 754 binary32: 0x41440000


@pytest.mark.skipif(not XSD.is_file(), reason="UANodeSet.xsd missing (make test runs npm ci)")
@pytest.mark.parametrize("site_map", [None, EXAMPLES_MAP])
def test_the_nodeset_export_validates_against_the_official_schema(
    site_map: Path | None, tmp_path: Path
) -> None:
    import xmlschema

    schema = xmlschema.XMLSchema(str(XSD))
    text = export(build_tagmap(config.load(site_map, environ={})), "nodeset")
    path = tmp_path / "export.xml"
    path.write_text(text, "utf-8")
    errors = [f"{e.path}: {e.reason}" for e in schema.iter_errors(str(path))]
    assert errors == []
    assert "<Models>" in text and "<UAObjectType " in text
