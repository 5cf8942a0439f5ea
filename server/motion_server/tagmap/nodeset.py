"""The OPC UA node tree of a tag map, and its NodeSet2 XML export.

:func:`node_plan` lists every node of the site's namespace once: the folders ``Clock``,
``Diagnostics``, ``Groups``, ``Axes``, ``Instructions`` under the Objects folder; one
object per axis, group and instruction instance; one variable per tag (NodeId =
``tag.node_id``, e.g. ``Instructions.MAG_1.Ratio``); the properties of analog and
enumerated variables. Both the OPC UA front-end and ``motion-server map --format nodeset``
are built from it, so the served tree and the export cannot differ.

Shapes:

- an instruction instance is an object shaped like an OPC 30000 function block: its
  variables are its components, and two folders ``InputVariables`` (the trigger and the
  operands, writable) and ``OutputVariables`` (the status, read-only) organize them;
- REAL/LREAL values with a quantity or units are ``AnalogItemType`` variables with the
  ``EURange`` (the operand's range, else the type's) and ``EngineeringUnits`` (UNECE
  code where one is known, else -1, and the units as display name) properties;
- enumerated values are ``MultiStateValueDiscreteType`` variables with ``EnumValues``
  (value, name) and ``ValueAsText``;
- every other value is a ``BaseDataVariableType``.

DataTypes: BOOL Boolean, SINT SByte, INT Int16, DINT Int32, UDINT UInt32, REAL Float,
LREAL Double. Access level: CurrentRead, plus CurrentWrite for writable tags.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any
from xml.sax.saxutils import escape

from ..instructions.schema import Quantity, TagType
from .model import Folder, Tag, TagMap


class Ns0(IntEnum):
    """Node ids of the standard namespace the tree refers to."""

    BOOLEAN = 1
    SBYTE = 2
    INT16 = 4
    INT32 = 6
    UINT32 = 7
    FLOAT = 10
    DOUBLE = 11
    LOCALIZED_TEXT = 21
    ORGANIZES = 35
    HAS_TYPE_DEFINITION = 40
    HAS_PROPERTY = 46
    HAS_COMPONENT = 47
    BASE_OBJECT_TYPE = 58
    FOLDER_TYPE = 61
    BASE_DATA_VARIABLE_TYPE = 63
    PROPERTY_TYPE = 68
    OBJECTS_FOLDER = 85
    RANGE = 884
    RANGE_XML = 885
    EU_INFORMATION = 887
    EU_INFORMATION_XML = 888
    ANALOG_ITEM_TYPE = 2368
    ENUM_VALUE_TYPE = 7594
    ENUM_VALUE_TYPE_XML = 7616
    MULTI_STATE_VALUE_DISCRETE_TYPE = 11238


DATA_TYPES: dict[TagType, Ns0] = {
    TagType.BOOL: Ns0.BOOLEAN,
    TagType.SINT: Ns0.SBYTE,
    TagType.INT: Ns0.INT16,
    TagType.DINT: Ns0.INT32,
    TagType.UDINT: Ns0.UINT32,
    TagType.REAL: Ns0.FLOAT,
    TagType.LREAL: Ns0.DOUBLE,
}

#: UNECE Recommendation 20 common codes of the units the tag map produces
UNECE_CODES = {
    "mm": "MMT",
    "m": "MTR",
    "deg": "DD",
    "rad": "C81",
    "s": "SEC",
    "ms": "C26",
    "%": "P1",
    "mm/s": "C16",
    "m/s": "MTS",
    "deg/s": "E96",
    "rad/s": "2A",
    "m/s²": "MSK",
    "rad/s²": "2B",
}
UNECE_NAMESPACE = "http://www.opcfoundation.org/UA/units/un/cefact"
ACCESS_READ = 1
ACCESS_READ_WRITE = 3
_DOUBLE_MAX = sys.float_info.max
ANALOG_QUANTITIES = frozenset(
    {Quantity.POSITION, Quantity.VELOCITY, Quantity.ACCELERATION, Quantity.JERK, Quantity.RATIO}
)


class NodeKind(IntEnum):
    FOLDER = 0
    OBJECT = 1
    VARIABLE = 2
    PROPERTY = 3


@dataclass(frozen=True)
class EUInfo:
    """The EngineeringUnits property value."""

    units: str
    unit_id: int


@dataclass(frozen=True)
class NodeSpec:
    """One node of the site's namespace. ``parent`` None = the Objects folder;
    ``reference`` is the reference type from the parent; ``organizes`` lists node ids the
    node organizes besides its children (the function-block variable groups)."""

    node_id: str
    parent: str | None
    browse_name: str
    kind: NodeKind
    reference: Ns0
    type_definition: Ns0
    tag: Tag | None = None
    data_type: Ns0 = Ns0.BOOLEAN
    value: Any = None
    value_rank: int = -1
    description: str = ""
    organizes: tuple[str, ...] = field(default=())

    @property
    def writable(self) -> bool:
        return self.tag is not None and self.tag.writable


def unit_id(units: str) -> int:
    """The OPC UA UnitId of a UNECE code (characters packed into an integer), -1 if unknown."""
    code = UNECE_CODES.get(units)
    if code is None:
        return -1
    out = 0
    for ch in code:
        out = (out << 8) | ord(ch)
    return out


def is_analog(tag: Tag) -> bool:
    return tag.type.is_float and (bool(tag.units) or tag.quantity in ANALOG_QUANTITIES)


def eu_range(tag: Tag) -> tuple[float, float]:
    """(low, high) of the EURange: the operand's range, else the type's (finite)."""
    lo, hi = tag.type.bounds
    low = tag.minimum if tag.minimum is not None else max(lo, -_DOUBLE_MAX)
    high = tag.maximum if tag.maximum is not None else min(hi, _DOUBLE_MAX)
    return float(low), float(high)


def parent_of(tag: Tag) -> str:
    return tag.node_id.rsplit(".", 1)[0]


def node_plan(tagmap: TagMap) -> list[NodeSpec]:
    """Every node of the site's namespace, parents before children."""
    out: list[NodeSpec] = []
    for folder in Folder:
        out.append(
            NodeSpec(
                folder.value, None, folder.value, NodeKind.FOLDER, Ns0.ORGANIZES, Ns0.FOLDER_TYPE
            )
        )
    owners: dict[str, list[Tag]] = {}
    for tag in tagmap:
        owners.setdefault(parent_of(tag), []).append(tag)
    for parent, tags in owners.items():
        if "." not in parent:  # Clock and Diagnostics tags sit in their folders
            continue
        folder_name, name = parent.split(".", 1)
        is_fb = tags[0].folder == Folder.INSTRUCTIONS
        desc = f"{tags[0].instruction} instruction instance" if is_fb else ""
        out.append(
            NodeSpec(
                parent,
                folder_name,
                name,
                NodeKind.OBJECT,
                Ns0.ORGANIZES,
                Ns0.BASE_OBJECT_TYPE,
                description=desc,
            )
        )
        if is_fb:
            for group, writable in (("InputVariables", True), ("OutputVariables", False)):
                members = tuple(t.node_id for t in tags if t.writable == writable)
                out.append(
                    NodeSpec(
                        f"{parent}.{group}",
                        parent,
                        group,
                        NodeKind.FOLDER,
                        Ns0.HAS_COMPONENT,
                        Ns0.FOLDER_TYPE,
                        organizes=members,
                    )
                )
    for parent, tags in owners.items():
        ref = Ns0.ORGANIZES if "." not in parent else Ns0.HAS_COMPONENT
        for tag in tags:
            out += _variable(tag, parent, ref)
    return out


