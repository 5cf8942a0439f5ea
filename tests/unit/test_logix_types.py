"""The tag map as Logix UDTs and tags (tagmap/logix_types.py) and their L5X export.

Numbers from Rockwell's MOTION_INSTRUCTION data type (FLAGS a DINT: EN bit 31, DN 29,
ER 28, PC 27, IP 26, AC 23) and from the Logix layout rules: members aligned to their
size (LREAL to 8), BOOLs packed eight to a hidden SINT host, the structure padded to its
largest alignment."""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET

from motion_server import config
from motion_server.tagmap import build_tagmap, export
from motion_server.tagmap.logix_types import (
    FIRST_TEMPLATE,
    STRUCT_BIT,
    CipType,
    build_logix_map,
    template_definition,
)


def demo():  # type: ignore[no-untyped-def]
    tagmap = build_tagmap(config.load())
    return tagmap, build_logix_map(tagmap)


def test_every_owner_is_one_tag_and_every_field_one_member() -> None:
    tagmap, logix = demo()
    owners = list(dict.fromkeys(t.owner for t in tagmap))
    assert [t.name for t in logix.tags] == owners
    for t in logix.tags:
        shown = {f for m in t.structure.members for f in m.fields}
        assert shown == {tag.field for tag in tagmap if tag.owner == t.name}, t.name
        assert t.structure.symbol_type == STRUCT_BIT | t.structure.instance
        assert FIRST_TEMPLATE <= t.structure.instance < 0xF00


def test_motion_instruction_bits_are_aliases_of_flags() -> None:
    _, logix = demo()
    s = logix.tag("MAG_1").structure  # type: ignore[union-attr]
    flags = s.member("FLAGS")
    assert flags is not None and flags.type == CipType.DINT and flags.offset == 0
    for name, bit in (("EN", 31), ("DN", 29), ("ER", 28), ("PC", 27), ("IP", 26), ("AC", 23)):
        m = s.member(name)
        assert m is not None and m.type == CipType.BOOL
        assert m.offset * 8 + m.bit == bit, name  # type: ignore[operator]
        assert not m.writable
    execute = s.member("Execute")
    assert execute is not None and execute.writable and execute.bit == 0
    host = [m for m in s.members if m.hidden]
    assert len(host) == 1 and host[0].offset == execute.offset and host[0].type == CipType.SINT


def test_layout_aligns_as_logix_does() -> None:
    _, logix = demo()
    for t in logix.tags:
        s = t.structure
        for m in s.members:
            if m.bit is None:
                assert m.offset % min(m.type.size, 8) == 0, (s.name, m.name)
                assert m.offset + m.size <= s.size
        widest = max([4, *(min(m.type.size, 8) for m in s.members)])
        assert s.size % widest == 0
    axis = logix.tag("Axis2").structure  # type: ignore[union-attr]
    assert axis.member("ActualPosition").type == CipType.LREAL  # type: ignore[union-attr]
    cam = logix.tag("Cam1").structure  # type: ignore[union-attr]
    master = cam.member("Master")
    assert master is not None and master.length == 16 and master.type == CipType.REAL


def test_template_definition_is_what_pycomm3_and_pylogix_parse() -> None:
    _, logix = demo()
    s = logix.tag("MAG_1").structure  # type: ignore[union-attr]
    raw = template_definition(s)
    assert len(raw) % 4 == 0
    n = len(s.members)
    info, ctype, offset = struct.unpack_from("<HHI", raw, 8 * 2)  # the third member: DN
    assert (s.members[2].name, info, ctype, offset) == ("DN", 5, 0xC1, 3)
    names = raw[8 * n :].split(b"\x00")
    head, access = names[0].split(b";", 1)
    assert head == b"MS_MAG" and access[:1] == b"n" and len(access) == 1 + 2 * n
    assert [x.decode() for x in names[1 : n + 1]] == [m.name for m in s.members]


def test_l5x_export_declares_the_same_types() -> None:
    tagmap, logix = demo()
    root = ET.fromstring(export(tagmap, "l5x"))
    types = root.findall("./Controller/DataTypes/DataType")
    assert [t.get("Name") for t in types] == [s.name for s in logix.structures]
    mag = next(t for t in types if t.get("Name") == "MS_MAG")
    dn = mag.find("./Members/Member[@Name='DN']")
    assert dn is not None and dn.get("DataType") == "BIT"
    assert (dn.get("Target"), dn.get("BitNumber")) == ("FLAGS", "29")
    assert dn.get("ExternalAccess") == "Read Only"
    ratio = mag.find("./Members/Member[@Name='Ratio']")
    assert ratio is not None and ratio.get("ExternalAccess") == "Read/Write"
    tags = root.findall("./Controller/Tags/Tag")
    assert [(t.get("Name"), t.get("DataType")) for t in tags] == [
        (t.name, t.structure.name) for t in logix.tags
    ]
