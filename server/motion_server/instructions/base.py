"""The instruction framework: operands latched on the trigger's edge, dialect status rules.

Each cycle the system calls :meth:`Instruction.scan` on every instance (edge detection,
operand snapshot, execution), steps the kernel, then calls :meth:`Instruction.update`
(status from the processes the instance started). Subclasses implement ``execute`` (act on
``self.op``, the latched operands) and ``poll`` (follow their processes).
"""

from __future__ import annotations

from enum import IntEnum, StrEnum
from typing import Any, ClassVar

from ..kernel import Axis, Controller, ErrorCode, MotionError, TransitionError
from ..kernel.group import MotionGroup
from ..kernel.processes import Process
from .judging import judge_of
from .schema import Kind, Operand, StatusField, TagType, coerce
from .status import LOGIX_STATUS, PLCOPEN_STATUS, LogixBit


class Dialect(StrEnum):
    LOGIX = "logix"
    PLCOPEN = "plcopen"


class Outputs(dict[str, Any]):
    """An instance's outputs. A change of value adds the instance's name to ``changed``
    (the set its system gives it): the scan publishes only what changed."""

    __slots__ = ("changed", "owner")

    def __init__(self, owner: str, values: dict[str, Any]) -> None:
        super().__init__(values)
        self.owner = owner
        self.changed: set[str] | None = None

    def __setitem__(self, key: str, value: Any) -> None:
        if dict.get(self, key, _UNSET) != value:
            changed = self.changed
            if changed is not None:
                changed.add(self.owner)
        dict.__setitem__(self, key, value)

    def write(self, values: dict[str, Any]) -> None:
        """Set several outputs at once (as many ``self[key] = value``, in one call)."""
        changed = self.changed
        if changed is not None:
            get = self.get
            for key, value in values.items():
                if get(key, _UNSET) != value:
                    changed.add(self.owner)
                    break
        dict.update(self, values)

    def __reduce__(self) -> tuple[Any, ...]:
        # a dict subclass unpickles its items before its slots: the items go in with the
        # state instead, past __setitem__ (a snapshot marks nothing changed)
        return _empty_dict, (Outputs,), (dict(self), self.owner, self.changed)

    def __setstate__(self, state: tuple[dict[str, Any], str, set[str] | None]) -> None:
        values, self.owner, self.changed = state
        dict.update(self, values)


def _empty_dict(cls: type[Outputs | Inputs]) -> Outputs | Inputs:
    """An :class:`Outputs` or :class:`Inputs` without items or slots yet (snapshots)."""
    if cls not in (Outputs, Inputs):
        raise ValueError(f"{cls!r} is not an instance's inputs or outputs")
    return cls.__new__(cls)


_UNSET = object()


class Inputs(dict[str, Any]):
    """An instance's operands as clients write them. A write adds the instance to
    ``woken`` (the set its system gives it): an instance that sleeps is scanned again
    (see :meth:`Instruction.asleep`)."""

    __slots__ = ("owner", "woken")

    def __init__(self, owner: Instruction, values: dict[str, Any]) -> None:
        super().__init__(values)
        self.owner = owner
        self.woken: set[Instruction] | None = None

    def _wake(self) -> None:
        woken = self.woken
        if woken is not None:
            woken.add(self.owner)

    def __setitem__(self, key: str, value: Any) -> None:
        dict.__setitem__(self, key, value)
        woken = self.woken  # (self._wake() inlined: every client write comes through here)
        if woken is not None:
            woken.add(self.owner)

    def update(self, *args: Any, **kwargs: Any) -> None:
        dict.update(self, *args, **kwargs)
        self._wake()

    def setdefault(self, key: str, default: Any = None) -> Any:
        self._wake()
        return dict.setdefault(self, key, default)

    def __ior__(self, other: Any) -> Inputs:  # type: ignore[override,misc]
        self.update(other)
        return self

    def __reduce__(self) -> tuple[Any, ...]:
        return _empty_dict, (Inputs,), (dict(self), self.owner, self.woken)

    def __setstate__(self, state: tuple[dict[str, Any], Instruction, set[Any] | None]) -> None:
        values, self.owner, self.woken = state
        dict.update(self, values)


#: (selector operand, the selector values that make an operand count)
Gate = tuple[str, frozenset[int]]


