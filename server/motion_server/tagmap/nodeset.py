"""The OPC UA node tree of a tag map: types and instances (the NodeSet2 writer is in
:mod:`.nodeset_xml`).

:func:`node_plan` lists every node of the site's namespace once. Both the OPC UA
front-end and ``motion-server map --format nodeset`` are built from it, so the served tree
and the export cannot differ.

Types (string NodeIds under ``Types.``):

- one ObjectType per instruction type, ``<TYPE>_Type`` (``MAG_Type``, ``MC_GearIn_Type``),
  a subtype of OPC 30000's ``CtrlFunctionBlockType`` (PLCopen IEC 61131-3 companion
  specification); its trigger and operands are instance declarations referenced with
  ``HasInputVar``, its status outputs with ``HasOutputVar`` (ModellingRule Mandatory);
- ``MotionAxisType`` and ``MotionGroupType`` (subtypes of BaseObjectType) with the axis and
  group fields as components (Mandatory where every axis or group has the field,
  Optional otherwise: a hand wheel's ``FeedbackInput``, a group's ``Member<k>``);
- ``CamTableType`` (a subtype of BaseObjectType): ``ProfileStatus``, ``Capacity``,
  ``Number``, ``Length`` and the array views ``MasterValues``, ``SlaveValues``,
  ``SegmentTypes`` (one-dimensional arrays, capacity long), all Mandatory; a table's
  element variables (``Master[k]`` ...) are components of the table only, as their number
  is the table's capacity.

Instances: the folders ``Clock``, ``Diagnostics``, ``Groups``, ``Axes``, ``Instructions``,
``Safety``, ``Cams`` under the Objects folder; one object per axis, group, watchdog, cam
table and instruction instance, typed by its ObjectType; one variable per tag (NodeId =
``tag.node_id``, e.g. ``Instructions.MAG_1.Ratio``), referenced from an instruction
instance with ``HasInputVar``/``HasOutputVar`` as its type declares it, from other objects
with ``HasComponent``. An instruction instance also keeps two folders, ``InputVariables`` and
``OutputVariables``, that organize the same variables for clients that do not follow the
PLCopen reference types.

Variables:

- REAL/LREAL values with a quantity or units are analog: ``AnalogItemType`` with
  ``EURange`` (from the axis limits, :mod:`.units`) and ``EngineeringUnits``
  (``EUInformation`` with the UNECE code); those without a range (gear ratios) are
  ``BaseAnalogType`` with ``EngineeringUnits`` only;
- enumerated values are ``MultiStateValueDiscreteType`` with ``EnumValues`` and
  ``ValueAsText``;
- every other value is a ``BaseDataVariableType``.

DataTypes: BOOL Boolean, SINT SByte, INT Int16, DINT Int32, UDINT UInt32, REAL Float,
LREAL Double. Access level: CurrentRead, plus CurrentWrite for writable tags.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from ..instructions.schema import Quantity, TagType
from .cams import ArrayView, cam_tables
from .companion import CTRL_FUNCTION_BLOCK_TYPE, HAS_INPUT_VAR, HAS_OUTPUT_VAR, PLCOPEN_URI
from .model import Folder, Tag, TagMap
from .units import RATIO_UNIT, UNECE_NAMESPACE, unit_of

__all__ = ["UNECE_NAMESPACE"]


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
    HAS_MODELLING_RULE = 37
    HAS_TYPE_DEFINITION = 40
    HAS_SUBTYPE = 45
    HAS_PROPERTY = 46
    HAS_COMPONENT = 47
    BASE_OBJECT_TYPE = 58
    FOLDER_TYPE = 61
    BASE_DATA_VARIABLE_TYPE = 63
    PROPERTY_TYPE = 68
    MANDATORY = 78
    OPTIONAL = 80
    OBJECTS_FOLDER = 85
    RANGE = 884
    RANGE_XML = 885
    EU_INFORMATION = 887
    EU_INFORMATION_XML = 888
    ANALOG_ITEM_TYPE = 2368
    ENUM_VALUE_TYPE = 7594
    ENUM_VALUE_TYPE_XML = 7616
    MULTI_STATE_VALUE_DISCRETE_TYPE = 11238
    BASE_ANALOG_TYPE = 15318


@dataclass(frozen=True)
class Ext:
    """A node of another namespace: its namespace URI ("" = the OPC UA base namespace)
    and numeric identifier."""

    uri: str
    id: int


def ns0(node: Ns0) -> Ext:
    return Ext("", int(node))


CTRL_FUNCTION_BLOCK = Ext(PLCOPEN_URI, CTRL_FUNCTION_BLOCK_TYPE)
INPUT_VAR = Ext(PLCOPEN_URI, HAS_INPUT_VAR)
OUTPUT_VAR = Ext(PLCOPEN_URI, HAS_OUTPUT_VAR)

DATA_TYPES: dict[TagType, Ns0] = {
    TagType.BOOL: Ns0.BOOLEAN,
    TagType.SINT: Ns0.SBYTE,
    TagType.INT: Ns0.INT16,
    TagType.DINT: Ns0.INT32,
    TagType.UDINT: Ns0.UINT32,
    TagType.REAL: Ns0.FLOAT,
    TagType.LREAL: Ns0.DOUBLE,
}

ACCESS_READ = 1
ACCESS_READ_WRITE = 3
ANALOG_QUANTITIES = frozenset(
    {Quantity.POSITION, Quantity.VELOCITY, Quantity.ACCELERATION, Quantity.JERK, Quantity.RATIO}
)
TYPES = "Types"
AXIS_TYPE = f"{TYPES}.MotionAxisType"
GROUP_TYPE = f"{TYPES}.MotionGroupType"
CAM_TABLE_TYPE = f"{TYPES}.CamTableType"


class NodeKind(IntEnum):
    FOLDER = 0
    OBJECT = 1
    VARIABLE = 2
    PROPERTY = 3
    OBJECT_TYPE = 4


@dataclass(frozen=True)
class EUInfo:
    """The EngineeringUnits property value: the units as the tag map names them, their
    UNECE symbol (DisplayName) and name (Description), and the UnitId (-1: no code)."""

    units: str
    unit_id: int
    symbol: str = ""
    name: str = ""


def eu_info(units: str) -> EUInfo:
    unit = unit_of(units)
    if unit is None:
        return EUInfo(units, -1, units, units)
    return EUInfo(units, unit.unit_id, unit.symbol, unit.name)


@dataclass(frozen=True)
class NodeSpec:
    """One node of the site's namespace. ``parent``: a node of the site (its string
    id), another namespace's node (:class:`Ext`), or None = the Objects folder;
    ``reference`` is the reference type from the parent; ``organizes`` lists node ids the
    node organizes besides its children (the function-block variable groups);
    ``modelling_rule`` marks an instance declaration of a type."""

    node_id: str
    parent: str | Ext | None
    browse_name: str
    kind: NodeKind
    reference: Ext
    type_definition: Ext | str | None
    tag: Tag | None = None
    data_type: Ns0 = Ns0.BOOLEAN
    value: Any = None
    value_rank: int = -1
    description: str = ""
    organizes: tuple[str, ...] = field(default=())
    modelling_rule: Ext | None = None
    #: a cam table's array view (an array variable served from its element tags)
    view: ArrayView | None = None

    @property
    def writable(self) -> bool:
        if self.modelling_rule is not None:
            return False
        if self.view is not None:
            return self.view.writable
        return self.tag is not None and self.tag.writable


def unit_id(units: str) -> int:
    """The OPC UA UnitId of one of our unit strings, -1 if it has no UNECE code."""
    return eu_info(units).unit_id


def is_analog(tag: Tag) -> bool:
    return tag.type.is_float and (bool(tag.units) or tag.quantity in ANALOG_QUANTITIES)


def engineering_units(tag: Tag) -> EUInfo | None:
    """The EngineeringUnits of an analog tag (None: it has no units)."""
    if tag.units:
        return eu_info(tag.units)
    if tag.quantity == Quantity.RATIO:
        return EUInfo(RATIO_UNIT.symbol, RATIO_UNIT.unit_id, RATIO_UNIT.symbol, RATIO_UNIT.name)
    return None


def eu_range(tag: Tag) -> tuple[float, float] | None:
    """(low, high) of the EURange (:mod:`.units`), None when the tag has none."""
    return tag.eu_range


def variable_type(tag: Tag) -> Ns0:
    if tag.enum is not None:
        return Ns0.MULTI_STATE_VALUE_DISCRETE_TYPE
    if is_analog(tag):
        return Ns0.ANALOG_ITEM_TYPE if tag.eu_range is not None else Ns0.BASE_ANALOG_TYPE
    return Ns0.BASE_DATA_VARIABLE_TYPE


def parent_of(tag: Tag) -> str:
    return tag.node_id.rsplit(".", 1)[0]


def type_of_instruction(instruction: str) -> str:
    return f"{TYPES}.{instruction}_Type"


def type_of(folder: Folder, tags: list[Tag]) -> str | Ext:
    """The type definition of the object owning ``tags``."""
    if folder == Folder.INSTRUCTIONS:
        return type_of_instruction(tags[0].instruction)
    if folder == Folder.AXES:
        return AXIS_TYPE
    if folder == Folder.GROUPS:
        return GROUP_TYPE
    if folder == Folder.CAMS:
        return CAM_TABLE_TYPE
    return ns0(Ns0.BASE_OBJECT_TYPE)


def var_reference(tag: Tag) -> Ext:
    """The reference from an object to its variable."""
    if tag.folder == Folder.INSTRUCTIONS:
        return INPUT_VAR if tag.writable else OUTPUT_VAR
    return ns0(Ns0.HAS_COMPONENT)


def node_plan(tagmap: TagMap) -> list[NodeSpec]:
    """Every node of the site's namespace, types first, parents before children."""
    owners: dict[str, list[Tag]] = {}
    for tag in tagmap:
        owners.setdefault(parent_of(tag), []).append(tag)
    out = _types(owners, {c.name: c.views for c in cam_tables(tagmap)})
    for folder in Folder:
        out.append(
            NodeSpec(
                folder.value,
                None,
                folder.value,
                NodeKind.FOLDER,
                ns0(Ns0.ORGANIZES),
                ns0(Ns0.FOLDER_TYPE),
            )
        )
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
                ns0(Ns0.ORGANIZES),
                type_of(tags[0].folder, tags),
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
                        ns0(Ns0.HAS_COMPONENT),
                        ns0(Ns0.FOLDER_TYPE),
                        organizes=members,
                    )
                )
    for parent, tags in owners.items():
        for tag in tags:
            ref = ns0(Ns0.ORGANIZES) if "." not in parent else var_reference(tag)
            out += _variable(tag, tag.node_id, parent, ref)
    for cam in cam_tables(tagmap):
        out += [array_variable(v, v.node_id, cam.node_id) for v in cam.views]
    return out


