"""Register layout: from a site map to a :class:`TagMap`.

Every owner gets its own block of holding registers, at a documented base per kind:

=============  =========================  ========================================
kind           default base               block
=============  =========================  ========================================
Clock          0                          up to register 49
Diagnostics    50                         up to register 99
groups         ``[modbus] group_base``    100 + 20·k (k-th group of the site map)
watchdogs      ``[modbus] safety_base``   900 + 20·k (k-th ``[[watchdogs]]`` entry)
axes           ``[modbus] axis_base``     1000 + 50·k (k-th axis of the site map)
axis config    ``[modbus] axis_config_    3000 + 50·k: the k-th axis's configuration
               base``                     (read-only), its REAL mirrors, its fault
                                          words and fault injection bits
instructions   ``[modbus] instruction_    5000 + 100·k (k-th declared instance)
               base``
every_type     ``[modbus] every_type_     20000 + 100·(code − 1): ``<TYPE>_1`` at a block
               base``                     fixed by the type's stable code
                                          (``instructions.registry.TYPE_CODES``)
cam tables     ``[modbus] cam_base``      30000, each table after the one before it
                                          at the next multiple of 100 (k-th
                                          ``[[cams]]`` entry); unset and some other
                                          block past 30000: the first multiple of
                                          1000 after every other block
=============  =========================  ========================================

A cam table's block (base ``B``): read-only ``ProfileStatus`` DINT at B, ``Capacity``
DINT at B+2 and ``Number`` DINT at B+4; then the writable ``Length`` DINT at B+6 and
element k (0-based): ``Master[k]`` REAL at B+8+6·k, ``Slave[k]`` REAL at B+10+6·k,
``SegmentType[k]`` DINT at B+12+6·k (the Logix CAM element: REAL, REAL, DINT). The block
spans 8+6·capacity registers, rounded up to a multiple of 100.

An instance's ``modbus_base`` in the site map overrides its default base (it must be
even); a block larger than its stride takes the next multiple of the stride and moves the
blocks after it. Overlapping blocks are a site-map error naming the field.

Inside a block: first the read-only status region (a register of status BOOLs, bit 0 =
first BOOL, then the status words), then, from an even register, the writable command
region (a register of command BOOLs — the trigger is bit 0 — then the operands). The
Diagnostics block alone has its register of BOOLs after its words (``Ready`` was added
after them, which kept their registers). 32 and
64-bit values start on even registers; a 16-bit value may fill the hole an alignment
left. Command and status bits never share a register. Every register of a block is valid:
unused ones read 0; writes to the read-only part answer a Modbus exception.
"""

from __future__ import annotations

import builtins
import functools
import itertools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING

from ..instructions import Instruction, Kind, Operand, Quantity, StatusField, TagType, catalog
from ..instructions.registry import type_code
from ..kernel.config import DEFAULT_PERIOD, AxisConfig
from .axis_config import CONFIG_FIELDS, HOMING_FIELDS, mirror_fields
from .axis_faults import fault_fields
from .fields import (
    AXIS_FIELDS,
    DIAGNOSTICS_FIELDS,
    FEEDBACK_INPUT,
    GROUP_FIELDS,
    HOME_SWITCH,
    MARKER,
    WATCHDOG_FIELDS,
    FieldSpec,
    cam_fields,
    clock_fields,
    group_member,
    units_of,
)
from .model import MAX_ADDRESS, Access, Block, Folder, Tag, TagMap, TagMapError, WordOrder
from .units import axis_range, fixed_range, narrowed, operand_range

if TYPE_CHECKING:
    # the site map's schema only: the tag map never imports the config package at run
    # time (the config's loader imports this module to check the layout)
    from ..config.schema import InstanceSection, SiteMap

CLOCK_BASE = 0
#: the axis configuration blocks of a site whose axis blocks end at or below it
AXIS_CONFIG_BASE = 3000
DIAGNOSTICS_BASE = 50
GROUP_STRIDE = 20
AXIS_STRIDE = 50
WATCHDOG_STRIDE = 20
INSTRUCTION_STRIDE = 100
#: the cam tables' blocks: at 30000 unless some other block passes it
CAM_BASE = 30000
CAM_STRIDE = 100
#: owner names the server uses itself
RESERVED_OWNERS = ("Clock", "Diagnostics")