def gate(selector: str, *values: int) -> Gate:
    """An operand counts when ``selector`` holds one of ``values`` (see ``Instruction.GATES``)."""
    return selector, frozenset(int(v) for v in values)


class Instruction:
    TYPE: ClassVar[str] = ""
    DIALECT: ClassVar[Dialect]
    DESCRIPTION: ClassVar[str] = ""
    OPERANDS: ClassVar[tuple[Operand, ...]] = ()
    #: outputs beyond the dialect's common status fields
    OUTPUTS: ClassVar[tuple[StatusField, ...]] = ()
    TRIGGER: ClassVar[str] = "Execute"
    COMMON_STATUS: ClassVar[tuple[StatusField, ...]] = ()
    #: the one rule for operands a mode does not use: an operand named here (a value, or
    #: the units of a value) counts, i.e. is judged at execution and used, only when one
    #: of its gates is open (its selector holds one of the gate's values); operands not
    #: named always count
    GATES: ClassVar[dict[str, tuple[Gate, ...]]] = {}
    #: outputs that follow the power state of an axis even while the instance is idle:
    #: its system wakes it whenever an axis changes state (see :meth:`asleep`)
    FOLLOWS_AXIS_STATE: ClassVar[bool] = False
    #: an attribute of the process an instance is parked on (:meth:`parked_on`) whose
    #: falling wakes it too (MC_MoveVelocity: ``at_speed``, which InVelocity shows)
    PARKED_WATCH: ClassVar[str | None] = None

    def __init__(self, name: str, ctl: Controller, defaults: dict[str, Any] | None = None) -> None:
        self.name = name
        self.ctl = ctl
        self.inputs = Inputs(self, {op.name: coerce(op.type, op.default) for op in self.OPERANDS})
        self.inputs[self.TRIGGER] = False
        for key, value in (defaults or {}).items():
            op = self.operand(key)
            self.inputs[key] = coerce(op.type, value)
        self.outputs = Outputs(
            name, {f.name: coerce(f.type, f.default) for f in self.status_fields()}
        )
        self.op: dict[str, Any] = dict(self.inputs)
        self._last_trigger = False

    # -- schema ---------------------------------------------------------------------------
    @classmethod
    def status_fields(cls) -> tuple[StatusField, ...]:
        return cls.COMMON_STATUS + cls.OUTPUTS

    @classmethod
    def trigger_operand(cls) -> Operand:
        return Operand(cls.TRIGGER, TagType.BOOL, False, description="trigger (rising edge)")

    @classmethod
    def input_operands(cls) -> tuple[Operand, ...]:
        return (cls.trigger_operand(), *cls.OPERANDS)

    @classmethod
    def operand(cls, name: str) -> Operand:
        for op in cls.input_operands():
            if op.name == name:
                return op
        raise KeyError(f"{cls.TYPE} has no operand {name!r}")

    # -- operand access -------------------------------------------------------------------
    def latch(self) -> None:
        self.op = dict(self.inputs)

    def validate(self) -> None:
        """Judge the latched operands: out of range -> ERR 13 naming the operand (the
        verdict on the values comes from the type's table: see :mod:`.judging`)."""
        judge_of(type(self)).judge(self)

    def operand_used(self, op: Operand) -> bool:
        """False for an operand the latched selectors make irrelevant (not judged): see
        :attr:`GATES`."""
        gates = self.GATES.get(op.name)
        if not gates:
            return True
        for selector, values in gates:
            try:
                if int(self.op[selector]) in values:
                    return True
            except (TypeError, ValueError, OverflowError):
                continue  # a selector that is no integer opens nothing (it is judged itself)
        return False

    @classmethod
    def gate_note(cls, name: str) -> str:
        """When operand ``name`` counts, in words ("" when always): for the tag map."""
        gates = cls.GATES.get(name)
        if not gates:
            return ""
        parts = []
        for selector, values in gates:
            op = cls.operand(selector)
            shown = []
            for v in sorted(values):
                label = op.enum(v).name if op.enum is not None else ""
                shown.append(f"{v} ({label})" if label else str(v))
            parts.append(f"{selector} = {' or '.join(shown)}")
        return "used and judged only when " + " or ".join(parts)

    def axis(self, name: str = "Axis") -> Axis:
        return self.ctl.axis(int(self.op[name]))

    def group(self, name: str = "Group") -> MotionGroup:
        return self.ctl.group(int(self.op[name]))

    def commanded_axes(self) -> list[Axis]:
        """The axes the latched axis operands name (those that exist)."""
        out: list[Axis] = []
        for op in self.OPERANDS:
            if op.kind == Kind.AXIS:
                try:
                    out.append(self.ctl.axis(int(self.op[op.name])))
                except (MotionError, TypeError, ValueError, OverflowError):
                    continue
        return out

    def fail_internal(self) -> None:
        """The instance raised an unexpected exception: show the internal error
        (Logix ER, PLCopen Error, code :attr:`ErrorCode.INTERNAL_ERROR`)."""
        raise NotImplementedError

    def operand_index(self, name: str) -> int:
        for i, op in enumerate(self.OPERANDS):
            if op.name == name:
                return i
        raise KeyError(name)

    def out_of_range(self, name: str, message: str = "") -> OperandError:
        """Build the ERR 13 error for operand ``name`` (raise it from ``execute``)."""
        i = self.operand_index(name)
        return OperandError(ErrorCode.PARAMETER_OUT_OF_RANGE, i, self.OPERANDS[i], message)

    # -- cycle ----------------------------------------------------------------------------
    def scan(self) -> None:
        raise NotImplementedError

    def update(self) -> None:
        raise NotImplementedError

    def execute(self) -> None:
        raise NotImplementedError

    def poll(self) -> None:
        """Follow the processes this instance started (after the kernel step)."""

    def parked_on(self) -> Process | None:
        """The process this instance does nothing but wait on, or None: until that
        process leaves ACTIVE or an operand is written, :meth:`scan` and :meth:`update`
        would change nothing. Its system then checks only the process's state each
        cycle (see :class:`~.system.MotionSystem`). Asked after :meth:`update` of an
        instance that is not asleep; the default (None) calls it every cycle."""
        return None

    def end_parked(self) -> bool:
        """:meth:`update` of this instance, parked on a process that has now left
        ACTIVE; True if it is asleep after it (see :meth:`parked_on`)."""
        self.update()
        return self.asleep()

    def asleep(self) -> bool:
        """True when, until an operand is written, neither :meth:`scan` nor :meth:`update`
        would change anything: no trigger edge to come, no process to follow, no output
        still to show. Its system then stops calling them (an idle instance costs
        nothing) and calls them again after a write to :attr:`inputs`. Asked after
        :meth:`update`; the default (False) scans every cycle."""
        return False

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class OperandError(MotionError):
    """An operand judged at execution: carries its index for EXERR."""

    def __init__(self, code: ErrorCode, index: int, operand: Operand, message: str = "") -> None:
        self.index = index
        self.operand = operand
        super().__init__(code, message or f"operand {operand.name} out of range")


