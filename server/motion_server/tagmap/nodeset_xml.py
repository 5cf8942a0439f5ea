"""NodeSet2 XML of the site's namespace (``motion-server map --format nodeset``).

The document follows the official ``UANodeSet.xsd`` (OPC 10000-6, Annex F; ``make test``
validates the demo's and the examples' exports against it): ``<NamespaceUris>`` (1 = the
site, 2 = PLCopen), ``<Models>`` with the site's model (ModelUri = the namespace URI,
Version = the motion-server version, PublicationDate = its release date) and a
``<RequiredModel>`` for each model it builds on (the OPC UA base model, DI and PLCopen as
the companion nodesets declare them, :mod:`.companion`), ``<Aliases>``, the ObjectTypes,
then the instances, each variable with its initial value: what the server serves before
its first cycle (the site map's operand values, the configuration, zeros).

Importers load it after the nodesets it requires: DI, then PLCopen
(``Opc.Ua.Di.NodeSet2.xml``, ``Opc.Ua.PLCopen.NodeSet2_V1.02.xml``).
"""

from __future__ import annotations

import math
from typing import Any
from xml.sax.saxutils import escape

from .. import __version__
from ..identity import RELEASE_DATE
from ..instructions.schema import TagType
from .companion import PLCOPEN_URI, required_models
from .image import StandaloneHost, TagImage
from .model import Folder, TagMap
from .nodeset import (
    ACCESS_READ,
    ACCESS_READ_WRITE,
    INPUT_VAR,
    OUTPUT_VAR,
    UNECE_NAMESPACE,
    EUInfo,
    Ext,
    NodeKind,
    NodeSpec,
    Ns0,
    enum_text,
    node_plan,
)

#: namespace indexes inside the document
SITE_NS = 1
NAMESPACES = {"": 0, PLCOPEN_URI: 2}
_ALIASES: dict[str, str] = {
    "Boolean": "i=1",
    "SByte": "i=2",
    "Int16": "i=4",
    "Int32": "i=6",
    "UInt32": "i=7",
    "Float": "i=10",
    "Double": "i=11",
    "LocalizedText": "i=21",
    "Range": "i=884",
    "EUInformation": "i=887",
    "EnumValueType": "i=7594",
    "Organizes": "i=35",
    "HasModellingRule": "i=37",
    "HasTypeDefinition": "i=40",
    "HasSubtype": "i=45",
    "HasProperty": "i=46",
    "HasComponent": "i=47",
    "HasInputVar": f"ns={NAMESPACES[PLCOPEN_URI]};i={INPUT_VAR.id}",
    "HasOutputVar": f"ns={NAMESPACES[PLCOPEN_URI]};i={OUTPUT_VAR.id}",
}
_ALIAS_OF = {v: k for k, v in _ALIASES.items()}
_XML_VALUE = {
    TagType.BOOL: "Boolean",
    TagType.SINT: "SByte",
    TagType.INT: "Int16",
    TagType.DINT: "Int32",
    TagType.UDINT: "UInt32",
    TagType.REAL: "Float",
    TagType.LREAL: "Double",
}
_DATA_TYPE_NAME = {
    Ns0.BOOLEAN: "Boolean",
    Ns0.SBYTE: "SByte",
    Ns0.INT16: "Int16",
    Ns0.INT32: "Int32",
    Ns0.UINT32: "UInt32",
    Ns0.FLOAT: "Float",
    Ns0.DOUBLE: "Double",
    Ns0.LOCALIZED_TEXT: "LocalizedText",
    Ns0.RANGE: "Range",
    Ns0.EU_INFORMATION: "EUInformation",
    Ns0.ENUM_VALUE_TYPE: "EnumValueType",
}


def _nid(node: str | Ext) -> str:
    if isinstance(node, Ext):
        text = f"i={node.id}" if not node.uri else f"ns={NAMESPACES[node.uri]};i={node.id}"
        return _ALIAS_OF.get(text, text)
    return escape(f"ns={SITE_NS};s={node}")


