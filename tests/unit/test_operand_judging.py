"""Operands judged through each type's verdict table (``instructions/judging.py``) give
exactly the error of the plain operand-by-operand loop (``judge_reference``): the same
code and the same operand, or none, for every instruction type and any values, the
table cold or warm; and the Logix status words written in one call per change keep the
FLAGS word equal to its bits and mark an instance changed exactly when an output did."""

from __future__ import annotations

import math
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem
from motion_server.instructions.base import Instruction, LogixInstruction, OperandError
from motion_server.instructions.judging import judge_of, judge_reference
from motion_server.instructions.registry import catalog
from motion_server.instructions.schema import Kind, Operand
from motion_server.instructions.status import LogixBit
from motion_server.kernel import AxisConfig, AxisType

from ..support import make_system

TYPES = list(catalog().values())
#: axes 1..3 exist, group 1 exists: numbers around them, and values that are no number
REFERENCES = st.sampled_from([0, 1, 2, 3, 4, -1, 2**40, 1.5, math.nan])


def values_of(op: Operand) -> st.SearchStrategy[Any]:
    """Values around ``op``'s range: inside, on and beyond its bounds, each enumeration
    member and its neighbours, non-finite numbers; few enough that they repeat."""
    if op.kind != Kind.VALUE:
        return REFERENCES
    pool: list[Any] = [op.default, 0, 1, -1, 0.0, -0.0, 0.5, 100.0, 1e39, -1e39]
    pool += [math.inf, -math.inf, math.nan, 2**31, 2**64]
    for bound in (op.minimum, op.maximum):
        if bound is not None:
            pool += [bound, bound - 1e-3, bound + 1e-3]
    if op.enum is not None:
        for m in op.enum:
            pool += [int(m), int(m) + 1, float(m)]
    return st.sampled_from(pool)


def system() -> MotionSystem:
    return make_system(*(AxisConfig(n, f"A{n}", AxisType.SERVO) for n in (1, 2, 3)))


def outcome(call: Any) -> tuple[int, int, str] | None:
    try:
        call()
    except OperandError as exc:
        return int(exc.code), exc.index, exc.operand.name
    return None


@st.composite
def operand_sets(draw: st.DrawFn) -> tuple[type[Instruction], list[dict[str, Any]]]:
    cls = draw(st.sampled_from(TYPES))
    sets = draw(
        st.lists(
            st.fixed_dictionaries({op.name: values_of(op) for op in cls.OPERANDS}),
            min_size=1,
            max_size=6,
        )
    )
    return cls, sets


@settings(max_examples=400, deadline=None)
@given(case=operand_sets())
def test_the_table_judges_as_the_reference_loop(
    case: tuple[type[Instruction], list[dict[str, Any]]],
) -> None:
    cls, sets = case
    cold = len(sets) % 2 == 1
    if cold:
        judge_of(cls).table.clear()
    inst = cls("I", system().ctl)
    for values in sets * 2:  # each set twice: the second time from the table
        inst.inputs.update(values)
        inst.latch()
        expected = outcome(lambda: judge_reference(inst))
        assert outcome(inst.validate) == expected, (cls.TYPE, values, cold)


def test_a_value_that_cannot_be_a_key_is_judged_without_the_table() -> None:
    cls = catalog()["MAJ"]
    inst = cls("I", system().ctl)
    inst.inputs["Speed"] = [1.0]  # no number: out of range, and unhashable
    inst.latch()
    assert outcome(inst.validate) == outcome(lambda: judge_reference(inst))
    assert outcome(inst.validate) is not None


def test_the_table_stays_bounded() -> None:
    from motion_server.instructions import judging

    cls = catalog()["MAJ"]
    inst = cls("I", system().ctl)
    for k in range(judging.TABLE_SIZE + 10):
        inst.inputs["Speed"] = float(k)
        inst.latch()
        inst.validate()
        assert len(judge_of(cls).table) <= judging.TABLE_SIZE


LOGIX = [cls for cls in TYPES if issubclass(cls, LogixInstruction)]


@settings(max_examples=200, deadline=None)
@given(
    cls=st.sampled_from(LOGIX),
    steps=st.lists(
        st.tuples(st.booleans(), st.sampled_from([0, 1, 2, 5, 7, 4, 1.5]), st.booleans()),
        min_size=1,
        max_size=12,
    ),
)
def test_status_words_follow_their_bits_and_mark_changes(
    cls: type[LogixInstruction], steps: list[tuple[bool, Any, bool]]
) -> None:
    sys_ = system()
    inst = cls("I", sys_.ctl)
    sys_.adopt(inst)
    axis_ops = [op.name for op in cls.OPERANDS if op.kind == Kind.AXIS]
    for rung, axis, step in steps:
        for name in axis_ops:
            inst.inputs[name] = axis
        inst.inputs[inst.TRIGGER] = rung
        before = dict(inst.outputs)
        sys_.changed_outputs.clear()
        inst.scan()
        if step:
            sys_.ctl.step()
            inst.update()
        out = inst.outputs
        flags = sum(1 << int(b) for b in LogixBit if out[b.name])
        assert out["FLAGS"] == flags
        if dict(out) != before:  # (a value set and reset in one scan may mark it too)
            assert "I" in sys_.changed_outputs


@settings(max_examples=200, deadline=None)
@given(
    old=st.dictionaries(st.sampled_from("ABCD"), st.sampled_from([0, 1, True, False, 2.5])),
    new=st.dictionaries(st.sampled_from("ABCDE"), st.sampled_from([0, 1, True, False, 2.5])),
)
def test_a_write_of_several_outputs_marks_the_instance_as_single_writes_do(
    old: dict[str, Any], new: dict[str, Any]
) -> None:
    from motion_server.instructions.base import Outputs

    one, many = Outputs("I", old), Outputs("I", old)
    one.changed, many.changed = set(), set()
    for key, value in new.items():
        one[key] = value
    many.write(new)
    assert dict(many) == dict(one)
    assert many.changed == one.changed