# -- Logix ---------------------------------------------------------------------------------


class RungEvent(IntEnum):
    RISING = 0
    HIGH = 1
    LOW = 2


#: (previous rung, rung) -> event; a transitional instruction executes on RISING only
RUNG_EVENTS: dict[tuple[bool, bool], RungEvent] = {
    (False, True): RungEvent.RISING,
    (True, True): RungEvent.HIGH,
    (True, False): RungEvent.LOW,
    (False, False): RungEvent.LOW,
}


#: the mask of each LogixBit in the FLAGS word (as plain ints: no enum walk per write)
_EN = 1 << LogixBit.EN.value
_DN = 1 << LogixBit.DN.value
_ER = 1 << LogixBit.ER.value
_PC = 1 << LogixBit.PC.value
_IP = 1 << LogixBit.IP.value
_AC = 1 << LogixBit.AC.value
#: the outputs a rising rung sets before the operands are judged: EN, DN/ER/PC cleared,
#: no error code
_RISING = RungEvent.RISING
_NO_STATUS: dict[str, Any] = {}
_ENDED_PC: dict[str, Any] = {"IP": False, "PC": True}
_ENDED_NO_PC: dict[str, Any] = {"IP": False, "PC": False}
_RISING_STATUS: dict[str, Any] = {"EN": True, "DN": False, "ER": False, "PC": False, "ERR": 0,
                                  "EXERR": 0}  # fmt: skip


