"""Build the site's OPC UA namespace in an asyncua server from the tag map's node plan.

First the companion nodesets the types build on (DI, PLCopen: :mod:`.opcua_models`), then
all nodes of :func:`motion_server.tagmap.nodeset.node_plan` (the plan the NodeSet2 export
uses: ObjectTypes with their instance declarations, then the instances) with a few batched
AddNodes/AddReferences calls on the server's internal session (thousands of nodes in
well under a second).
"""

from __future__ import annotations

from typing import Any

from asyncua import Server, ua

from ..tagmap import Tag, TagType
from ..tagmap.nodeset import (
    ACCESS_READ,
    ACCESS_READ_WRITE,
    UNECE_NAMESPACE,
    EUInfo,
    Ext,
    NodeKind,
    NodeSpec,
    Ns0,
    enum_text,
    node_plan,
)
from .opcua_models import load_companions
from .view import ImageView

VARIANT_TYPES: dict[TagType, ua.VariantType] = {
    TagType.BOOL: ua.VariantType.Boolean,
    TagType.SINT: ua.VariantType.SByte,
    TagType.INT: ua.VariantType.Int16,
    TagType.DINT: ua.VariantType.Int32,
    TagType.UDINT: ua.VariantType.UInt32,
    TagType.REAL: ua.VariantType.Float,
    TagType.LREAL: ua.VariantType.Double,
}


def variant(tag: Tag, value: Any) -> ua.Variant:
    """The value of ``tag`` as a Variant of the tag's own type."""
    vt = VARIANT_TYPES[tag.type]
    if tag.type == TagType.BOOL:
        value = bool(value)
    elif not tag.type.is_float:
        value = int(value)
    else:
        value = float(value)
    return ua.Variant(value, vt)


def _property_value(spec: NodeSpec) -> ua.Variant:
    v = spec.value
    if v is None:  # a type's declaration: each instance has its own value
        return ua.Variant()
    if spec.data_type == Ns0.RANGE:
        return ua.Variant(ua.Range(Low=v[0], High=v[1]), ua.VariantType.ExtensionObject)
    if spec.data_type == Ns0.EU_INFORMATION:
        assert isinstance(v, EUInfo)
        eu = ua.EUInformation(
            NamespaceUri=UNECE_NAMESPACE,
            UnitId=v.unit_id,
            DisplayName=ua.LocalizedText(v.symbol),
            Description=ua.LocalizedText(v.name),
        )
        return ua.Variant(eu, ua.VariantType.ExtensionObject)
    if spec.data_type == Ns0.ENUM_VALUE_TYPE:
        items = [
            ua.EnumValueType(Value=value, DisplayName=ua.LocalizedText(name)) for name, value in v
        ]
        return ua.Variant(items, ua.VariantType.ExtensionObject)
    return ua.Variant(ua.LocalizedText(str(v)), ua.VariantType.LocalizedText)


async def build_space(server: Server, ns: int, image: ImageView) -> dict[str, NodeSpec]:
    """Add the site's nodes to ``server`` under namespace index ``ns`` (after the
    companion nodesets they build on); returns the plan by node id (string identifier)."""
    await load_companions(server)
    namespaces = await server.get_namespace_array()

    def nid(node: str | Ext | None) -> ua.NodeId:
        if node is None:
            return ua.NodeId(ua.ObjectIds.ObjectsFolder)
        if isinstance(node, Ext):
            return ua.NodeId(node.id, namespaces.index(node.uri) if node.uri else 0)
        return ua.NodeId(node, ns)

    plan = node_plan(image.map)
    items: list[ua.AddNodesItem] = []
    refs: list[ua.AddReferencesItem] = []
    for spec in plan:
        items.append(_add_item(spec, ns, image, nid))
        if spec.modelling_rule is not None:
            refs.append(
                ua.AddReferencesItem(
                    SourceNodeId=ua.NodeId(spec.node_id, ns),
                    ReferenceTypeId=ua.NodeId(Ns0.HAS_MODELLING_RULE),
                    IsForward=True,
                    TargetNodeId=nid(spec.modelling_rule),
                    TargetNodeClass=ua.NodeClass.Object,
                )
            )
        for target in spec.organizes:
            refs.append(
                ua.AddReferencesItem(
                    SourceNodeId=ua.NodeId(spec.node_id, ns),
                    ReferenceTypeId=ua.NodeId(Ns0.ORGANIZES),
                    IsForward=True,
                    TargetNodeId=ua.NodeId(target, ns),
                    TargetNodeClass=ua.NodeClass.Variable,
                )
            )
    session = server.iserver.isession
    for result in await session.add_nodes(items):
        result.StatusCode.check()
    for code in await session.add_references(refs):
        code.check()
    return {spec.node_id: spec for spec in plan}


