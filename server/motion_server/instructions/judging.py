"""Judging latched operands at execution, with the verdict on values looked up in a table.

An instruction judges its latched operands on every trigger edge (ERR 13 naming the
first operand out of range, ERR 11 / group not configured for an axis or group number
that names nothing). Most of that work depends only on the operands' values: whether a
gate leaves an operand out (see ``Instruction.GATES``) and whether a value is in range.
When N instances of one type fire in one scan with the same settings (128 MAJ on 128
axes: the same Speed, rates and units), or one instance fires again and again, that work
is the same N times. So each instruction type keeps a table: the values of its value
operands (and of any selector) -> the verdict, i.e. which axis and group operands are
to be looked up (those that count and come before the first value out of range) and the
first value out of range, if any. Only the look-ups of axes and groups, which depend on
the controller, are done on every edge.

:func:`judge_reference` is the plain loop the table is built from and tested against.
The table is bounded (:data:`TABLE_SIZE`): a client writing ever new values empties it
now and then instead of growing it.
"""

from __future__ import annotations

from operator import itemgetter
from typing import TYPE_CHECKING, Any

from ..kernel import ErrorCode, MotionError
from .schema import Kind, Operand

if TYPE_CHECKING:
    from .base import Instruction

#: verdicts kept per instruction type before the table starts again empty
TABLE_SIZE = 1024

#: (axis and group operands to look up, in order, as (index, operand)), (index, operand)
#: of the first value out of range or None
Verdict = tuple[tuple[tuple[int, Operand], ...], tuple[int, Operand] | None]


def _reference_error(inst: Instruction, i: int, op: Operand) -> Exception | None:
    """The error of reference operand ``op`` (axis or group number), None if it names one."""
    value = inst.op[op.name]
    try:
        if op.kind == Kind.AXIS:
            inst.ctl.axis(int(value))
        else:
            inst.ctl.group(int(value))
    except (MotionError, TypeError, ValueError, OverflowError):
        from .base import OperandError

        code = (
            ErrorCode.AXIS_NOT_CONFIGURED
            if op.kind == Kind.AXIS
            else ErrorCode.GROUP_NOT_CONFIGURED
        )
        return OperandError(code, i, op)
    return None


def judge_reference(inst: Instruction) -> None:
    """Judge ``inst.op`` operand by operand (the reference the table is tested against):
    raise the :class:`~.base.OperandError` of the first operand at fault."""
    from .base import OperandError

    for i, op in enumerate(inst.OPERANDS):
        if not inst.operand_used(op):
            continue
        if op.kind != Kind.VALUE:
            exc = _reference_error(inst, i, op)
            if exc is not None:
                raise exc
        elif not op.check(inst.op[op.name]):
            raise OperandError(ErrorCode.PARAMETER_OUT_OF_RANGE, i, op)


class OperandJudge:
    """The judge of one instruction type: its verdict table and the key it is read by."""

    __slots__ = ("cls", "key", "names", "table")

    def __init__(self, cls: type[Instruction]) -> None:
        self.cls = cls
        selectors = {sel for gates in cls.GATES.values() for sel, _ in gates}
        #: the operands the verdict depends on: every value operand and every selector
        self.names = tuple(
            op.name for op in cls.OPERANDS if op.kind == Kind.VALUE or op.name in selectors
        )
        n = len(self.names)
        getter = itemgetter(*self.names) if n else None
        if n == 0:
            self.key: Any = lambda op: ()
        elif n == 1:
            self.key = lambda op: (getter(op),)  # type: ignore[misc]
        else:
            self.key = getter
        self.table: dict[tuple[Any, ...], Verdict] = {}

    def verdict(self, inst: Instruction) -> Verdict:
        """The verdict on ``inst.op``'s values, computed (no table)."""
        refs: list[tuple[int, Operand]] = []
        for i, op in enumerate(self.cls.OPERANDS):
            if not inst.operand_used(op):
                continue
            if op.kind != Kind.VALUE:
                refs.append((i, op))
            elif not op.check(inst.op[op.name]):
                return tuple(refs), (i, op)
        return tuple(refs), None

    def judge(self, inst: Instruction) -> Any:
        """Raise the :class:`~.base.OperandError` of the first operand at fault, exactly
        as :func:`judge_reference` does. Returns the key the verdict was looked up by:
        the values of the value operands and selectors (None when they cannot be a key),
        for callers that keep more by the same values (see ``scan_pass``)."""
        try:
            key = self.key(inst.op)
            verdict = self.table.get(key)
        except TypeError:  # a value that cannot be a key (unhashable): no table
            key = None
            verdict = None
        if verdict is None:
            verdict = self.verdict(inst)
            if key is not None:
                table = self.table
                if len(table) >= TABLE_SIZE:
                    table.clear()
                table[key] = verdict
        refs, failure = verdict
        if refs:
            ctl = inst.ctl
            values = inst.op
            for i, op in refs:
                try:
                    if op.kind == Kind.AXIS:
                        ctl.axis(int(values[op.name]))
                    else:
                        ctl.group(int(values[op.name]))
                except (MotionError, TypeError, ValueError, OverflowError):
                    exc = _reference_error(inst, i, op)
                    if exc is not None:
                        raise exc from None
        if failure is not None:
            from .base import OperandError

            raise OperandError(ErrorCode.PARAMETER_OUT_OF_RANGE, failure[0], failure[1])
        return key


_JUDGES: dict[type[Instruction], OperandJudge] = {}


def judge_of(cls: type[Instruction]) -> OperandJudge:
    """The judge of instruction type ``cls`` (made on first use)."""
    judge = _JUDGES.get(cls)
    if judge is None:
        judge = _JUDGES[cls] = OperandJudge(cls)
    return judge