class LogixInstruction(Instruction):
    """Transitional Logix instruction: ``Execute`` is the rung-condition-in.

    Rising edge: EN set, DN/ER/PC cleared, operands latched and judged, then executed.
    Rung false: EN cleared once DN or ER is set (the seeds' execution table).
    """

    DIALECT = Dialect.LOGIX
    COMMON_STATUS = LOGIX_STATUS
    #: position of the Motion Control operand in the instruction's ST signature; EXERR
    #: counts it, so operands after it are numbered one higher
    MOTION_CONTROL_INDEX: ClassVar[int] = 1
    #: the rising status is owed (set by :meth:`scan` for the execution it starts; a
    #: class default, so that instances from older snapshots have it too)
    _rising: bool = False

    def bit(self, name: str) -> bool:
        return bool(self.outputs[name])

    def set_bits(self, **bits: bool) -> None:
        for name, value in bits.items():
            bits[name] = bool(value)
        self._write_status(bits)

    def _write_status(self, values: dict[str, Any]) -> None:
        """Write ``values`` (bits as bools, codes) and the FLAGS word that follows; on a
        rising rung, after the rising status (see :meth:`scan`)."""
        out = self.outputs
        if self._rising:
            self._rising = False
            out.write(_RISING_STATUS)
        out.write(values)
        get = out.get
        flags = (
            (_EN if get("EN") else 0)
            | (_DN if get("DN") else 0)
            | (_ER if get("ER") else 0)
            | (_PC if get("PC") else 0)
            | (_IP if get("IP") else 0)
            | (_AC if get("AC") else 0)
        )
        if get("FLAGS") != flags:
            out["FLAGS"] = flags

    def _write_started(self, values: dict[str, Any], flags: int) -> None:
        """:meth:`_write_status` of ``values`` that set DN, ER, PC and IP (as in ``flags``,
        the FLAGS word without AC) on a rising rung (EN set): the same writes, without
        reading the bits back."""
        out = self.outputs
        if self._rising:
            self._rising = False
            out.write(_RISING_STATUS)
        out.write(values)
        flags = flags | _EN | (_AC if out.get("AC") else 0)
        if out.get("FLAGS") != flags:
            out["FLAGS"] = flags

    def fail(self, code: int, exerr: int = 0) -> None:
        self._write_status(
            {"ERR": int(code), "EXERR": int(exerr), "ER": True, "DN": False, "IP": False,
             "PC": False, "AC": False}
        )  # fmt: skip

    def fail_internal(self) -> None:
        self.fail(ErrorCode.INTERNAL_ERROR)

    def scan(self) -> None:
        rung = bool(self.inputs[self.TRIGGER])
        if not rung and not self._last_trigger and not self.outputs["EN"]:
            return  # rung false and EN already cleared: the table has nothing to do
        event = RUNG_EVENTS[(self._last_trigger, rung)]
        self._last_trigger = rung
        if event is _RISING:
            # the rising status (EN set, DN/ER/PC and the codes cleared) is owed: it goes
            # in with the execution's first status write, or alone at the end
            self._rising = True
            self.latch()
            try:
                self.validate()
                self.execute()
            except OperandError as exc:
                idx = exc.index + (1 if exc.index >= self.MOTION_CONTROL_INDEX else 0)
                self.fail(exc.code, idx if exc.code == ErrorCode.PARAMETER_OUT_OF_RANGE else 0)
            except MotionError as exc:
                self.fail(exc.code)
            finally:
                if self._rising:
                    self._write_status(_NO_STATUS)
        elif event == RungEvent.LOW and (self.bit("DN") or self.bit("ER")):
            self.set_bits(EN=False)

    def update(self) -> None:
        out = self.outputs
        if out["IP"] or out["AC"]:
            self.poll()

    def rung_steady(self) -> bool:
        """:meth:`scan` does nothing until a write changes the rung: it is steady, high
        (EN held: no edge to come) or low with EN already cleared; no rising status
        owed."""
        if self._rising:
            return False
        rung = bool(self.inputs[self.TRIGGER])
        return rung == self._last_trigger and (rung or not self.outputs["EN"])

    def asleep(self) -> bool:
        # update has no process to poll and scan nothing to do
        out = self.outputs
        return not (out["IP"] or out["AC"]) and self.rung_steady()

    def clear_ip(self, pc: bool | None = None) -> None:
        """``set_bits(IP=False)``, or ``set_bits(IP=False, PC=pc)``, for the end of a
        process: the FLAGS word follows from the one kept (one bit or two changed), not
        from every bit read back."""
        if self._rising:
            if pc is None:
                self.set_bits(IP=False)
            else:
                self.set_bits(IP=False, PC=pc)
            return
        out = self.outputs
        flags = out.get("FLAGS", 0) & ~_IP
        if pc is None:
            out["IP"] = False
        else:
            out.write(_ENDED_PC if pc else _ENDED_NO_PC)
            flags = (flags | _PC) if pc else (flags & ~_PC)
        if out.get("FLAGS") != flags:
            out["FLAGS"] = flags