def _parent(spec: NodeSpec) -> str:
    if spec.parent is None:
        return f"i={int(Ns0.OBJECTS_FOLDER)}"
    return _nid(spec.parent)


def initial_values(tagmap: TagMap) -> dict[str, Any]:
    """Every tag's value before the first cycle, by tag name (empty when the tag map
    does not know its site map)."""
    site = tagmap.source
    if site is None:
        return {}
    system = site.build()
    zero = {t.name: (lambda t=t: _zero(t.type), lambda _v: None) for t in tagmap}
    safety = {t.name: zero[t.name] for t in tagmap if t.folder == Folder.SAFETY}
    image = TagImage(tagmap, system, StandaloneHost(system, __version__), safety)
    return {t.name: image.read(t) for t in tagmap}


def _zero(tag_type: TagType) -> Any:
    if tag_type == TagType.BOOL:
        return False
    return 0.0 if tag_type.is_float else 0


def to_nodeset(tagmap: TagMap) -> str:
    """The site's namespace as a NodeSet2 XML document (deterministic)."""
    plan = node_plan(tagmap)
    values = initial_values(tagmap)
    organized_by: dict[str, list[str]] = {}
    for spec in plan:
        for target in spec.organizes:
            organized_by.setdefault(target, []).append(spec.node_id)
    uri = escape(tagmap.namespace_uri)
    date = RELEASE_DATE.strftime("%Y-%m-%dT%H:%M:%SZ")
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        '<UANodeSet xmlns="http://opcfoundation.org/UA/2011/03/UANodeSet.xsd"'
        ' xmlns:uax="http://opcfoundation.org/UA/2008/02/Types.xsd">',
        "  <NamespaceUris>",
        f"    <Uri>{uri}</Uri>",
        f"    <Uri>{escape(PLCOPEN_URI)}</Uri>",
        "  </NamespaceUris>",
        "  <Models>",
        f'    <Model ModelUri="{uri}" Version="{escape(__version__)}" PublicationDate="{date}">',
        *(
            f'      <RequiredModel ModelUri="{escape(m.uri)}" Version="{escape(m.version)}"'
            f' PublicationDate="{escape(m.publication_date)}" />'
            for m in required_models()
        ),
        "    </Model>",
        "  </Models>",
        "  <Aliases>",
        *(f'    <Alias Alias="{k}">{v}</Alias>' for k, v in _ALIASES.items()),
        "  </Aliases>",
    ]
    texts = {
        f"{spec.node_id}.ValueAsText": enum_text(spec.tag, values[spec.tag.name])
        for spec in plan
        if spec.kind == NodeKind.VARIABLE
        and spec.tag is not None
        and spec.tag.enum is not None
        and spec.tag.name in values
    }
    for spec in plan:
        lines += _xml_node(spec, organized_by.get(spec.node_id, []), values, texts)
    lines.append("</UANodeSet>")
    return "\n".join(lines) + "\n"


