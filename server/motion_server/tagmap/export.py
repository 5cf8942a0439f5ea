"""Exports of a tag map: JSON (the ``motion-server-map/1`` contract), CSV and Markdown.

All three list the tags in address order and are deterministic, so the exports checked in
for the demo map can be compared with a fresh export.
"""

from __future__ import annotations

import csv
import io
import json
from importlib import resources
from typing import Any

from ..kernel.errors import ERROR_TEXT
from .bits import bits_text, packed_words, word_bits
from .cams import CAM_ELEMENT_WORDS, CAM_HEADER_WORDS, CamInfo, cam_tables
from .model import MAP_FORMAT, Block, Tag, TagMap

FORMATS = ("json", "csv", "md", "nodeset", "kepware", "ignition", "l5x")
SCHEMA_FILE = "map.schema.json"

#: function codes the Modbus front-end serves, and the exceptions it answers
FUNCTION_CODES = (3, 6, 16, 22, 23)
EXCEPTIONS = {
    1: "function code not served",
    2: "a register outside the map, or a write to a read-only register",
    3: "a value the tag cannot hold (SINT range, Clock.Mode, non-finite hand-wheel input)",
    11: "unknown unit id (no device answers)",
}


def reference(address: int) -> str:
    """The 6-digit holding-register reference of a 0-based address: 0 -> 400001."""
    return f"4{address + 1:05d}"


def enum_text(tag: Tag) -> str:
    return "; ".join(f"{v}={k}" for k, v in tag.enum_members().items())


def tag_record(tag: Tag) -> dict[str, Any]:
    rec: dict[str, Any] = {
        "name": tag.name,
        "type": tag.type.value,
        "access": tag.access.value,
        "modbus": {"address": tag.address, "count": tag.count},
        "opcua": {"node_id": tag.node_id},
    }
    if tag.bit is not None:
        rec["modbus"]["bit"] = tag.bit
    if tag.enum is not None:
        rec["enum"] = tag.enum_members()
    if tag.units:
        rec["units"] = tag.units
    if tag.minimum is not None:
        rec["minimum"] = tag.minimum
        if tag.exclusive_minimum:
            rec["exclusive_minimum"] = True
    if tag.maximum is not None:
        rec["maximum"] = tag.maximum
    if tag.description:
        rec["description"] = tag.description
    return rec


def cam_record(cam: CamInfo) -> dict[str, Any]:
    """A cam table: where its elements are (element k's Master at ``first_element`` +
    ``element_stride``·k, Slave 2 and SegmentType 4 registers after it) and its OPC UA
    array views."""
    return {
        "name": cam.name,
        "capacity": cam.capacity,
        "modbus": {
            "base": cam.base,
            "first_element": cam.base + CAM_HEADER_WORDS,
            "element_stride": CAM_ELEMENT_WORDS,
            "fields": {"Master": 0, "Slave": 2, "SegmentType": 4},
        },
        "opcua": {
            "node_id": cam.node_id,
            "arrays": {
                v.name: {"node_id": v.node_id, "type": v.type.value, "length": len(v.tags)}
                for v in cam.views
            },
        },
    }


def to_dict(tagmap: TagMap) -> dict[str, Any]:
    """The JSON contract as a Python object."""
    out = {
        "format": MAP_FORMAT,
        "site": tagmap.site,
        "modbus": {
            "word_order": tagmap.word_order.value,
            "unit_id": tagmap.unit_id,
            "function_codes": list(FUNCTION_CODES),
        },
        "opcua": {"namespace_uri": tagmap.namespace_uri},
        "tags": [tag_record(t) for t in tagmap],
        # the meaning of ERR / ErrorID values, so that clients can explain an outcome
        "errors": {str(int(code)): text for code, text in ERROR_TEXT.items()},
        # every packed word: the status words' bits and the registers of BOOL tags
        "packed_words": [
            {
                "address": w.address,
                "count": w.count,
                "owner": w.owner,
                "kind": w.kind,
                "access": w.access.value,
                **({"tag": w.tag.name} if w.tag is not None else {}),
                "bits": {str(n): name for n, name in sorted(w.bits.items())},
            }
            for w in packed_words(tagmap)
        ],
    }
    cams = cam_tables(tagmap)
    if cams:
        out["cams"] = [cam_record(c) for c in cams]
    return out


def to_json(tagmap: TagMap) -> str:
    return json.dumps(to_dict(tagmap), indent=2, ensure_ascii=False) + "\n"


CSV_COLUMNS = (
    "name",
    "address",
    "address_hex",
    "reference",
    "bit",
    "count",
    "unit_id",
    "type",
    "word_order",
    "access",
    "units",
    "enum",
    "node_id",
    "description",
    "bits",
)


def to_csv(tagmap: TagMap) -> str:
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for t in tagmap:
        w.writerow(
            [
                t.name,
                t.address,
                f"0x{t.address:04X}",
                reference(t.address),
                "" if t.bit is None else t.bit,
                t.count,
                tagmap.unit_id,
                t.type.value,
                tagmap.word_order.value,
                t.access.value,
                t.units,
                enum_text(t),
                t.node_id,
                t.description,
                bits_text(word_bits(t) or {}),
            ]
        )
    return out.getvalue()