# -- PLCopen -------------------------------------------------------------------------------


class BlockState(IntEnum):
    IDLE = 0
    BUSY = 1
    DONE = 2
    ABORTED = 3
    ERROR = 4


class BlockEvent(IntEnum):
    START = 0
    COMPLETE = 1
    ABORT = 2
    FAIL = 3
    RELEASE = 4


_TERMINAL = (BlockState.DONE, BlockState.ABORTED, BlockState.ERROR)

#: the PLCopen block state table: (state, event) -> next state
BLOCK_TRANSITIONS: dict[tuple[BlockState, BlockEvent], BlockState] = {
    (BlockState.IDLE, BlockEvent.START): BlockState.BUSY,
    (BlockState.IDLE, BlockEvent.FAIL): BlockState.ERROR,
    (BlockState.BUSY, BlockEvent.START): BlockState.BUSY,
    (BlockState.BUSY, BlockEvent.COMPLETE): BlockState.DONE,
    (BlockState.BUSY, BlockEvent.ABORT): BlockState.ABORTED,
    (BlockState.BUSY, BlockEvent.FAIL): BlockState.ERROR,
    **{(s, BlockEvent.START): BlockState.BUSY for s in _TERMINAL},
    **{(s, BlockEvent.FAIL): BlockState.ERROR for s in _TERMINAL},
    **{(s, BlockEvent.RELEASE): BlockState.IDLE for s in _TERMINAL},
}


class PLCopenBlock(Instruction):
    """PLCopen function block: inputs latched on the rising edge of ``Execute``.

    Done, Error and CommandAborted are mutually exclusive; each is held until Execute
    falls, and shown for at least one cycle even when Execute dropped earlier.
    """

    DIALECT = Dialect.PLCOPEN
    COMMON_STATUS = PLCOPEN_STATUS

    def __init__(self, name: str, ctl: Controller, defaults: dict[str, Any] | None = None) -> None:
        super().__init__(name, ctl, defaults)
        self.state = BlockState.IDLE
        self.active = False
        self._shown = False

    def fire(self, event: BlockEvent) -> None:
        nxt = BLOCK_TRANSITIONS.get((self.state, event))
        if nxt is None:
            raise TransitionError(f"{self.TYPE} {self.name}", self.state, event)
        self.state = nxt
        self._shown = False
        if nxt != BlockState.BUSY:
            self.active = False

    def fail(self, code: int) -> None:
        self.fire(BlockEvent.FAIL)
        self.outputs["ErrorID"] = int(code)

    def fail_internal(self) -> None:
        self.active = False
        self.fail(ErrorCode.INTERNAL_ERROR)
        self._publish()

    def scan(self) -> None:
        ex = bool(self.inputs[self.TRIGGER])
        if not ex and not self._last_trigger and self.state == BlockState.IDLE:
            return  # idle with Execute low: nothing can change, outputs already published
        rising = ex and not self._last_trigger
        self._last_trigger = ex
        if rising:
            self.outputs["ErrorID"] = 0
            self.on_restart()
            self.latch()
            try:
                self.validate()
                self.execute()
            except MotionError as exc:
                self.fail(exc.code)
        elif not ex and self.state in _TERMINAL and self._shown:
            self.fire(BlockEvent.RELEASE)
            self.outputs["ErrorID"] = 0
            self.on_release()
        self._publish()

    def update(self) -> None:
        if self.state == BlockState.IDLE:
            return  # published when it became idle
        if self.state == BlockState.BUSY:
            self.poll()
        if self.state in _TERMINAL:
            self._shown = True  # published at the end of this cycle: visible at least once
        self._publish()

    def asleep(self) -> bool:
        # idle with Execute low: scan returns at once and update has nothing to follow.
        # Done, Error or CommandAborted already shown with Execute held high (PLCopen
        # holds them until it falls): scan and update publish the same outputs again,
        # where the type's are these (publish_extra reads only the state then)
        ex = bool(self.inputs[self.TRIGGER])
        if ex != self._last_trigger:
            return False
        if not ex:
            return self.state == BlockState.IDLE
        return self.state in _TERMINAL and self._shown and _holds_terminal(type(self))

    def on_restart(self) -> None:
        """A new rising edge arrived (before the operands are latched)."""

    def on_release(self) -> None:
        """Terminal outputs were cleared after Execute fell."""

    def _publish(self) -> None:
        s = self.state
        out = self.outputs
        busy = s == BlockState.BUSY
        values = {"Busy": busy, "Done": s == BlockState.DONE, "Error": s == BlockState.ERROR}
        # a block may lack these (MC_Reset has no Active or CommandAborted)
        if "Active" in out:
            values["Active"] = busy and self.active
        if "CommandAborted" in out:
            values["CommandAborted"] = s == BlockState.ABORTED
        out.write(values)
        self.publish_extra()

    def publish_extra(self) -> None:
        """Set block-specific outputs (InVelocity, InGear ...) from the state."""