def array_variable(view: ArrayView, node_id: str, parent: str, rule: Ext | None = None) -> NodeSpec:
    """The node of a cam table's array view (or, with ``rule``, its declaration)."""
    return NodeSpec(
        node_id,
        parent,
        view.name,
        NodeKind.VARIABLE,
        ns0(Ns0.HAS_COMPONENT),
        ns0(Ns0.BASE_DATA_VARIABLE_TYPE),
        data_type=DATA_TYPES[view.type],
        value_rank=1,
        description=view.description,
        modelling_rule=rule,
        view=view,
    )


def _types(
    owners: dict[str, list[Tag]], cam_views: dict[str, tuple[ArrayView, ...]]
) -> list[NodeSpec]:
    """The ObjectTypes and their instance declarations (``cam_views``: the array views
    of every cam table, by name)."""
    by_type: dict[str, tuple[Ext, list[list[Tag]]]] = {}
    for tags in owners.values():
        folder = tags[0].folder
        if folder == Folder.INSTRUCTIONS:
            type_id, supertype = type_of_instruction(tags[0].instruction), CTRL_FUNCTION_BLOCK
        elif folder in (Folder.AXES, Folder.GROUPS):
            type_id = AXIS_TYPE if folder == Folder.AXES else GROUP_TYPE
            supertype = ns0(Ns0.BASE_OBJECT_TYPE)
        elif folder == Folder.CAMS:
            # the header and the array views: the element variables depend on the
            # capacity, so each table carries its own (components the type does not declare)
            type_id, supertype = CAM_TABLE_TYPE, ns0(Ns0.BASE_OBJECT_TYPE)
            tags = [t for t in tags if "[" not in t.field]
        else:
            continue
        by_type.setdefault(type_id, (supertype, []))[1].append(tags)
    out: list[NodeSpec] = []
    for type_id, (supertype, instances) in sorted(by_type.items()):
        name = type_id.removeprefix(f"{TYPES}.")
        instruction = instances[0][0].instruction
        desc = (
            f"{instruction} instruction (OPC 30000 function block)"
            if instruction
            else "a cam table (Logix CAM array) and its CAM_PROFILE Status"
            if type_id == CAM_TABLE_TYPE
            else f"a motion {'axis' if type_id == AXIS_TYPE else 'group'}"
        )
        out.append(
            NodeSpec(
                type_id,
                supertype,
                name,
                NodeKind.OBJECT_TYPE,
                ns0(Ns0.HAS_SUBTYPE),
                None,
                description=desc,
            )
        )
        fields: dict[str, Tag] = {}
        counts: dict[str, int] = {}
        for tags in instances:
            for tag in tags:
                fields.setdefault(tag.field, tag)
                counts[tag.field] = counts.get(tag.field, 0) + 1
        for fname, tag in fields.items():
            rule = Ns0.MANDATORY if counts[fname] == len(instances) else Ns0.OPTIONAL
            out += _variable(
                tag, f"{type_id}.{fname}", type_id, var_reference(tag), ns0(rule), declaration=True
            )
        if type_id == CAM_TABLE_TYPE:
            views = cam_views[instances[0][0].owner]
            mandatory = ns0(Ns0.MANDATORY)
            out += [array_variable(v, f"{type_id}.{v.name}", type_id, mandatory) for v in views]
    return out