def _md_cell(text: object) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _md_block(tagmap: TagMap, block: Block) -> list[str]:
    kind = f" ({block.instruction or block.part})" if block.instruction or block.part else ""
    lines = [
        f"### {block.owner}{kind}",
        "",
        f"Registers {block.base}–{block.end - 1} ({reference(block.base)}–"
        f"{reference(block.end - 1)})"
        + (
            f"; writable {block.command_start}–{block.command_end - 1}."
            if block.command_end > block.command_start
            else "; read-only."
        ),
        "",
        "| Register | Hex | Ref | Bit | Tag | Type | Access | Units | Values | Description |",
        "|---:|---:|---:|---:|---|---|---|---|---|---|",
    ]
    for t in tagmap.owned_by(block.owner):
        if not block.base <= t.address < block.end:
            continue  # in the owner's other block
        span = str(t.address) if t.count == 1 else f"{t.address}–{t.end - 1}"
        lines.append(
            "| "
            + " | ".join(
                _md_cell(c)
                for c in (
                    span,
                    f"0x{t.address:04X}",
                    reference(t.address),
                    "" if t.bit is None else t.bit,
                    f"`{t.name}`",
                    t.type.value,
                    "R/W" if t.writable else "R",
                    t.units,
                    enum_text(t),
                    t.description,
                )
            )
            + " |"
        )
    words = [w for w in packed_words(tagmap) if block.base <= w.address < block.end]
    if words:
        lines.append("")
        for w in words:
            what = f"`{w.tag.name}`" if w.tag is not None else w.kind
            span = str(w.address) if w.count == 1 else f"{w.address}–{w.address + w.count - 1}"
            names = ", ".join(f"{n} {name}" for n, name in sorted(w.bits.items()))
            lines.append(f"- Bits of {what} (register {span}): {names}.")
    return [*lines, ""]


def to_markdown(tagmap: TagMap) -> str:
    order = "big (ABCD: most significant word first)"
    if tagmap.word_order.value == "little":
        order = "little (CDAB: least significant word first)"
    lines = [
        f"# Modbus register map: site `{tagmap.site}`",
        "",
        "Generated by `motion-server map --format md`; do not edit by hand.",
        "",
        f"- Holding registers, 0-based on the wire (reference 4xxxxx = address + 400001); "
        f"unit id {tagmap.unit_id}.",
        f"- Word order of 32/64-bit values: {order}; they start on even registers.",
        "- BOOLs are bits of a 16-bit register (bit 0 = least significant). Command bits "
        "(written by clients) and status bits (written by the server) never share a register.",
        "- Function codes: " + ", ".join(str(c) for c in FUNCTION_CODES) + ".",
        "- Trigger an instruction: write its operands, then a rising edge on its trigger "
        "(bit 0 of its command bit register); poll the status bits and ERR / ErrorID.",
        "- Exceptions: " + "; ".join(f"{c:02d} {text}" for c, text in EXCEPTIONS.items()) + ".",
        f"- OPC UA namespace `{tagmap.namespace_uri}`; node ids are `Folder.Owner.Field`.",
        "",
    ]
    cams = cam_tables(tagmap)
    if cams:
        lines += [
            "- Cam tables: element k (0-based) of the table at base B: `Master[k]` at "
            f"B+{CAM_HEADER_WORDS}+{CAM_ELEMENT_WORDS}·k, `Slave[k]` at "
            f"B+{CAM_HEADER_WORDS + 2}+{CAM_ELEMENT_WORDS}·k, `SegmentType[k]` at "
            f"B+{CAM_HEADER_WORDS + 4}+{CAM_ELEMENT_WORDS}·k; "
            + "; ".join(f"`{c.name}` B = {c.base}, {c.capacity} elements" for c in cams)
            + ". OPC UA also shows each table's `MasterValues`, `SlaveValues` and "
            "`SegmentTypes` arrays.",
            "",
        ]
    for block in tagmap.blocks:
        lines += _md_block(tagmap, block)
    return "\n".join(lines).rstrip("\n") + "\n"


def export(tagmap: TagMap, fmt: str) -> str:
    """The export of ``tagmap`` in ``fmt`` (json, csv, md, nodeset, kepware, ignition,
    l5x)."""
    from .l5x import to_l5x  # Logix UDTs and tags (what EtherNet/IP serves)
    from .nodeset_xml import to_nodeset  # NodeSet2 XML of the OPC UA namespace
    from .scada import to_ignition, to_kepware  # SCADA tag imports

    writers = {
        "json": to_json,
        "csv": to_csv,
        "md": to_markdown,
        "nodeset": to_nodeset,
        "kepware": to_kepware,
        "ignition": to_ignition,
        "l5x": to_l5x,
    }
    try:
        return writers[fmt](tagmap)
    except KeyError:
        raise ValueError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}") from None


def json_schema() -> dict[str, Any]:
    """The JSON Schema of the ``motion-server-map/1`` contract."""
    text = resources.files(__package__).joinpath(SCHEMA_FILE).read_text("utf-8")
    schema: dict[str, Any] = json.loads(text)
    return schema