def _xml_node(
    spec: NodeSpec, organized_by: list[str], values: dict[str, Any], texts: dict[str, str]
) -> list[str]:
    is_var = spec.kind in (NodeKind.VARIABLE, NodeKind.PROPERTY)
    element = {NodeKind.OBJECT_TYPE: "UAObjectType"}.get(
        spec.kind, "UAVariable" if is_var else "UAObject"
    )
    name = escape(spec.browse_name)
    # standard properties keep their standard (namespace 0) browse names
    browse = name if spec.kind == NodeKind.PROPERTY else f"{SITE_NS}:{name}"
    attrs = f'NodeId="{_nid(spec.node_id)}" BrowseName="{browse}"'
    if spec.kind != NodeKind.OBJECT_TYPE:
        attrs += f' ParentNodeId="{_parent(spec)}"'
    if is_var:
        attrs += f' DataType="{_DATA_TYPE_NAME[spec.data_type]}"'
        if spec.value_rank != -1:
            attrs += f' ValueRank="{spec.value_rank}"'
        if spec.view is not None and spec.modelling_rule is None:
            attrs += f' ArrayDimensions="{len(spec.view.tags)}"'
        level = ACCESS_READ_WRITE if spec.writable else ACCESS_READ
        attrs += f' AccessLevel="{level}" UserAccessLevel="{level}"'
    out = [f"  <{element} {attrs}>", f"    <DisplayName>{name}</DisplayName>"]
    if spec.description:
        out.append(f"    <Description>{escape(spec.description)}</Description>")
    out.append("    <References>")
    if spec.type_definition is not None:
        typedef = _nid(spec.type_definition)
        out.append(f'      <Reference ReferenceType="HasTypeDefinition">{typedef}</Reference>')
    out.append(
        f'      <Reference ReferenceType="{_nid(spec.reference)}" IsForward="false">'
        f"{_parent(spec)}</Reference>"
    )
    if spec.modelling_rule is not None:
        rule = _nid(spec.modelling_rule)
        out.append(f'      <Reference ReferenceType="HasModellingRule">{rule}</Reference>')
    for source in organized_by:
        back = _nid(source)
        out.append(
            f'      <Reference ReferenceType="Organizes" IsForward="false">{back}</Reference>'
        )
    for target in spec.organizes:
        out.append(f'      <Reference ReferenceType="Organizes">{_nid(target)}</Reference>')
    out.append("    </References>")
    value = _value(spec, values, texts)
    if value is not None:
        # one element a line: importers such as asyncua's read an element without text
        # before its first child as an empty value
        value = value.replace("><uax:", ">\n      <uax:")
        out.append(f"    <Value>\n      {value}\n    </Value>")
    out.append(f"  </{element}>")
    return out


def _value(spec: NodeSpec, values: dict[str, Any], texts: dict[str, str]) -> str | None:
    if spec.kind == NodeKind.VARIABLE and spec.view is not None:
        if spec.modelling_rule is not None or not values:
            return None
        kind = _XML_VALUE[spec.view.type]
        items = "".join(
            f"<uax:{kind}>{_scalar(values[t.name], t.type)}</uax:{kind}>" for t in spec.view.tags
        )
        return f"<uax:ListOf{kind}>{items}</uax:ListOf{kind}>"
    if spec.kind == NodeKind.VARIABLE:
        if spec.tag is None or spec.modelling_rule is not None or spec.tag.name not in values:
            return None
        kind = _XML_VALUE[spec.tag.type]
        return f"<uax:{kind}>{_scalar(values[spec.tag.name], spec.tag.type)}</uax:{kind}>"
    if spec.kind != NodeKind.PROPERTY:
        return None
    v = texts.get(spec.node_id, spec.value)
    if v is None:
        return None
    if spec.data_type == Ns0.RANGE:
        body = (
            f"<uax:Range><uax:Low>{_double(v[0])}</uax:Low>"
            f"<uax:High>{_double(v[1])}</uax:High></uax:Range>"
        )
        return _extension(Ns0.RANGE_XML, body)
    if spec.data_type == Ns0.EU_INFORMATION:
        assert isinstance(v, EUInfo)
        body = (
            f"<uax:EUInformation><uax:NamespaceUri>{UNECE_NAMESPACE}</uax:NamespaceUri>"
            f"<uax:UnitId>{v.unit_id}</uax:UnitId>"
            f"<uax:DisplayName><uax:Text>{escape(v.symbol)}</uax:Text></uax:DisplayName>"
            f"<uax:Description><uax:Text>{escape(v.name)}</uax:Text></uax:Description>"
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


def _scalar(value: Any, tag_type: TagType) -> str:
    if tag_type == TagType.BOOL:
        return "true" if value else "false"
    if tag_type.is_float:
        return _double(float(value))
    return str(int(value))


def _double(v: float) -> str:
    if math.isnan(v):
        return "NaN"
    if math.isinf(v):
        return "INF" if v > 0 else "-INF"
    return repr(float(v))


def _extension(encoding: Ns0, body: str) -> str:
    return (
        f"<uax:ExtensionObject><uax:TypeId><uax:Identifier>i={int(encoding)}</uax:Identifier>"
        f"</uax:TypeId><uax:Body>{body}</uax:Body></uax:ExtensionObject>"
    )
