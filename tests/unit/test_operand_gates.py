"""One rule for operands a mode does not use (``Instruction.GATES``): such an operand (a
value or its units) is not judged; with its gate open the same value is ERR 13 / ErrorID
13 naming it."""

from __future__ import annotations

import pytest

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.instructions.base import OperandError
from motion_server.instructions.registry import catalog
from motion_server.instructions.schema import Operand
from motion_server.kernel import AxisConfig, AxisType, ErrorCode

from ..support import make_system

GATED = [
    (name, op)
    for name, cls in catalog().items()
    for op in cls.OPERANDS
    if op.name in cls.GATES and op.minimum is not None
]


def system() -> MotionSystem:
    return make_system(*(AxisConfig(n, f"A{n}", AxisType.SERVO) for n in (1, 2, 3)))


def test_the_gated_instructions_are_the_ones_with_selectors() -> None:
    gated = {name for name, cls in catalog().items() if cls.GATES}
    assert {"MAS", "MCD", "MAJ", "MAM", "MAG"} <= gated
    for cls in catalog().values():
        for name, gates in cls.GATES.items():
            cls.operand(name)  # a gated operand exists
            for selector, values in gates:
                op = cls.operand(selector)
                assert op.enum is not None, f"{cls.TYPE}.{selector} selects by enumeration"
                assert values <= {int(m) for m in op.enum}, f"{cls.TYPE}.{selector}: {values}"


@pytest.mark.parametrize(("type_name", "op"), GATED, ids=[f"{t}.{o.name}" for t, o in GATED])
def test_an_operand_is_judged_only_when_its_mode_uses_it(type_name: str, op: Operand) -> None:
    cls = instruction_type(type_name)
    name = op.name
    inst = cls("I", system().ctl)
    assert op.minimum is not None
    below = float(op.minimum) - 1.0
    gates = cls.GATES[name]
    # every gate closed: each selector holds a value none of its gates opens
    for selector, _ in gates:
        enum = cls.operand(selector).enum
        assert enum is not None
        opening = set().union(*(v for s, v in gates if s == selector))
        inst.inputs[selector] = next(int(m) for m in enum if int(m) not in opening)
    inst.inputs[name] = below
    inst.latch()
    inst.validate()  # not judged: no error
    # one gate open: judged, ERR 13 naming the operand
    selector, values = gates[0]
    inst.inputs[selector] = min(values)
    inst.latch()
    with pytest.raises(OperandError) as err:
        inst.validate()
    assert err.value.code == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert err.value.operand.name == name