def _variable(tag: Tag, parent: str, ref: Ns0) -> list[NodeSpec]:
    dtype = DATA_TYPES[tag.type]
    if tag.enum is not None:
        typedef = Ns0.MULTI_STATE_VALUE_DISCRETE_TYPE
    elif is_analog(tag):
        typedef = Ns0.ANALOG_ITEM_TYPE
    else:
        typedef = Ns0.BASE_DATA_VARIABLE_TYPE
    var = NodeSpec(
        tag.node_id,
        parent,
        tag.field,
        NodeKind.VARIABLE,
        ref,
        typedef,
        tag=tag,
        data_type=dtype,
        description=tag.description,
    )
    props: list[NodeSpec] = []

    def prop(name: str, data_type: Ns0, value: Any, rank: int = -1) -> None:
        props.append(
            NodeSpec(
                f"{tag.node_id}.{name}",
                tag.node_id,
                name,
                NodeKind.PROPERTY,
                Ns0.HAS_PROPERTY,
                Ns0.PROPERTY_TYPE,
                data_type=data_type,
                value=value,
                value_rank=rank,
            )
        )

    if typedef == Ns0.ANALOG_ITEM_TYPE:
        prop("EURange", Ns0.RANGE, eu_range(tag))
        prop("EngineeringUnits", Ns0.EU_INFORMATION, EUInfo(tag.units, unit_id(tag.units)))
    elif typedef == Ns0.MULTI_STATE_VALUE_DISCRETE_TYPE:
        prop("EnumValues", Ns0.ENUM_VALUE_TYPE, tuple(tag.enum_members().items()), rank=1)
        prop("ValueAsText", Ns0.LOCALIZED_TEXT, "")
    return [var, *props]


