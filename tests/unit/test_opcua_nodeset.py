"""The NodeSet2 export of the demo map (``motion-server map --format nodeset``, checked
in as maps/demo-nodeset.xml): well-formed XML that declares every tag's node with the
DataType the design gives its type, and that an OPC UA server can import.

Standard DataType node ids (OPC UA Part 6, namespace 0): Boolean i=1, SByte i=2,
Int16 i=4, Int32 i=6, UInt32 i=7, Float i=10, Double i=11. Access levels: CurrentRead
= 1, CurrentRead | CurrentWrite = 3.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from asyncua import Server, ua

from motion_server import config
from motion_server.frontends.opcua_models import load_companions
from motion_server.tagmap import TagMap, TagType, build_tagmap, export

NS = {"u": "http://opcfoundation.org/UA/2011/03/UANodeSet.xsd"}
STANDARD_TYPE = {
    TagType.BOOL: ("Boolean", 1),
    TagType.SINT: ("SByte", 2),
    TagType.INT: ("Int16", 4),
    TagType.DINT: ("Int32", 6),
    TagType.UDINT: ("UInt32", 7),
    TagType.REAL: ("Float", 10),
    TagType.LREAL: ("Double", 11),
}
STORED = Path(__file__).resolve().parents[2] / "maps" / "demo-nodeset.xml"


@pytest.fixture(scope="module")
def demo() -> TagMap:
    return build_tagmap(config.load())


def test_every_tag_is_declared_with_its_data_type_and_access(demo: TagMap) -> None:
    root = ET.fromstring(export(demo, "nodeset"))  # raises on malformed XML
    assert root.tag == f"{{{NS['u']}}}UANodeSet"
    uris = [u.text for u in root.findall("u:NamespaceUris/u:Uri", NS)]
    # the site's namespace first (ns=1 in the file), then PLCopen's (its types' supertype)
    assert uris == ["urn:motion-server:demo", "http://PLCopen.org/OpcUa/IEC61131-3/"]
    aliases = {a.get("Alias"): a.text for a in root.findall("u:Aliases/u:Alias", NS)}
    variables = {v.get("NodeId"): v for v in root.findall("u:UAVariable", NS)}
    objects = root.findall("u:UAObject", NS) + root.findall("u:UAObjectType", NS)
    declared = set(variables) | {o.get("NodeId") for o in objects}
    tags = list(demo)
    assert len(tags) > 100
    for tag in tags:
        var = variables.get(f"ns=1;s={tag.node_id}")
        assert var is not None, tag.node_id
        name, number = STANDARD_TYPE[tag.type]
        data_type = var.get("DataType")
        assert data_type == name, tag.node_id
        assert aliases[data_type] == f"i={number}"
        assert var.get("AccessLevel") == ("3" if tag.writable else "1"), tag.node_id
        assert var.get("BrowseName") == f"1:{tag.node_id.rsplit('.', 1)[1]}"
        parent = var.get("ParentNodeId")
        assert parent in declared, (tag.node_id, parent)
    assert {v.get("ParentNodeId") for v in variables.values()} <= declared


def test_the_checked_in_nodeset_is_the_demo_export(demo: TagMap) -> None:
    assert STORED.read_text("utf-8") == export(demo, "nodeset"), "run `make maps`"


async def test_an_opc_ua_server_imports_it(demo: TagMap) -> None:
    server = Server()
    await server.init()
    try:
        await load_companions(server)  # the nodesets it requires: DI, PLCopen
        await server.import_xml(str(STORED))
        ns = await server.get_namespace_index("urn:motion-server:demo")
        for tag in (demo.tag("MAJ_1.Speed"), demo.tag("MAJ_1.DN"), demo.tag("Clock.Cycle")):
            node = server.get_node(ua.NodeId(tag.node_id, ns))
            assert (await node.read_data_type()).Identifier == STANDARD_TYPE[tag.type][1]
        speed = server.get_node(ua.NodeId("Instructions.MAJ_1.Speed", ns))
        eu = await (await speed.get_child("0:EngineeringUnits")).read_value()
        assert eu.DisplayName.Text == "mm/s"
        eu_range = await (await speed.get_child("0:EURange")).read_value()
        assert eu_range.Low == 0.0 < eu_range.High  # Speed >= 0
        direction = server.get_node(ua.NodeId("Instructions.MAJ_1.Direction", ns))
        values = await (await direction.get_child("0:EnumValues")).read_value()
        assert [(v.Value, v.DisplayName.Text) for v in values] == [(0, "FORWARD"), (1, "REVERSE")]
    finally:
        await server.stop()
