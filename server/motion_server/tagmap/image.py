"""The tag image: live values of a :class:`TagMap`, bound to a running :class:`MotionSystem`.

Reads come from the system as the last completed cycle left it (front-ends only call in
between cycles: asyncio is single-threaded). Register reads encode a whole block once per
cycle and serve the following reads of that cycle from the copy; every write through the
image invalidates the copies. Writes to instruction operands land in the
instance's ``inputs``; the instance latches them on its own trigger edge at the next
cycle. Clock and hand-wheel writes act at once. Errors are protocol-neutral; each
front-end maps them to its own codes (Modbus: :class:`AddressError` and
:class:`ReadOnlyError` -> exception 02, :class:`BadValueError` -> 03).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..instructions import MotionSystem
from ..instructions.schema import TagType
from ..kernel import Axis, Controller, MotionError
from ..kernel.group import MotionGroup
from .axis_config import CONFIG_GETTERS, MIRRORS
from .codec import RegisterValueError, Value, decoder, encoder
from .fields import ClockMode
from .model import Folder, Tag, TagMap, UnknownTagError


class TagAccessError(Exception):
    """A read or write the image refuses (the base of the errors below)."""


class AddressError(TagAccessError):
    """Registers outside the map."""


class ReadOnlyError(TagAccessError):
    """A write to a read-only tag or register."""


class BadValueError(TagAccessError):
    """A value the tag cannot hold (wrong type or range, an unknown clock mode ...)."""


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

    def set_mode(self, mode: ClockMode) -> None: ...

    def request_cycles(self, count: int) -> None: ...

    async def settle(self) -> None:
        """Return once the cycles requested so far have run."""


class StandaloneHost:
    """A host without a clock loop: manual time, requested cycles run at once."""

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

    def set_mode(self, mode: ClockMode) -> None:
        self.mode = mode

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
}
AXIS_GETTERS.update({mirror: AXIS_GETTERS[source] for mirror, source in MIRRORS.items()})


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

#: fields whose value never changes while the server runs (configuration)
STATIC_FIELDS: dict[Folder, frozenset[str]] = {
    Folder.AXES: frozenset({"Number", "Type", *CONFIG_GETTERS}),
    Folder.GROUPS: frozenset({"Number", "CoarseUpdatePeriod", "AxisCount"}),
    Folder.DIAGNOSTICS: frozenset(
        {"VersionMajor", "VersionMinor", "VersionPatch", "AxisCount", "GroupCount"}
    ),
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


def checked(tag_type: TagType, value: Any) -> Value:
    """``value`` as the Python value a tag of ``tag_type`` holds, or :class:`BadValueError`."""
    if tag_type == TagType.BOOL:
        if value in (0, 1):  # True/False, 0/1, 0.0/1.0
            return bool(value)
        raise BadValueError(f"{value!r} is not a BOOL (0 or 1)")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise BadValueError(f"{value!r} is not a number")
    if tag_type.is_float:
        return float(value)
    if isinstance(value, float) and not value.is_integer():
        raise BadValueError(f"{value!r} is not an integer ({tag_type.value})")
    lo, hi = tag_type.bounds
    if not lo <= value <= hi:
        raise BadValueError(f"{value} is outside the {tag_type.value} range {lo:.0f}..{hi:.0f}")
    return int(value)


class TagImage:
    """Live values of ``tagmap`` on ``system``: :meth:`read`/:meth:`write` by tag,
    :meth:`read_registers`/:meth:`write_registers` by holding register."""

    def __init__(
        self,
        tagmap: TagMap,
        system: MotionSystem,
        host: Host | None = None,
        bindings: Mapping[str, tuple[Getter, Setter | None]] | None = None,
    ) -> None:
        self.map = tagmap
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
        for tag in tagmap:
            self._bind(tag)
        self._slots = self._build_slots()
        self._starts = [s.address for s in self._slots]
        #: bumped by every write: part of the key of the block copies
        self.generation = 0
        self._copies: dict[int, tuple[tuple[int, int], list[int]]] = {}
        self._block_slots = {
            b.base: [s for s in self._slots if b.base <= s.address < b.end] for b in tagmap.blocks
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
        if count < 1 or address < 0:
            raise AddressError(f"bad register range {address}+{count}")
        a, end = address, address + count
        while a < end:
            block = self.map.block_at(a)
            if block is None:
                raise AddressError(f"register {a} is outside the map")
            if not write:
                a = block.end
            elif block.command_start <= a < block.command_end:
                a = block.command_end
            else:
                raise ReadOnlyError(f"register {a} ({block.owner}) is read-only")

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
        """Write registers. A write that covers part of a 32/64-bit value changes those
        words only (the value is judged when the instruction latches it); registers
        between tags take no value. Returns the number of cycles requested (Clock.Step)."""
        count = len(values)
        if check:
            self.check(address, count, write=True)
        updates: list[tuple[Tag | str, Any]] = []
        end = address + count
        slots = self._slots
        i = max(bisect.bisect_right(self._starts, address) - 1, 0)
        while i < len(slots) and slots[i].address < end:
            s = slots[i]
            i += 1
            if s.end <= address:
                continue
            if s.tags[0].type == TagType.BOOL:
                reg = values[s.address - address]
                updates += [(t, bool((reg >> (t.bit or 0)) & 1)) for t in s.tags]
                continue
            words = list(s.read())
            for k in range(s.count):
                if address <= s.address + k < end:
                    words[k] = values[s.address + k - address]
            tag = s.tags[0]
            try:
                updates.append((tag, self._decoders[tag.name](words)))
            except RegisterValueError as exc:
                raise BadValueError(f"{tag.name}: {exc}") from None
        return self.write_many(updates)

    # -- binding ----------------------------------------------------------------------------
    def _judge(self, tag: Tag, value: Any) -> Value:
        v = checked(tag.type, value)
        if tag.owner == "Clock" and tag.field == "Mode":
            try:
                return ClockMode(int(v))
            except ValueError:
                raise BadValueError(
                    f"Clock.Mode {v}: expected 0 realtime, 1 manual, 2 scaled"
                ) from None
        if tag.field == "FeedbackInput" and not math.isfinite(float(v)):
            raise BadValueError(f"{tag.name} must be finite, got {v}")
        return v

    def _bind(self, tag: Tag) -> None:
        binders = {
            Folder.INSTRUCTIONS: self._bind_instruction,
            Folder.AXES: self._bind_axis,
            Folder.GROUPS: self._bind_group,
            Folder.DIAGNOSTICS: self._bind_diagnostics,
            Folder.CLOCK: self._bind_clock,
            Folder.SAFETY: self._bind_safety,
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
        ax = self.system.ctl.axis(tag.owner)
        get = AXIS_GETTERS[tag.field]
        self._get[tag.name] = lambda: get(ax)
        if tag.field == "FeedbackInput":
            ctl = self.system.ctl
            self._set[tag.name] = lambda value: ctl.set_feedback_input(ax, float(value))

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

    def _set_step(self, value: Value) -> None:
        rising = bool(value) and not self.step
        self.step = bool(value)
        if rising and self.host.mode == ClockMode.MANUAL and self.step_cycles > 0:
            self._requested += self.step_cycles
            self.host.request_cycles(self.step_cycles)

    def _build_slots(self) -> list[_Slot]:
        order = self.map.word_order
        self._decoders: dict[str, Callable[[Sequence[int]], Value]] = {}
        by_address: dict[int, list[Tag]] = {}
        slots: list[_Slot] = []
        for tag in self.map:
            if tag.type == TagType.BOOL:
                by_address.setdefault(tag.address, []).append(tag)
                continue
            enc = encoder(tag.type, order)
            get = self._get[tag.name]
            self._decoders[tag.name] = decoder(tag.type, order)
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