def enum_text(tag: Tag, value: Any) -> str:
    """The ValueAsText of an enumerated value (the member name, else the number)."""
    for name, v in tag.enum_members().items():
        if v == value:
            return name
    return str(value)


# -- NodeSet2 XML ------------------------------------------------------------------------------

_XML_TYPES = "http://opcfoundation.org/UA/2008/02/Types.xsd"
_ALIASES = {
    "Boolean": Ns0.BOOLEAN,
    "SByte": Ns0.SBYTE,
    "Int16": Ns0.INT16,
    "Int32": Ns0.INT32,
    "UInt32": Ns0.UINT32,
    "Float": Ns0.FLOAT,
    "Double": Ns0.DOUBLE,
    "LocalizedText": Ns0.LOCALIZED_TEXT,
    "Range": Ns0.RANGE,
    "EUInformation": Ns0.EU_INFORMATION,
    "EnumValueType": Ns0.ENUM_VALUE_TYPE,
    "Organizes": Ns0.ORGANIZES,
    "HasTypeDefinition": Ns0.HAS_TYPE_DEFINITION,
    "HasProperty": Ns0.HAS_PROPERTY,
    "HasComponent": Ns0.HAS_COMPONENT,
}
_ALIAS_OF = {v: k for k, v in _ALIASES.items()}


def _nid(node_id: str) -> str:
    return escape(f"ns=1;s={node_id}")


def _ref_name(ref: Ns0) -> str:
    return _ALIAS_OF.get(ref, f"i={int(ref)}")


def to_nodeset(tagmap: TagMap) -> str:
    """The site's namespace as a NodeSet2 XML document (deterministic)."""
    plan = node_plan(tagmap)
    organized_by: dict[str, list[str]] = {}
    for spec in plan:
        for target in spec.organizes:
            organized_by.setdefault(target, []).append(spec.node_id)
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        '<UANodeSet xmlns="http://opcfoundation.org/UA/2011/03/UANodeSet.xsd"'
        ' xmlns:uax="http://opcfoundation.org/UA/2008/02/Types.xsd">',
        f"  <NamespaceUris><Uri>{escape(tagmap.namespace_uri)}</Uri></NamespaceUris>",
        "  <Aliases>",
        *(f'    <Alias Alias="{k}">i={int(v)}</Alias>' for k, v in _ALIASES.items()),
        "  </Aliases>",
    ]
    for spec in plan:
        lines += _xml_node(spec, organized_by.get(spec.node_id, []))
    lines.append("</UANodeSet>")
    return "\n".join(lines) + "\n"


