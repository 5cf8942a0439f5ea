"""Load the official companion nodesets (DI, PLCopen) into an asyncua server.

The files are the OPC Foundation's, unmodified on disk (:mod:`motion_server.tagmap.companion`
checks their SHA-256). asyncua's importer cannot add an Object or Variable without a
parent: its AddNodes answers ``BadParentNodeIdInvalid`` (asyncua 2.1,
``XmlImporter._add_node_data``) and the whole import stops. The published files hold such
nodes: DI's ``DesignToolOnly`` objects (Configuration, Tuning, ...: OPC 10000-6 F.3 says a
server does not import them), PLCopen's free-standing property declarations
(SubrangeMin, ..., CONSTANT, AT) and the ``<TaskName>`` placeholder that
CtrlProgramOrganizationUnitType points at with the non-hierarchical ``With`` reference. So
before importing, this adapter drops the Objects and Variables that have neither a
``ParentNodeId`` nor an inverse reference, and the references to them; nothing motion-server
uses is among them. node-opcua's loader (the interop test) loads the files as published.
"""

from __future__ import annotations

import functools
import logging
import xml.etree.ElementTree as ET

from asyncua import Server

from ..tagmap.companion import LOAD_ORDER, nodeset_text

NODESET_NS = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
_INSTANCES = (f"{NODESET_NS}UAObject", f"{NODESET_NS}UAVariable", f"{NODESET_NS}UAMethod")


@functools.cache
def asyncua_importable(uri: str) -> str:
    """The companion nodeset ``uri`` without the parentless nodes asyncua cannot add."""
    text = nodeset_text(uri)
    root = ET.fromstring(text)
    orphans: set[str] = set()
    for node in root:
        if node.tag not in _INSTANCES or node.get("ParentNodeId"):
            continue
        refs = node.iter(f"{NODESET_NS}Reference")
        if not any(r.get("IsForward", "true").lower() == "false" for r in refs):
            orphans.add(node.get("NodeId", ""))
    if not orphans:
        return text
    for node in list(root):
        if node.get("NodeId") in orphans:
            root.remove(node)
            continue
        refs_el = node.find(f"{NODESET_NS}References")
        if refs_el is None:
            continue
        for ref in list(refs_el):
            if (ref.text or "").strip() in orphans:
                refs_el.remove(ref)
    ET.register_namespace("", NODESET_NS.strip("{}"))
    ET.register_namespace("uax", "http://opcfoundation.org/UA/2008/02/Types.xsd")
    return ET.tostring(root, encoding="unicode")


async def load_companions(server: Server) -> None:
    """Import DI and PLCopen into ``server`` unless it has them already."""
    present = await server.get_namespace_array()
    importer_log = logging.getLogger("asyncua.common.xmlimporter")
    level = importer_log.level
    # asyncua warns about DI's OptionSet data types it makes no Python class for, and
    # about the references it repairs: noise at every start, nothing we use
    importer_log.setLevel(logging.ERROR)
    try:
        for uri in LOAD_ORDER:
            if uri not in present:
                await server.import_xml(xmlstring=asyncua_importable(uri))
    finally:
        importer_log.setLevel(level)
