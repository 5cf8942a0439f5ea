"""Tag imports for two SCADA/HMI products: KEPServerEX (CSV) and Ignition (tag JSON).

``motion-server map --format kepware``: the CSV that KEPServerEX's "CSV Import/Export"
reads into a device of its Modbus TCP/IP Ethernet driver (columns and values as the
KEPServerEX server help, "CSV Import/Export", describes them: Tag Name, Address, Data
Type, Respect Data Type, Client Access, Scan Rate, Scaling, Raw Low, Raw High, Scaled Low,
Scaled High, Scaled Data Type, Clamp Low, Clamp High, Eng Units, Description). Addresses
are Modbus holding-register references ``4xxxxx`` (1-based: ``400001`` is register 0, the
driver's default zero-based addressing), BOOLs ``4xxxxx.bb`` (bit ``bb`` of the register,
0 = least significant). Tag names keep their dot (``MAJ_1.Speed``), which the import turns
into a tag group per owner (a cam element's brackets become an underscore:
``Cam1.Master_3`` for ``Cam1.Master[3]``). Word order is a property of the Modbus device
in KEPServerEX, not of a tag: for ``word_order = "big"`` (the default) turn off "First
word low in 32-bit data types" and "First DWord low in 64-bit data types"; for
``"little"`` turn both on (docs/hmi.md).

``motion-server map --format ignition``: a tag tree for Ignition 8.1's Tag Browser import
(or ``system.tag.importTags``/``system.tag.configure``): a folder for the site, one per
OPC UA folder and owner, an OPC tag (``tagType`` AtomicTag, ``valueSource`` opc) per tag
pointing at our node (``opcItemPath`` ``nsu=<site namespace URI>;s=<node id>``: the
namespace by URI, which does not depend on the server's namespace index), with its data
type (Int1, Int2, Int4, Int8, Float4, Float8, Boolean), engineering units and range,
read-only flag and documentation (enumerations and bit layouts included); a cam table
also gets its array views (``MasterValues`` Float4Array, ``SlaveValues``,
``SegmentTypes`` Int4Array) and its element tags are named ``Master_3``. ``opcServer`` is
the name of the OPC UA connection in the gateway: ``motion-server`` (rename the connection
or edit the file).
"""

from __future__ import annotations

import csv
import io
import json
from typing import Any

from ..instructions.schema import TagType
from .bits import bits_text, word_bits
from .cams import ArrayView, cam_tables, scada_name
from .model import Folder, Tag, TagMap
from .nodeset import engineering_units, is_analog

#: the columns of a KEPServerEX tag CSV, in its order
KEPWARE_COLUMNS = (
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
)
#: KEPServerEX data types of our tag types (a SINT fills a whole signed register)
KEPWARE_TYPES = {
    TagType.BOOL: "Boolean",
    TagType.SINT: "Short",
    TagType.INT: "Short",
    TagType.DINT: "Long",
    TagType.UDINT: "DWord",
    TagType.REAL: "Float",
    TagType.LREAL: "Double",
}
KEPWARE_SCAN_RATE_MS = 100
#: Ignition data types of our tag types
IGNITION_TYPES = {
    TagType.BOOL: "Boolean",
    TagType.SINT: "Int1",
    TagType.INT: "Int2",
    TagType.DINT: "Int4",
    TagType.UDINT: "Int8",  # Int4 is signed: 2^31 and more would not fit
    TagType.REAL: "Float4",
    TagType.LREAL: "Float8",
}
#: the OPC UA connection the Ignition tags read through
IGNITION_OPC_SERVER = "motion-server"
#: KEPServerEX limits a description to this many characters
DESCRIPTION_LIMIT = 255


def modbus_address(tag: Tag) -> str:
    """The KEPServerEX Modbus address: ``4xxxxx`` or ``4xxxxx.bb``."""
    ref = f"4{tag.address + 1:05d}"
    return f"{ref}.{tag.bit}" if tag.bit is not None else ref


def documentation(tag: Tag) -> str:
    """A tag's description with its enumeration and bit layout."""
    parts = [tag.description] if tag.description else []
    if tag.enum is not None:
        parts.append("values: " + "; ".join(f"{v}={k}" for k, v in tag.enum_members().items()))
    bits = word_bits(tag)
    if bits:
        parts.append("bits: " + bits_text(bits))
    return " | ".join(parts)