def _holds_terminal(cls: type[PLCopenBlock]) -> bool:
    """A terminal state shown changes nothing while Execute stays high: ``cls`` scans
    and updates as :class:`PLCopenBlock` does (MC_Stop's scan also drops its latch,
    MC_Power follows the axis: they do not)."""
    return cls.scan is PLCopenBlock.scan and cls.update is PLCopenBlock.update


# -- PLCopen, Enable-style -----------------------------------------------------------------

#: the outputs of an Enable-style block (PLCopen Part 1: "Valid", "Busy", "Error", ErrorID)
ENABLE_STATUS: tuple[StatusField, ...] = (
    StatusField("Valid", TagType.BOOL, "the value outputs are valid (Enable high, no error)"),
    StatusField("Busy", TagType.BOOL, "Enable is high: the block reads every cycle"),
    StatusField("Error", TagType.BOOL, "the value cannot be read, see ErrorID"),
    StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
)


class EnableBlock(Instruction):
    """PLCopen Enable-style block (MC_ReadStatus, MC_ReadParameter, ...): while ``Enable``
    is high the block works every cycle, not once per edge.

    Each scan with Enable high latches the operands (they may change while enabled,
    PLCopen: "get the value ... continuously while enabled") and judges them; after the
    kernel step :meth:`read` sets the value outputs from the axis as the cycle left it.
    Busy follows Enable; Valid and Error are exclusive: an error (a bad operand, an axis
    that does not exist) sets Error with its ErrorID and clears Valid, and is judged again
    every cycle. Enable low: Valid, Busy, Error and ErrorID clear; the value outputs keep
    their last valid reading.
    """

    DIALECT = Dialect.PLCOPEN
    TRIGGER = "Enable"
    COMMON_STATUS = ENABLE_STATUS

    def __init__(self, name: str, ctl: Controller, defaults: dict[str, Any] | None = None) -> None:
        super().__init__(name, ctl, defaults)
        self._error = 0

    @classmethod
    def trigger_operand(cls) -> Operand:
        return Operand(cls.TRIGGER, TagType.BOOL, False, description="read while high (level)")

    def read(self) -> None:
        """Set the value outputs from the latched operands (raise MotionError)."""
        raise NotImplementedError

    def commanded_axes(self) -> list[Axis]:
        """None: a block that reads commands no axis (an internal error in it stops
        nothing)."""
        return []

    def scan(self) -> None:
        enable = bool(self.inputs[self.TRIGGER])
        if not enable:
            if self._last_trigger:
                self._last_trigger = False
                self._error = 0
                self._publish()
            return
        self._last_trigger = True
        self.latch()
        try:
            self.validate()
            self._error = 0
        except MotionError as exc:
            self._error = int(exc.code)

    def update(self) -> None:
        if not self._last_trigger:
            return
        if not self._error:
            try:
                self.read()
            except MotionError as exc:
                self._error = int(exc.code)
        self._publish()

    def fail_internal(self) -> None:
        self._error = int(ErrorCode.INTERNAL_ERROR)
        self._publish()

    def asleep(self) -> bool:
        # Enable low and its fall already published: scan and update return at once
        return not (self.inputs[self.TRIGGER] or self._last_trigger)

    def _publish(self) -> None:
        enabled = self._last_trigger
        out = self.outputs
        out["Busy"] = enabled
        out["Error"] = enabled and bool(self._error)
        out["Valid"] = enabled and not self._error
        out["ErrorID"] = self._error if enabled else 0