def _variable(
    tag: Tag,
    node_id: str,
    parent: str,
    ref: Ext,
    rule: Ext | None = None,
    declaration: bool = False,
) -> list[NodeSpec]:
    typedef = variable_type(tag)
    var = NodeSpec(
        node_id,
        parent,
        tag.field,
        NodeKind.VARIABLE,
        ref,
        ns0(typedef),
        tag=tag,
        data_type=DATA_TYPES[tag.type],
        description=tag.description,
        modelling_rule=rule,
    )
    props: list[NodeSpec] = []

    def prop(name: str, data_type: Ns0, value: Any, rank: int = -1) -> None:
        props.append(
            NodeSpec(
                f"{node_id}.{name}",
                node_id,
                name,
                NodeKind.PROPERTY,
                ns0(Ns0.HAS_PROPERTY),
                ns0(Ns0.PROPERTY_TYPE),
                data_type=data_type,
                value=value,
                value_rank=rank,
                modelling_rule=ns0(Ns0.MANDATORY) if rule is not None else None,
            )
        )

    if typedef in (Ns0.ANALOG_ITEM_TYPE, Ns0.BASE_ANALOG_TYPE):
        # a type's declaration carries no value: each instance has its axis's units
        span = tag.eu_range
        if span is not None:
            prop("EURange", Ns0.RANGE, None if declaration else span)
        eu = engineering_units(tag)
        if eu is not None:
            prop("EngineeringUnits", Ns0.EU_INFORMATION, None if declaration else eu)
    elif typedef == Ns0.MULTI_STATE_VALUE_DISCRETE_TYPE:
        prop("EnumValues", Ns0.ENUM_VALUE_TYPE, tuple(tag.enum_members().items()), rank=1)
        prop("ValueAsText", Ns0.LOCALIZED_TEXT, None if declaration else "")
    return [var, *props]


def enum_text(tag: Tag, value: Any) -> str:
    """The ValueAsText of an enumerated value (the member name, else the number)."""
    for name, v in tag.enum_members().items():
        if v == value:
            return name
    return str(value)