def units_symbol(tag: Tag) -> str:
    eu = engineering_units(tag) if is_analog(tag) else None
    return eu.symbol if eu is not None else tag.units


def to_kepware(tagmap: TagMap) -> str:
    """The tag map as a KEPServerEX CSV tag import (address order)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n", quoting=csv.QUOTE_ALL)
    w.writerow(KEPWARE_COLUMNS)
    for t in tagmap:
        w.writerow(
            [
                f"{t.owner}.{scada_name(t.field)}",
                modbus_address(t),
                KEPWARE_TYPES[t.type],
                1,
                "R/W" if t.writable else "RO",
                KEPWARE_SCAN_RATE_MS,
                "",
                "",
                "",
                "",
                "",
                "",
                "",
                "",
                units_symbol(t),
                documentation(t)[:DESCRIPTION_LIMIT],
            ]
        )
    return out.getvalue()


def ignition_tag(tag: Tag, namespace_uri: str) -> dict[str, Any]:
    """One Ignition OPC tag."""
    rec: dict[str, Any] = {
        "name": scada_name(tag.field),
        "tagType": "AtomicTag",
        "valueSource": "opc",
        "opcServer": IGNITION_OPC_SERVER,
        "opcItemPath": f"nsu={namespace_uri};s={tag.node_id}",
        "dataType": IGNITION_TYPES[tag.type],
        "readOnly": not tag.writable,
    }
    text = documentation(tag)
    if text:
        rec["documentation"] = text
        rec["tooltip"] = tag.description or text
    units = units_symbol(tag)
    if units:
        rec["engUnit"] = units
    if tag.eu_range is not None and is_analog(tag):
        rec["engLow"], rec["engHigh"] = tag.eu_range
    return rec


#: Ignition array data types of the cam tables' array views
IGNITION_ARRAY_TYPES = {TagType.REAL: "Float4Array", TagType.DINT: "Int4Array"}


def ignition_array(view: ArrayView, namespace_uri: str) -> dict[str, Any]:
    """One Ignition OPC tag of a cam table's array view (``MasterValues`` ...)."""
    return {
        "name": view.name,
        "tagType": "AtomicTag",
        "valueSource": "opc",
        "opcServer": IGNITION_OPC_SERVER,
        "opcItemPath": f"nsu={namespace_uri};s={view.node_id}",
        "dataType": IGNITION_ARRAY_TYPES[view.type],
        "readOnly": False,
        "documentation": view.description,
        "tooltip": view.description,
    }


def to_ignition_dict(tagmap: TagMap) -> dict[str, Any]:
    """The tag tree as Ignition's tag JSON (a folder for the site)."""
    root: dict[str, Any] = {
        "name": f"motion-server-{tagmap.site}",
        "tagType": "Folder",
        "tags": [],
    }
    folders: dict[str, dict[str, Any]] = {}
    for folder in Folder:
        tags = tagmap.in_folder(folder)
        if not tags:
            continue
        node: dict[str, Any] = {"name": folder.value, "tagType": "Folder", "tags": []}
        folders[folder.value] = node
        root["tags"].append(node)
        owners: dict[str, dict[str, Any]] = {}
        for tag in tags:
            parent = tag.node_id.split(".")
            if len(parent) == 2:  # Clock.Cycle, Diagnostics.Heartbeat
                node["tags"].append(ignition_tag(tag, tagmap.namespace_uri))
                continue
            owner = owners.get(tag.owner)
            if owner is None:
                owner = {"name": tag.owner, "tagType": "Folder", "tags": []}
                owners[tag.owner] = owner
                node["tags"].append(owner)
            owner["tags"].append(ignition_tag(tag, tagmap.namespace_uri))
        if folder == Folder.CAMS:
            for cam in cam_tables(tagmap):
                owners[cam.name]["tags"] += [
                    ignition_array(v, tagmap.namespace_uri) for v in cam.views
                ]
    return root


def to_ignition(tagmap: TagMap) -> str:
    return json.dumps(to_ignition_dict(tagmap), indent=2, ensure_ascii=False) + "\n"
