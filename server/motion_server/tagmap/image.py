"""The tag image: every tag of a :class:`TagMap` bound to a running :class:`MotionSystem`.

This is the scan's side of the tags: a getter and (for writable tags) a setter per tag.
The scan applies judged client writes through :meth:`TagImage.write_many` and fills the
shared image from the getters after every cycle (:mod:`motion_server.scan.filler`);
front-ends never touch it (they read the shared image: ``frontends/view.py``). Writes to
instruction operands land in the instance's ``inputs``; the instance latches them on its
own trigger edge. Clock and hand-wheel writes act at once. Tools and unit tests use it
directly on a system, with :class:`StandaloneHost` as the clock. Errors are
protocol-neutral (:mod:`.errors`); each front-end maps them to its own codes.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..instructions import MotionSystem
from ..instructions.schema import TagType
from ..kernel import Axis, Controller, MotionError
from ..kernel.faults import axis_error_id_array, servo_fault_array
from ..kernel.group import MotionGroup
from ..kernel.homing import Homing
from .axis_config import CONFIG_GETTERS, MIRRORS
from .axis_faults import FAULT_GETTERS, INJECT_CAUSES
from .codec import Value, encoder
from .errors import AddressError, ReadOnlyError, TagAccessError
from .fields import ClockMode, cam_element_of
from .judge import Judge
from .model import Folder, Tag, TagMap, UnknownTagError
from .registers import RegisterWrites


class Host(Protocol):
    """What the image needs from whoever runs the cycles (the runtime, or
    :class:`StandaloneHost` in tests): the clock and the diagnostics counters."""

    mode: ClockMode
    scale: float
    heartbeat: int
    overruns: int
    dropped: int
    last_cycle_time: float
    max_cycle_time: float
    version: str
    #: percent of the last second spent in cycles; write batches waiting; restarts
    load: float
    queued_writes: int
    restarts: int

    @property
    def ready(self) -> bool:
        """True while the controller runs (cycles are being run, or run on request)."""

    #: ``Clock.Snapshot``, and the snapshot command bits (cleared once done)
    snapshot_number: int
    snapshot_save: bool
    snapshot_restore: bool
    #: ``Clock.CommFault``, ``CommDelay`` (ms), ``CommDuration`` (ms), ``CommClientPort``
    comm: CommSettings

    def set_mode(self, mode: ClockMode) -> None: ...

    def request_cycles(self, count: int) -> None: ...

    def snapshot(self, kind: str) -> None:
        """A rising edge of ``Clock.SnapshotSave`` (``kind`` "save") or
        ``SnapshotRestore`` ("restore"), of snapshot ``snapshot_number``;
        :class:`TagAccessError` when it cannot be done."""

    def comm_changed(self) -> None:
        """A ``Clock.Comm...`` tag was written."""

    async def settle(self) -> None:
        """Return once the cycles requested so far have run."""


@dataclass
class CommSettings:
    """The communication fault the Clock tags ask for (front-ends apply it)."""

    mode: int = 0
    delay: int = 0
    duration: int = 0
    client_port: int = 0


class StandaloneHost:
    """A host without a clock loop: manual time, requested cycles run at once; no
    snapshots (the scan keeps them)."""

    snapshot_number = 0
    snapshot_save = False
    snapshot_restore = False

    def __init__(self, system: MotionSystem, version: str = "0.0.0") -> None:
        self.system = system
        self.mode = ClockMode.MANUAL
        self.scale = 1.0
        self.heartbeat = 0
        self.overruns = 0
        self.dropped = 0
        self.last_cycle_time = 0.0
        self.max_cycle_time = 0.0
        self.version = version
        self.load = 0.0
        self.queued_writes = 0
        self.restarts = 0
        self.ready = True
        self.comm = CommSettings()

    def set_mode(self, mode: ClockMode) -> None:
        self.mode = mode

    def snapshot(self, kind: str) -> None:
        raise TagAccessError("snapshots are kept by the scan: this host has none")

    def comm_changed(self) -> None:
        return None

    def request_cycles(self, count: int) -> None:
        for _ in range(count):
            self.system.cycle()
            self.heartbeat = (self.heartbeat + 1) & 0xFFFFFFFF

    async def settle(self) -> None:
        return None


Getter = Callable[[], Value]
Setter = Callable[[Value], None]


@dataclass
class _Slot:
    """Registers read or written together: one 16/32/64-bit tag, or a register of BOOLs."""

    address: int
    count: int
    tags: list[Tag]
    read: Callable[[], tuple[int, ...]]

    @property
    def end(self) -> int:
        return self.address + self.count


_UINT32 = 0xFFFFFFFF
#: Clock communication-fault field -> attribute of ``CommSettings``
_COMM = {
    "CommFault": "mode",
    "CommDelay": "delay",
    "CommDuration": "duration",
    "CommClientPort": "client_port",
}

AXIS_GETTERS: dict[str, Callable[[Axis], Value]] = {
    "Number": lambda ax: ax.number,
    "Type": lambda ax: int(ax.type),
    "AxisState": lambda ax: int(ax.state),
    "PLCopenState": lambda ax: int(ax.plcopen_state),
    "MotionStatus": lambda ax: ax.motion_status,
    "AxisFault": lambda ax: int(ax.fault),
    "ActualPosition": lambda ax: ax.actual_position,
    "CommandPosition": lambda ax: ax.command_position,
    "ActualVelocity": lambda ax: ax.actual_velocity,
    "CommandVelocity": lambda ax: ax.command_velocity,
    "CommandAcceleration": lambda ax: ax.command_acceleration,
    "PositionError": lambda ax: ax.position_error,
    "FeedbackInput": lambda ax: ax.feedback_input,
    **CONFIG_GETTERS,
    **FAULT_GETTERS,
}
AXIS_GETTERS.update({mirror: AXIS_GETTERS[source] for mirror, source in MIRRORS.items()})


def _switch_getter(homing: Homing, ax: Axis) -> Getter:
    return lambda: homing.switch(ax)


def _marker_getter(homing: Homing, ax: Axis) -> Getter:
    seen, i = homing.marker_seen, ax.index
    return lambda: seen(i)


#: axis fields read from the kernel's homing sensors (the axes that have them)
SENSOR_FIELDS: dict[str, Callable[[Homing, Axis], Getter]] = {
    "HomeSwitch": _switch_getter,
    "Marker": _marker_getter,
}


def wrapped(ctl: Controller, positions: np.ndarray) -> np.ndarray:
    """``positions`` (all axes, unwound) as :meth:`Axis.wrap` reads them, vectorised
    with the same operations (C ``fmod``, then + rollover below 0)."""
    rot = ctl.rotary_idx
    if rot.size == 0:
        return positions
    out = positions.copy()
    r = ctl.rollover[rot]
    w = np.fmod(positions[rot], r)
    out[rot] = np.where(w < 0.0, w + r, w)
    return out


#: the axis fields that are plain functions of the kernel arrays: every axis at once, in
#: axis index order, equal to ``AXIS_GETTERS`` (a test checks it)
AXIS_ARRAYS: dict[str, Callable[[Controller], np.ndarray]] = {
    "ActualPosition": lambda ctl: wrapped(ctl, ctl.act_pos),
    "CommandPosition": lambda ctl: wrapped(ctl, ctl.cmd_pos),
    "ActualVelocity": lambda ctl: ctl.act_vel,
    "CommandVelocity": lambda ctl: ctl.cmd_vel,
    "CommandAcceleration": lambda ctl: ctl.cmd_acc,
    "PositionError": lambda ctl: ctl.cmd_pos - ctl.act_pos,
}

#: the axis status words the kernel gives for every axis at once
#: (``Controller.status_arrays()``): tag field -> field of its ``StatusArrays``
AXIS_STATUS: dict[str, str] = {
    "AxisState": "axis_state",
    "PLCopenState": "plcopen_state",
    "MotionStatus": "motion_status",
    "AxisFault": "fault",
}

#: the axis fault words, computed for every axis at once from the AxisFault bits (the
#: ``fault`` array of ``Controller.status_arrays()``); equal to ``AXIS_GETTERS``
AXIS_FAULT_WORDS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "ServoFault": servo_fault_array,
    "AxisErrorID": axis_error_id_array,
}

#: fields whose value never changes while the server runs (configuration)
STATIC_FIELDS: dict[Folder, frozenset[str]] = {
    Folder.AXES: frozenset({"Number", "Type", *CONFIG_GETTERS}),
    Folder.GROUPS: frozenset({"Number", "CoarseUpdatePeriod", "AxisCount"}),
    Folder.DIAGNOSTICS: frozenset(
        {"VersionMajor", "VersionMinor", "VersionPatch", "AxisCount", "GroupCount"}
    ),
    Folder.CAMS: frozenset({"Capacity", "Number"}),
}


def is_static(tag: Tag) -> bool:
    """True for a tag whose value is fixed by the configuration (a publisher sends it
    once)."""
    if tag.folder == Folder.GROUPS and tag.field.startswith("Member"):
        return True
    return tag.field in STATIC_FIELDS.get(tag.folder, frozenset())


GROUP_GETTERS: dict[str, Callable[[MotionGroup], Value]] = {
    "Number": lambda g: g.number,
    "GroupState": lambda g: int(g.state),
    "CoarseUpdatePeriod": lambda g: g.period * 1000.0,
    "AxisCount": lambda g: len(g.axes),
}


def check_registers(tagmap: TagMap, address: int, count: int, write: bool) -> None:
    """:class:`AddressError` unless every register is in the map; for a write,
    :class:`ReadOnlyError` unless every register is in a block's command region."""
    if count < 1 or address < 0:
        raise AddressError(f"bad register range {address}+{count}")
    a, end = address, address + count
    while a < end:
        block = tagmap.block_at(a)
        if block is None:
            raise AddressError(f"register {a} is outside the map")
        if not write:
            a = block.end
        elif block.command_start <= a < block.command_end:
            a = block.command_end
        else:
            raise ReadOnlyError(f"register {a} ({block.owner}) is read-only")