def _xml_node(spec: NodeSpec, organized_by: list[str]) -> list[str]:
    is_var = spec.kind in (NodeKind.VARIABLE, NodeKind.PROPERTY)
    element = "UAVariable" if is_var else "UAObject"
    parent = _nid(spec.parent) if spec.parent else f"i={int(Ns0.OBJECTS_FOLDER)}"
    attrs = f'NodeId="{_nid(spec.node_id)}" BrowseName="1:{escape(spec.browse_name)}"'
    if spec.kind == NodeKind.PROPERTY:
        attrs = f'NodeId="{_nid(spec.node_id)}" BrowseName="{escape(spec.browse_name)}"'
    if is_var:
        attrs += f' ParentNodeId="{parent}" DataType="{_ALIAS_OF[spec.data_type]}"'
        if spec.value_rank != -1:
            attrs += f' ValueRank="{spec.value_rank}"'
        level = ACCESS_READ_WRITE if spec.writable else ACCESS_READ
        attrs += f' AccessLevel="{level}" UserAccessLevel="{level}"'
    else:
        attrs += f' ParentNodeId="{parent}"'
    out = [f"  <{element} {attrs}>", f"    <DisplayName>{escape(spec.browse_name)}</DisplayName>"]
    if spec.description:
        out.append(f"    <Description>{escape(spec.description)}</Description>")
    out.append("    <References>")
    typedef = f"i={int(spec.type_definition)}"
    out.append(f'      <Reference ReferenceType="HasTypeDefinition">{typedef}</Reference>')
    out.append(
        f'      <Reference ReferenceType="{_ref_name(spec.reference)}" IsForward="false">'
        f"{parent}</Reference>"
    )
    for source in organized_by:
        back = _nid(source)
        out.append(
            f'      <Reference ReferenceType="Organizes" IsForward="false">{back}</Reference>'
        )
    for target in spec.organizes:
        out.append(f'      <Reference ReferenceType="Organizes">{_nid(target)}</Reference>')
    out.append("    </References>")
    if spec.kind == NodeKind.PROPERTY:
        # one element a line: importers such as asyncua's read an element without text
        # before its first child as an empty value
        value = _xml_value(spec).replace("><uax:", ">\n      <uax:")
        out.append(f"    <Value>\n      {value}\n    </Value>")
    out.append(f"  </{element}>")
    return out


def _xml_value(spec: NodeSpec) -> str:
    v = spec.value
    if spec.data_type == Ns0.RANGE:
        body = f"<uax:Range><uax:Low>{v[0]!r}</uax:Low><uax:High>{v[1]!r}</uax:High></uax:Range>"
        return _extension(Ns0.RANGE_XML, body)
    if spec.data_type == Ns0.EU_INFORMATION:
        body = (
            f"<uax:EUInformation><uax:NamespaceUri>{UNECE_NAMESPACE}</uax:NamespaceUri>"
            f"<uax:UnitId>{v.unit_id}</uax:UnitId>"
            f"<uax:DisplayName><uax:Text>{escape(v.units)}</uax:Text></uax:DisplayName>"
            f"<uax:Description><uax:Text>{escape(v.units)}</uax:Text></uax:Description>"
            "</uax:EUInformation>"
        )
        return _extension(Ns0.EU_INFORMATION_XML, body)
    if spec.data_type == Ns0.ENUM_VALUE_TYPE:
        items = "".join(
            _extension(
                Ns0.ENUM_VALUE_TYPE_XML,
                f"<uax:EnumValueType><uax:Value>{value}</uax:Value>"
                f"<uax:DisplayName><uax:Text>{escape(name)}</uax:Text></uax:DisplayName>"
                "</uax:EnumValueType>",
            )
            for name, value in v
        )
        return f"<uax:ListOfExtensionObject>{items}</uax:ListOfExtensionObject>"
    return f"<uax:LocalizedText><uax:Text>{escape(str(v))}</uax:Text></uax:LocalizedText>"


def _extension(encoding: Ns0, body: str) -> str:
    return (
        f"<uax:ExtensionObject><uax:TypeId><uax:Identifier>i={int(encoding)}</uax:Identifier>"
        f"</uax:TypeId><uax:Body>{body}</uax:Body></uax:ExtensionObject>"
    )