Problems = list[tuple[tuple[int | str, ...], str]]
#: the operands naming an instance's own axis and its master, in order of preference
OWN_AXIS = ("Axis", "SlaveAxis", "Slave")
MASTER_AXIS = ("MasterAxis", "Master", "Master1")


@dataclass(frozen=True)
class _Item:
    """A field on its way to becoming a tag."""

    field: str
    type: TagType
    writable: bool
    quantity: Quantity = Quantity.NONE
    enum: builtins.type[IntEnum] | None = None
    description: str = ""
    units: str = ""
    minimum: float | None = None
    maximum: float | None = None
    eu_range: tuple[float, float] | None = None
    exclusive_minimum: bool = False


class _Allocator:
    """Hands out registers upward from ``start``; 32/64-bit values go to even registers
    and a later 16-bit value fills the hole an alignment left."""

    def __init__(self, start: int) -> None:
        self.next = start
        self.holes: list[int] = []

    def take(self, words: int) -> int:
        if words == 1:
            if self.holes:
                return self.holes.pop(0)
            self.next += 1
            return self.next - 1
        if self.next % 2:
            self.holes.append(self.next)
            self.next += 1
        self.next += words
        return self.next - words


def _region(
    alloc: _Allocator, items: Sequence[_Item], bools_last: bool = False
) -> list[tuple[_Item, int, int | None]]:
    """Place a region's items: (item, address, bit). The registers of BOOLs come first,
    or after the words with ``bools_last``; then a word listed after the first BOOL comes
    after the BOOLs' registers (a word added to a block that has them moves nothing)."""
    placed: list[tuple[_Item, int, int | None]] = []
    bools = [i for i in items if i.type == TagType.BOOL]

    def place_bools() -> None:
        for k in range(0, len(bools), 16):
            reg = alloc.take(1)
            placed.extend((item, reg, bit) for bit, item in enumerate(bools[k : k + 16]))

    words = [i for i in items if i.type != TagType.BOOL]
    later: list[_Item] = []
    if not bools_last:
        place_bools()
    elif bools:
        first = items.index(bools[0])
        later = [i for i in items[first:] if i.type != TagType.BOOL]
        words = [i for i in items[:first] if i.type != TagType.BOOL]
    for item in words:
        placed.append((item, alloc.take(item.type.words), None))
    if bools_last:
        place_bools()
        for item in later:
            placed.append((item, alloc.take(item.type.words), None))
    return placed


def block_size(items: Sequence[_Item], bools_last: bool = False) -> tuple[int, int, int]:
    """(status end, command start, command end) offsets of a block holding ``items``."""
    alloc = _Allocator(0)
    _region(alloc, [i for i in items if not i.writable], bools_last)
    status_end = alloc.next
    writable = [i for i in items if i.writable]
    if not writable:
        return status_end, status_end, status_end
    start = status_end + status_end % 2
    alloc = _Allocator(start)
    _region(alloc, writable, bools_last)
    return status_end, start, alloc.next


Placed = tuple[tuple["_Item", int, int | None, int], ...]


@functools.lru_cache(maxsize=256)
def _block_plan(items: tuple[_Item, ...], bools_last: bool) -> tuple[int, int, Placed]:
    """(command start, command end, (item, offset, bit, words) of every item) of a
    block: the same for every block of one kind, so a site of 10,000 axes plans it once."""
    _, cmd_start, cmd_end = block_size(items, bools_last)
    placed = _region(_Allocator(0), [i for i in items if not i.writable], bools_last)
    placed += _region(_Allocator(cmd_start), [i for i in items if i.writable], bools_last)
    return cmd_start, cmd_end, tuple((i, off, bit, i.type.words) for i, off, bit in placed)