class TagImage:
    """Live values of ``tagmap`` on ``system``: :meth:`read`/:meth:`write` by tag,
    :meth:`read_registers`/:meth:`write_registers` by holding register."""

    def __init__(
        self,
        tagmap: TagMap,
        system: MotionSystem,
        host: Host | None = None,
        bindings: Mapping[str, tuple[Getter, Setter | None]] | None = None,
        judge: Judge | None = None,
    ) -> None:
        self.map = tagmap
        #: judges every written value (type, range, the kernel's numeric boundary)
        self.judge = judge if judge is not None else Judge.for_system(tagmap, system)
        self.system = system
        self.host: Host = host if host is not None else StandaloneHost(system)
        #: getter/setter by tag name for the Safety folder (watchdogs: the runtime's)
        self._bindings = dict(bindings or {})
        #: called after every accepted write with (tag, old value, new value): audit log
        self.observers: list[Callable[[Tag, Value, Value], None]] = []
        self.step_cycles = 1
        self.step = False
        self._requested = 0
        self._get: dict[str, Getter] = {}
        self._set: dict[str, Setter] = {}
        #: cam table name -> number (made when the first cam tag is bound)
        self._cam_numbers: dict[str, int] | None = None
        for tag in tagmap:
            self._bind(tag)
        self._slots = self._build_slots()
        self._writes = RegisterWrites(tagmap.tags, tagmap.word_order)
        #: bumped by every write: part of the key of the block copies
        self.generation = 0
        self._copies: dict[int, tuple[tuple[int, int], list[int]]] = {}
        # the slots of every block (both sorted by address: one pass, not blocks x slots)
        starts = [slot.address for slot in self._slots]
        self._block_slots = {
            b.base: self._slots[bisect_left(starts, b.base) : bisect_left(starts, b.end)]
            for b in tagmap.blocks
        }

    # -- by tag -----------------------------------------------------------------------------
    def tag(self, tag: Tag | str) -> Tag:
        return tag if isinstance(tag, Tag) else self.map.tag(tag)

    def read(self, tag: Tag | str) -> Value:
        """The value of a tag as of the last completed cycle (or as last written)."""
        return self._get[self.tag(tag).name]()

    def axis_values(self, field: str) -> np.ndarray:
        """The values of an ``AXIS_ARRAYS`` field for every axis (by axis index), as of
        the last completed cycle. The result may be the kernel's own array: index it (a
        copy) before the next cycle."""
        return AXIS_ARRAYS[field](self.system.ctl)

    def write(self, tag: Tag | str, value: Any) -> int:
        """Write one tag: :class:`ReadOnlyError`, :class:`BadValueError` on refusal.
        Returns the number of cycles the write asked for (a ``Clock.Step`` edge)."""
        return self.write_many([(self.tag(tag), value)])

    def write_many(self, updates: Iterable[tuple[Tag | str, Any]]) -> int:
        """Write several tags all or nothing: every value is judged before any is set;
        words are set before bits, so a trigger sees the operands written with it.
        Returns the number of cycles requested (await :meth:`settle` for them)."""
        staged: list[tuple[Tag, Value]] = []
        for ref, value in updates:
            tag = self.tag(ref)
            if not tag.writable:
                raise ReadOnlyError(f"{tag.name} is read-only")
            staged.append((tag, self._judge(tag, value)))
        staged.sort(key=lambda tv: tv[0].type == TagType.BOOL)
        self.generation += 1
        self._requested = 0
        observers = self.observers
        try:
            for tag, value in staged:
                if not observers:
                    self._set[tag.name](value)
                    continue
                old = self._get[tag.name]()
                self._set[tag.name](value)
                for observe in observers:
                    observe(tag, old, value)
        finally:
            self.generation += 1  # a Clock.Step write may have run cycles
        return self._requested

    async def settle(self) -> None:
        """Wait until the cycles a Clock.Step write asked for have run."""
        await self.host.settle()

    # -- by register ------------------------------------------------------------------------
    def check(self, address: int, count: int, write: bool) -> None:
        """:class:`AddressError` unless every register is in the map (and writable)."""
        check_registers(self.map, address, count, write)

    def read_registers(self, address: int, count: int, check: bool = True) -> list[int]:
        """``count`` registers from ``address`` (unused registers of a block read 0)."""
        if check:
            self.check(address, count, write=False)
        out: list[int] = []
        end = address + count
        a = address
        while a < end:
            block = self.map.block_at(a)
            if block is None:  # only without check: outside the map reads 0
                out.append(0)
                a += 1
                continue
            words = self.block_registers(block.base)
            stop = min(end, block.end)
            out += words[a - block.base : stop - block.base]
            a = stop
        return out

    def block_registers(self, base: int) -> list[int]:
        """All registers of the block at ``base``, encoded once per cycle."""
        key = (self.system.ctl.tick, self.generation)
        copy = self._copies.get(base)
        if copy is not None and copy[0] == key:
            return copy[1]
        block = self.map.block_at(base)
        assert block is not None
        words = [0] * block.size
        for s in self._block_slots[base]:
            lo = s.address - base
            words[lo : lo + s.count] = s.read()
        self._copies[base] = (key, words)
        return words

    def write_registers(self, address: int, values: Sequence[int], check: bool = True) -> int:
        """Write registers (see :class:`RegisterWrites`). Returns the number of cycles
        requested (Clock.Step)."""
        if check:
            self.check(address, len(values), write=True)
        return self.write_many(self._writes.updates(address, values, self._current))

    def _current(self, address: int, count: int) -> list[int]:
        return self.read_registers(address, count, check=False)

    # -- binding ----------------------------------------------------------------------------
    def _judge(self, tag: Tag, value: Any) -> Value:
        return self.judge(tag, value)

    def getter(self, name: str) -> Getter:
        """The function that reads tag ``name`` from the system."""
        return self._get[name]

    def setter(self, name: str) -> Setter:
        """The function that writes tag ``name`` (a writable tag) into the system."""
        return self._set[name]

    def _bind(self, tag: Tag) -> None:
        binders = {
            Folder.INSTRUCTIONS: self._bind_instruction,
            Folder.AXES: self._bind_axis,
            Folder.GROUPS: self._bind_group,
            Folder.DIAGNOSTICS: self._bind_diagnostics,
            Folder.CLOCK: self._bind_clock,
            Folder.SAFETY: self._bind_safety,
            Folder.CAMS: self._bind_cam,
        }
        try:
            binders[tag.folder](tag)
        except (KeyError, MotionError) as exc:
            raise UnknownTagError(f"{tag.name}: nothing to bind it to ({exc})") from None

    def _bind_instruction(self, tag: Tag) -> None:
        inst = self.system.instances[tag.owner]
        key = tag.field
        if tag.writable:
            inputs = inst.inputs
            if key not in inputs:
                raise KeyError(key)
            self._get[tag.name] = lambda: inputs[key]

            def set_input(value: Value) -> None:
                inputs[key] = value

            self._set[tag.name] = set_input
        else:
            outputs = inst.outputs
            if key not in outputs:
                raise KeyError(key)
            self._get[tag.name] = lambda: outputs[key]

    def _bind_safety(self, tag: Tag) -> None:
        get, set_ = self._bindings[tag.name]
        self._get[tag.name] = get
        if tag.writable:
            if set_ is None:
                raise KeyError(tag.name)
            self._set[tag.name] = set_
        elif set_ is not None:
            raise KeyError(f"{tag.name} is read-only")

    def _bind_axis(self, tag: Tag) -> None:
        ctl = self.system.ctl
        ax = ctl.axis(tag.owner)
        if tag.field in SENSOR_FIELDS:
            self._get[tag.name] = SENSOR_FIELDS[tag.field](ctl.homing, ax)
            return
        cause = INJECT_CAUSES.get(tag.field)
        if cause is not None:
            faults = ctl.faults
            self._get[tag.name] = lambda: faults.holds(ax.index, cause)
            self._set[tag.name] = lambda value: ctl.inject(ax, cause, bool(value))
            return
        get = AXIS_GETTERS[tag.field]
        self._get[tag.name] = lambda: get(ax)
        if tag.field == "FeedbackInput":
            self._set[tag.name] = lambda value: ctl.set_feedback_input(ax, float(value))

    def _bind_cam(self, tag: Tag) -> None:
        """A cam table's tags: its points and Length are the kernel table's lists (a
        write lands there when the scan applies it, at the start of a cycle);
        ProfileStatus is read from the profile slot of the same number."""
        store = self.system.ctl.cams
        if self._cam_numbers is None:
            self._cam_numbers = {t.name: n for n, t in store.tables.items()}
        number = self._cam_numbers[tag.owner]
        table, slot = store.tables[number], store.slots[number]
        element = cam_element_of(tag.field)
        if element is None:
            if tag.field == "ProfileStatus":
                self._get[tag.name] = lambda: slot.status
            elif tag.field == "Capacity":
                self._get[tag.name] = lambda: table.capacity
            elif tag.field == "Number":
                self._get[tag.name] = lambda: number
            elif tag.field == "Length":
                self._get[tag.name] = lambda: table.length

                def set_length(value: Value) -> None:
                    table.length = int(value)

                self._set[tag.name] = set_length
            else:
                raise KeyError(tag.field)
            return
        name, k = element
        values: list[Any] = {"Master": table.master, "Slave": table.slave}.get(name, table.segment)
        if not 0 <= k < len(values):
            raise KeyError(tag.field)
        convert: Callable[[Value], Any] = int if name == "SegmentType" else float
        self._get[tag.name] = lambda: values[k]

        def set_value(value: Value) -> None:
            values[k] = convert(value)

        self._set[tag.name] = set_value

    def _bind_group(self, tag: Tag) -> None:
        g = self.system.ctl.group(tag.owner)
        if tag.field.startswith("Member"):
            k = int(tag.field.removeprefix("Member")) - 1
            number = g.axes[k].number
            self._get[tag.name] = lambda: number
            return
        get = GROUP_GETTERS[tag.field]
        self._get[tag.name] = lambda: get(g)

    def _bind_diagnostics(self, tag: Tag) -> None:
        host, system = self.host, self.system

        def version(part: int) -> Getter:
            def get() -> int:
                nums = [*host.version.split("."), "0", "0", "0"][:3]
                digits = "".join(c for c in nums[part] if c.isdigit())
                return int(digits or 0)

            return get

        # the kernel counts fallbacks per OS process; the tag counts those of this image's
        # scan (one per server process, many in a test process)
        fallbacks0 = system.ctl.profile_fallbacks
        getters: dict[str, Getter] = {
            "Heartbeat": lambda: host.heartbeat & _UINT32,
            "CycleTime": lambda: host.last_cycle_time * 1e6,
            "MaxCycleTime": lambda: host.max_cycle_time * 1e6,
            "Overruns": lambda: host.overruns & _UINT32,
            "DroppedCycles": lambda: host.dropped & _UINT32,
            "VersionMajor": version(0),
            "VersionMinor": version(1),
            "VersionPatch": version(2),
            "AxisCount": lambda: len(system.ctl.axes),
            "GroupCount": lambda: len(system.ctl.groups),
            "InstanceCount": lambda: len(system.instances),
            "ScanLoad": lambda: host.load,
            "QueuedWrites": lambda: host.queued_writes & _UINT32,
            "FrontendRestarts": lambda: host.restarts & _UINT32,
            "Ready": lambda: host.ready,
            "ProfileFallbacks": lambda: (system.ctl.profile_fallbacks - fallbacks0) & _UINT32,
        }
        self._get[tag.name] = getters[tag.field]

    def _bind_clock(self, tag: Tag) -> None:
        host, ctl = self.host, self.system.ctl
        getters: dict[str, Getter] = {
            "Step": lambda: self.step,
            "Mode": lambda: int(host.mode),
            "StepCycles": lambda: self.step_cycles,
            "Cycle": lambda: ctl.tick & _UINT32,
            "SimTime": lambda: ctl.time,
            "Period": lambda: ctl.period * 1000.0,
            "Scale": lambda: host.scale,
        }
        getters |= {
            "Snapshot": lambda: host.snapshot_number,
            "SnapshotSave": lambda: host.snapshot_save,
            "SnapshotRestore": lambda: host.snapshot_restore,
            "CommFault": lambda: host.comm.mode,
            "CommDelay": lambda: host.comm.delay,
            "CommDuration": lambda: host.comm.duration,
            "CommClientPort": lambda: host.comm.client_port,
        }
        self._get[tag.name] = getters[tag.field]
        if not tag.writable:
            return
        if tag.field == "Step":
            self._set[tag.name] = self._set_step
        elif tag.field == "Mode":
            self._set[tag.name] = lambda value: host.set_mode(ClockMode(int(value)))
        elif tag.field == "StepCycles":

            def set_cycles(value: Value) -> None:
                self.step_cycles = int(value)

            self._set[tag.name] = set_cycles
        elif tag.field == "Snapshot":

            def set_number(value: Value) -> None:
                host.snapshot_number = int(value)

            self._set[tag.name] = set_number
        elif tag.field in ("SnapshotSave", "SnapshotRestore"):
            self._set[tag.name] = self._snapshot_setter(tag.field)
        elif tag.field in _COMM:
            attr = _COMM[tag.field]

            def set_comm(value: Value) -> None:
                setattr(host.comm, attr, int(value))
                host.comm_changed()

            self._set[tag.name] = set_comm

    def _snapshot_setter(self, field: str) -> Setter:
        host = self.host
        kind = "save" if field == "SnapshotSave" else "restore"
        attr = f"snapshot_{kind}"

        def set_bit(value: Value) -> None:
            rising = bool(value) and not getattr(host, attr)
            if rising:
                host.snapshot(kind)  # TagAccessError: refused, the bit stays low
            setattr(host, attr, bool(value))

        return set_bit

    def _set_step(self, value: Value) -> None:
        rising = bool(value) and not self.step
        self.step = bool(value)
        if rising and self.host.mode == ClockMode.MANUAL and self.step_cycles > 0:
            self._requested += self.step_cycles
            self.host.request_cycles(self.step_cycles)

    def _build_slots(self) -> list[_Slot]:
        order = self.map.word_order
        by_address: dict[int, list[Tag]] = {}
        slots: list[_Slot] = []
        for tag in self.map:
            if tag.type == TagType.BOOL:
                by_address.setdefault(tag.address, []).append(tag)
                continue
            enc = encoder(tag.type, order)
            get = self._get[tag.name]
            slots.append(_Slot(tag.address, tag.count, [tag], _word_reader(enc, get)))
        for address, tags in by_address.items():
            getters = [(self._get[t.name], t.bit or 0) for t in tags]
            slots.append(_Slot(address, 1, tags, _bit_reader(getters)))
        slots.sort(key=lambda s: s.address)
        return slots


def _word_reader(
    enc: Callable[[Value], tuple[int, ...]], get: Getter
) -> Callable[[], tuple[int, ...]]:
    return lambda: enc(get())


def _bit_reader(getters: list[tuple[Getter, int]]) -> Callable[[], tuple[int, ...]]:
    def read() -> tuple[int, ...]:
        reg = 0
        for get, bit in getters:
            if get():
                reg |= 1 << bit
        return (reg,)

    return read
