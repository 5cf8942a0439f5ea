"""``motion-server map --format l5x``: the Logix data types and tags as an L5X file.

What a Studio 5000 Logix Designer or FactoryTalk project imports to use the same UDTs and
tags the EtherNet/IP front-end serves (:mod:`.logix_types`, the one layout both use):
one ``DataType`` per structure, its BOOLs as ``BIT`` members on their host (``FLAGS``
for the MOTION_INSTRUCTION bits, hidden SINT hosts for the others), ``ExternalAccess``
Read Only for the members the map does not let a client write; one controller-scope
``Tag`` per owner. No values and no export date: the file depends on the map alone, so
the checked-in export changes only when the map does.

Untested here with Logix Designer (docs/ethernetip.md): the file follows the L5X layout
of a controller export (``RSLogix5000Content`` / ``Controller`` / ``DataTypes`` / ``Tags``).
"""

from __future__ import annotations

from xml.sax.saxutils import escape, quoteattr

from .logix_types import (
    FLAG_BITS,
    CipType,
    LogixMap,
    LogixTag,
    Member,
    Structure,
    build_logix_map,
)
from .model import Tag, TagMap

#: the Logix firmware the file declares (UDINT members need 32 or later)
MAJOR_REV, MINOR_REV = 33, 11
PROCESSOR = "1756-L85E"


def _cdata(text: str) -> str:
    """``text`` safe inside a CDATA section."""
    return text.replace("]]>", "]]]]><![CDATA[>")


def _radix(m: Member) -> str:
    return "Float" if m.type in (CipType.REAL, CipType.LREAL) else "Decimal"


def _access(writable: bool) -> str:
    return "Read/Write" if writable else "Read Only"


def _member(s: Structure, m: Member, described: dict[str, Tag]) -> str:
    tag = described.get(m.fields[0]) if m.fields else None
    desc = _cdata(tag.description) if tag is not None else ""
    body = f"<Description><![CDATA[{desc}]]></Description>" if desc else ""
    attrs = [f"Name={quoteattr(m.name)}"]
    if m.bit is not None:
        if m.name in FLAG_BITS and s.member("FLAGS") is not None:
            host, bit = "FLAGS", FLAG_BITS[m.name]
        else:
            host = next(h.name for h in s.members if h.hidden and h.offset == m.offset)
            bit = m.bit
        attrs += [
            'DataType="BIT"',
            'Dimension="0"',
            'Radix="Decimal"',
            'Hidden="false"',
            f"Target={quoteattr(host)}",
            f'BitNumber="{bit}"',
        ]
    else:
        attrs += [
            f'DataType="{m.type.name}"',
            f'Dimension="{m.length}"',
            f'Radix="{_radix(m)}"',
            f'Hidden="{"true" if m.hidden else "false"}"',
        ]
    writable = m.writable
    if m.hidden:  # a BOOL host: as writable as the BOOLs it holds
        writable = any(b.writable for b in s.members if b.bit is not None and b.offset == m.offset)
    attrs.append(f'ExternalAccess="{_access(writable)}"')
    head = " ".join(attrs)
    if body:
        return f"<Member {head}>\n{body}\n</Member>"
    return f"<Member {head}/>"


def to_l5x(tagmap: TagMap, logix: LogixMap | None = None) -> str:
    """The L5X text of ``tagmap``'s Logix types and tags."""
    logix = logix if logix is not None else build_logix_map(tagmap)
    name = "".join(c if c.isalnum() or c == "_" else "_" for c in tagmap.site or "motion_server")
    out = [
        '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>',
        f'<RSLogix5000Content SchemaRevision="1.0" SoftwareRevision="{MAJOR_REV}.00" '
        f'TargetName="{name}" TargetType="Controller" ContainsContext="false" '
        'ExportOptions="NoRawData L5KData DecoratedData ForceProtectedEncoding '
        'AllProjDocTrans">',
        f'<Controller Use="Target" Name="{name}" ProcessorType="{PROCESSOR}" '
        f'MajorRev="{MAJOR_REV}" MinorRev="{MINOR_REV}">',
        "<DataTypes>",
    ]
    first_of: dict[str, LogixTag] = {}
    for t in logix.tags:
        first_of.setdefault(t.structure.name, t)
    for s in logix.structures:
        owner = first_of[s.name]
        out.append(f'<DataType Name="{s.name}" Family="NoFamily" Class="User">')
        out.append(
            f"<Description><![CDATA[motion-server: {escape(owner.folder.value)} "
            f"({escape(owner.tags[next(iter(owner.tags))].instruction or owner.name)})]]>"
            "</Description>"
        )
        out.append("<Members>")
        out += [_member(s, m, owner.tags) for m in s.members]
        out.append("</Members>")
        out.append("</DataType>")
    out.append("</DataTypes>")
    out.append("<Tags>")
    for t in logix.tags:
        access = _access(t.structure.writable)
        out.append(
            f'<Tag Name="{t.name}" TagType="Base" DataType="{t.structure.name}" '
            f'Constant="false" ExternalAccess="{access}"/>'
        )
    out.append("</Tags>")
    out.append("</Controller>")
    out.append("</RSLogix5000Content>")
    return "\n".join(out) + "\n"