def _add_item(spec: NodeSpec, ns: int, image: ImageView, nid: Any) -> ua.AddNodesItem:
    item = ua.AddNodesItem()
    item.RequestedNewNodeId = ua.NodeId(spec.node_id, ns)
    # standard properties keep their standard (namespace 0) browse names
    name_ns = 0 if spec.kind == NodeKind.PROPERTY else ns
    item.BrowseName = ua.QualifiedName(spec.browse_name, name_ns)
    item.ParentNodeId = nid(spec.parent)
    item.ReferenceTypeId = nid(spec.reference)
    if spec.type_definition is not None:
        item.TypeDefinition = nid(spec.type_definition)
    if spec.kind == NodeKind.OBJECT_TYPE:
        item.NodeClass = ua.NodeClass.ObjectType
        tattrs = ua.ObjectTypeAttributes()
        tattrs.DisplayName = ua.LocalizedText(spec.browse_name)
        tattrs.Description = ua.LocalizedText(spec.description)
        tattrs.IsAbstract = False
        item.NodeAttributes = tattrs
        return item
    if spec.kind in (NodeKind.FOLDER, NodeKind.OBJECT):
        item.NodeClass = ua.NodeClass.Object
        oattrs = ua.ObjectAttributes()
        oattrs.DisplayName = ua.LocalizedText(spec.browse_name)
        oattrs.Description = ua.LocalizedText(spec.description)
        item.NodeAttributes = oattrs
        return item
    item.NodeClass = ua.NodeClass.Variable
    attrs = ua.VariableAttributes()
    attrs.DisplayName = ua.LocalizedText(spec.browse_name)
    attrs.Description = ua.LocalizedText(spec.description)
    attrs.DataType = ua.NodeId(spec.data_type)
    attrs.ValueRank = spec.value_rank
    if spec.value_rank == 1:
        view = spec.view
        size = len(view.tags) if view is not None and spec.modelling_rule is None else 0
        attrs.ArrayDimensions = [size]
    level = ACCESS_READ_WRITE if spec.writable else ACCESS_READ
    attrs.AccessLevel = level
    attrs.UserAccessLevel = level
    if spec.modelling_rule is not None and spec.kind == NodeKind.VARIABLE:
        attrs.Value = ua.Variant()  # an instance declaration: no value of its own
    elif spec.view is not None:
        vt = VARIANT_TYPES[spec.view.type]
        attrs.Value = ua.Variant([variant(t, image.read(t)).Value for t in spec.view.tags], vt)
    elif spec.tag is not None:
        attrs.Value = variant(spec.tag, image.read(spec.tag))
    elif spec.browse_name == "ValueAsText" and spec.modelling_rule is None:
        owner = image.map.by_node_id(spec.parent if isinstance(spec.parent, str) else "")
        text = enum_text(owner, image.read(owner))
        attrs.Value = ua.Variant(ua.LocalizedText(text), ua.VariantType.LocalizedText)
    else:
        attrs.Value = _property_value(spec)
    item.NodeAttributes = attrs
    return item