def _place(
    owner: str,
    folder: Folder,
    base: int,
    stride: int,
    items: Sequence[_Item],
    instruction: str = "",
    node_prefix: str = "",
    part: str = "",
    bools_last: bool = False,
) -> tuple[Block, Callable[[], list[Tag]]]:
    """The block of one owner, and a function making its tags (made only once the
    layout is known to be sound: a refused map of 10,000 axes needs blocks, not tags)."""
    cmd_start, cmd_end, placed = _block_plan(tuple(items), bools_last)
    size = max(cmd_end, 1)
    span = -(-size // stride) * stride
    block = Block(
        owner, folder, base, base + span, base + cmd_start, base + cmd_end, instruction, part
    )
    return block, functools.partial(
        _tags, owner, folder, base, placed, node_prefix or f"{folder.value}.{owner}", instruction
    )


def _tags(
    owner: str, folder: Folder, base: int, placed: Placed, prefix: str, instruction: str
) -> list[Tag]:
    return [
        Tag(
            name=f"{owner}.{item.field}",
            owner=owner,
            field=item.field,
            folder=folder,
            type=item.type,
            access=Access.READ_WRITE if item.writable else Access.READ,
            address=base + offset,
            count=words,
            bit=bit,
            node_id=f"{prefix}.{item.field}",
            units=item.units,
            quantity=item.quantity,
            enum=item.enum,
            description=item.description,
            minimum=item.minimum,
            maximum=item.maximum,
            instruction=instruction,
            eu_range=item.eu_range,
            exclusive_minimum=item.exclusive_minimum,
        )
        for item, offset, bit, words in placed
    ]


def _spec_items(
    specs: Iterable[FieldSpec],
    axis: AxisConfig | None = None,
    period: float = DEFAULT_PERIOD,
    owner: str = "",
    static: bool = False,
) -> list[_Item]:
    """Items of non-instruction fields; ``axis``: the owner's axis (units, ranges);
    ``static``: configuration values, whose range is [0, value]."""
    items = []
    for s in specs:
        span: tuple[float, float] | None = None
        if s.type.is_float:
            if static and axis is not None:
                value = _config_value(axis, s.name)
                span = (min(0.0, value), max(0.0, value)) if value is not None else None
            elif axis is not None:
                span = axis_range(s.quantity, axis, period, reported=True, field=s.name)
            else:
                span = fixed_range(owner, s.name, period)
        items.append(
            _Item(
                s.name,
                s.type,
                s.writable,
                s.quantity,
                s.enum,
                s.description,
                s.units or units_of(s.quantity, axis.units if axis else ""),
                eu_range=span,
            )
        )
    return items


def _config_value(cfg: AxisConfig, name: str) -> float | None:
    snake = "".join("_" + c.lower() if c.isupper() else c for c in name).lstrip("_")
    value = getattr(cfg, snake, None)
    return float(value) if isinstance(value, int | float) else None


def instruction_items(
    cls: type[Instruction],
    units: dict[str, str] | None = None,
    axes: dict[str, AxisConfig] | None = None,
    period: float = DEFAULT_PERIOD,
) -> list[_Item]:
    """The tags of one instruction type: its status fields (read) and its trigger and
    operands (read/write). ``units`` gives axis units and ``axes`` the axis
    configuration by operand-name prefix (``""`` for the instruction's own axis,
    ``"Master"`` for operands named Master...)."""
    units = units or {}
    axes = axes or {}

    def key(op: Operand | StatusField) -> str:
        return "Master" if op.name.startswith("Master") else ""

    def unit(op: Operand | StatusField) -> str:
        return units_of(op.quantity, units.get(key(op), ""))

    def span(op: Operand | StatusField) -> tuple[float, float] | None:
        if not op.type.is_float:
            return None
        cfg = axes.get(key(op))
        found = axis_range(op.quantity, cfg, period, reported=False) if cfg else None
        if isinstance(op, StatusField):
            return found
        if found is None:
            documented = operand_range(cls.TYPE, op.name)
            if documented is not None:
                return documented
            if op.minimum is None or op.maximum is None:
                return None
            return float(op.minimum), float(op.maximum)
        return narrowed(found, op.minimum, op.maximum)

    items = [
        _Item(f.name, f.type, False, f.quantity, f.enum, f.description, unit(f), eu_range=span(f))
        for f in cls.status_fields()
    ]
    for op in cls.input_operands():
        desc = op.description
        if op.kind == Kind.AXIS:
            desc = desc or "axis number"
        note = cls.gate_note(op.name)
        if note:
            desc = f"{desc}; {note}" if desc else note
        items.append(
            _Item(
                op.name,
                op.type,
                True,
                op.quantity,
                op.enum,
                desc,
                unit(op),
                op.minimum,
                op.maximum,
                span(op),
                exclusive_minimum=op.exclusive_min and op.minimum is not None,
            )
        )
    return items


def _instance_axes(inst: InstanceSection, configs: dict[int, AxisConfig]) -> dict[str, AxisConfig]:
    """The instance's own axis (key ``""``) and its master (``"Master"``), from its
    configured operands (see :mod:`.units` for the rule)."""
    cls = catalog()[inst.type]
    values = {op.name: inst.operands.get(op.name, op.default) for op in cls.OPERANDS}
    axes = {op.name: int(values[op.name]) for op in cls.OPERANDS if op.kind == Kind.AXIS}
    own = next((axes[n] for n in OWN_AXIS if n in axes), None)
    if own is None and axes:
        own = next(iter(axes.values()))
    master = next((axes[n] for n in MASTER_AXIS if n in axes), None)
    out: dict[str, AxisConfig] = {}
    if own is not None and own in configs:
        out[""] = configs[own]
    if master is not None and master in configs:
        out["Master"] = configs[master]
    return out


def _instance_units(inst: InstanceSection, axis_units: dict[int, str]) -> dict[str, str]:
    """Units of the instance's own axis and of its master, from its configured operands."""
    cls = catalog()[inst.type]
    values = {op.name: inst.operands.get(op.name, op.default) for op in cls.OPERANDS}
    axes = {op.name: int(values[op.name]) for op in cls.OPERANDS if op.kind == Kind.AXIS}
    own = next((axes[n] for n in OWN_AXIS if n in axes), None)
    if own is None and axes:
        own = next(iter(axes.values()))
    master = next((axes[n] for n in MASTER_AXIS if n in axes), None)
    out: dict[str, str] = {}
    if own is not None:
        out[""] = axis_units.get(own, "")
    if master is not None:
        out["Master"] = axis_units.get(master, "")
    return out


def build_tagmap(site: SiteMap) -> TagMap:
    """The tag map of a site; raises :class:`TagMapError` when blocks overlap."""
    tagmap, problems = plan_tagmap(site)
    if problems:
        raise TagMapError(problems)
    return tagmap


def layout_problems(site: SiteMap) -> Problems:
    """Layout errors of a site map as (field location, message) pairs."""
    return plan_tagmap(site)[1]


def plan_tagmap(site: SiteMap) -> tuple[TagMap, Problems]:
    """The tag map of a site and its layout errors ((field location, message) pairs);
    when there are errors the tag map holds the blocks only, no tags."""
    mb = site.modbus
    blocks: list[tuple[Block, tuple[int | str, ...]]] = []
    makers: list[Callable[[], list[Tag]]] = []

    def add(result: tuple[Block, Callable[[], list[Tag]]], where: tuple[int | str, ...]) -> int:
        block, make = result
        blocks.append((block, where))
        makers.append(make)
        return block.end

    group_configs = site.group_configs()
    base_period = min((g.coarse_update_period for g in group_configs), default=DEFAULT_PERIOD)
    add(
        _place(
            "Clock",
            Folder.CLOCK,
            CLOCK_BASE,
            DIAGNOSTICS_BASE - CLOCK_BASE,
            _spec_items(clock_fields(site.controller.remote_clock), None, base_period, "Clock"),
            node_prefix="Clock",
        ),
        ("controller",),
    )
    add(
        _place(
            "Diagnostics",
            Folder.DIAGNOSTICS,
            DIAGNOSTICS_BASE,
            50,
            _spec_items(DIAGNOSTICS_FIELDS, None, base_period, "Diagnostics"),
            node_prefix="Diagnostics",
            # Ready came after the words: they keep their registers
            bools_last=True,
        ),
        ("controller",),
    )
    period_of: dict[int, float] = {}
    for gc in group_configs:
        for number in gc.axes:
            period_of[number] = gc.coarse_update_period
    base = mb.group_base
    for gi, (g, gc) in enumerate(zip(site.groups, group_configs, strict=True)):
        items = _spec_items(GROUP_FIELDS, None, gc.coarse_update_period, g.name)
        items += _spec_items(group_member(k + 1) for k in range(len(g.axes)))
        base = add(_place(g.name, Folder.GROUPS, base, GROUP_STRIDE, items), ("groups", gi))
    base = mb.safety_base
    for wi, w in enumerate(site.watchdogs):
        items = _spec_items(WATCHDOG_FIELDS)
        base = add(_place(w.name, Folder.SAFETY, base, WATCHDOG_STRIDE, items), ("watchdogs", wi))
    base = mb.axis_base
    configs = site.axis_configs()
    for ai, (a, cfg) in enumerate(zip(site.axes, configs, strict=True)):
        specs = list(AXIS_FIELDS)
        if cfg.type.name == "FEEDBACK_ONLY" and cfg.feedback_signal.name == "INPUT":
            specs.append(FEEDBACK_INPUT)
        if cfg.home_switch is not None:
            specs.append(HOME_SWITCH)
        if cfg.marker_interval > 0.0:
            specs.append(MARKER)
        period = period_of.get(cfg.number, DEFAULT_PERIOD)
        items = _spec_items(specs, cfg, period)
        # the sensors' BOOLs after the words: an axis with sensors keeps the registers of
        # one without
        block = _place(a.name, Folder.AXES, base, AXIS_STRIDE, items, bools_last=True)
        base = add(block, ("axes", ai))

    def place_configuration(base: int) -> None:
        for ai, (a, cfg) in enumerate(zip(site.axes, configs, strict=True)):
            period = period_of.get(cfg.number, DEFAULT_PERIOD)
            items = _spec_items(CONFIG_FIELDS, cfg, period, static=True)
            if mb.real_mirrors:
                items += _spec_items(mirror_fields(AXIS_FIELDS), cfg, period)
            items += _spec_items(HOMING_FIELDS, cfg, period, static=True)
            items += _spec_items(fault_fields(cfg.type), cfg, period)
            block = _place(a.name, Folder.AXES, base, AXIS_STRIDE, items, part="configuration")
            base = add(block, ("modbus", "axis_config_base") if ai == 0 else ("axes", ai))

    # the axis configuration blocks: where the site map says, else at 3000 when the axis
    # blocks end there, else after every other block (a large site keeps its defaults)
    config_base = mb.axis_config_base
    if config_base is None and base <= AXIS_CONFIG_BASE:
        config_base = AXIS_CONFIG_BASE
    if config_base is not None:
        place_configuration(config_base)
    axis_units = {c.number: c.units for c in configs}
    by_number = {c.number: c for c in configs}
    declared = {inst.name: i for i, inst in enumerate(site.instructions.instances)}
    base = mb.instruction_base
    for inst in site.instances():
        i = declared.get(inst.name)
        where: tuple[int | str, ...] = (
            ("instructions", "instances", i) if i is not None else ("instructions", "every_type")
        )
        cls = catalog()[inst.type]
        own_axes = _instance_axes(inst, by_number)
        own = own_axes.get("")
        period = period_of.get(own.number, DEFAULT_PERIOD) if own else DEFAULT_PERIOD
        items = instruction_items(cls, _instance_units(inst, axis_units), own_axes, period)
        explicit = inst.modbus_base
        if i is None:
            # an every_type instance: a fixed block per type, stable as types are added
            explicit = mb.every_type_base + INSTRUCTION_STRIDE * (type_code(cls.TYPE) - 1)
        if explicit is not None:
            placed = _place(
                inst.name,
                Folder.INSTRUCTIONS,
                explicit,
                INSTRUCTION_STRIDE,
                items,
                cls.TYPE,
            )
            add(placed, (*where, "modbus_base") if i is not None else where)
            if i is not None:
                # the default slot of this declared instance stays free
                base += placed[0].size
        else:
            block = _place(
                inst.name, Folder.INSTRUCTIONS, base, INSTRUCTION_STRIDE, items, cls.TYPE
            )
            base = add(block, where)
    if site.cams:
        last = max(b.end for b, _ in blocks)
        base = CAM_BASE if last <= CAM_BASE else -(-last // 1000) * 1000
        if mb.cam_base is not None:
            base = mb.cam_base
        for ci, (cam, capacity) in enumerate(
            zip(site.cams, (c.size for c in site.cams), strict=True)
        ):
            items = _spec_items(cam_fields(capacity))
            block = _place(cam.name, Folder.CAMS, base, CAM_STRIDE, items)
            given = ci == 0 and mb.cam_base is not None
            base = add(block, ("modbus", "cam_base") if given else ("cams", ci))
    if config_base is None and site.axes:
        last = max(b.end for b, _ in blocks)
        place_configuration(-(-last // 1000) * 1000)
    problems = _overlaps(blocks) + _owner_clashes(site)
    for inst in site.instances():
        if inst.modbus_base is not None and inst.modbus_base % 2:
            i = declared[inst.name]
            problems.append(
                (
                    ("instructions", "instances", i, "modbus_base"),
                    f"{inst.name}: modbus_base {inst.modbus_base} must be even "
                    "(32/64-bit values start on even registers)",
                )
            )
    tagmap = TagMap(
        site=site.site.name,
        namespace_uri=site.site.namespace_uri or f"urn:motion-server:{site.site.name}",
        unit_id=mb.unit_id,
        word_order=WordOrder(mb.word_order),
        tags=() if problems else tuple(t for make in makers for t in make()),
        blocks=tuple(b for b, _ in blocks),
        source=site,
    )
    return tagmap, problems


def _overlaps(blocks: list[tuple[Block, tuple[int | str, ...]]]) -> Problems:
    out: Problems = []
    ordered = sorted(blocks, key=lambda bw: bw[0].base)
    for (prev, _), (cur, where) in itertools.pairwise(ordered):
        if cur.base < prev.end:
            out.append(
                (
                    where,
                    f"registers {cur.base}-{cur.end - 1} of {cur.owner} overlap "
                    f"{prev.base}-{prev.end - 1} of {prev.owner}",
                )
            )
    for b, where in blocks:
        if b.end - 1 > MAX_ADDRESS:
            out.append(
                (where, f"registers {b.base}-{b.end - 1} of {b.owner} pass register {MAX_ADDRESS}")
            )
    return out


def _owner_clashes(site: SiteMap) -> Problems:
    """Tag names are ``Owner.Field``: group, axis, instance (declared or every_type),
    watchdog and cam table names must differ, else their tags would merge into one owner's."""
    out: Problems = []
    seen: dict[str, str] = {name: "the server" for name in RESERVED_OWNERS}
    owners: list[tuple[str, tuple[int | str, ...], str]] = [
        (g.name, ("groups", i, "name"), "group") for i, g in enumerate(site.groups)
    ]
    owners += [(a.name, ("axes", i, "name"), "axis") for i, a in enumerate(site.axes)]
    # declared instances, then the every_type ones (their tags would merge just the same)
    declared = len(site.instructions.instances)
    owners += [
        (
            inst.name,
            ("instructions", "instances", i, "name")
            if i < declared
            else ("instructions", "every_type"),
            "instance",
        )
        for i, inst in enumerate(site.instances())
    ]
    owners += [(w.name, ("watchdogs", i, "name"), "watchdog") for i, w in enumerate(site.watchdogs)]
    owners += [(c.name, ("cams", i, "name"), "cam table") for i, c in enumerate(site.cams)]
    for name, where, what in owners:
        if name in seen and seen[name] != what:
            out.append((where, f"{what} name {name!r} is already used by {seen[name]}"))
        seen.setdefault(name, what)
    return out
