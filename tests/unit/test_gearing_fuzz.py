"""Bad input never crashes and never produces NaN: random triggers of the gearing
instructions (and the stops and jogs they meet) with random operand values of each
operand's tag type, including the extremes and non-finite REALs."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.instructions.schema import Kind, Operand, TagType
from motion_server.kernel import AxisConfig, AxisType

from ..support import make_system

TYPES = (
    "MAG",
    "MC_GearIn",
    "MC_GearOut",
    "MC_CombineAxes",
    "MC_GearInPos",
    "MAJ",
    "MAS",
    "MC_Stop",
)


def system() -> MotionSystem:
    s = make_system(
        AxisConfig(1, "V", AxisType.VIRTUAL),
        AxisConfig(2, "S", AxisType.SERVO, following_error_limit=50.0),
        AxisConfig(3, "R", AxisType.SERVO, rollover=360.0),
        AxisConfig(4, "W", AxisType.FEEDBACK_ONLY, conversion_constant=100.0),
    )
    for n in (1, 2, 3):
        s.ctl.servo_on(s.ctl.axis(n))
    return s


def value(op: Operand) -> st.SearchStrategy[object]:
    if op.kind == Kind.AXIS:
        return st.integers(0, 5)
    if op.type == TagType.BOOL:
        return st.booleans()
    lo, hi = op.type.bounds
    if op.type.is_float:
        special = st.sampled_from([0.0, -0.0, 1e-30, -1.0, math.nan, math.inf, -math.inf, hi])
        usual = st.floats(-1e4, 1e4, allow_nan=False)
        return st.one_of(usual, special, st.floats(lo, hi, allow_nan=False))
    small = st.integers(-3, 5)
    return st.one_of(small, st.integers(int(lo), int(hi)))


@st.composite
def command(draw: st.DrawFn) -> tuple[str, dict[str, object], int]:
    type_name = draw(st.sampled_from(TYPES))
    cls = instruction_type(type_name)
    ops = {op.name: draw(value(op)) for op in cls.OPERANDS}
    return type_name, ops, draw(st.integers(1, 40))


@settings(max_examples=60, deadline=None)
@given(
    script=st.lists(command(), min_size=1, max_size=12),
    wheel=st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=5),
)
def test_random_gearing_commands_never_crash_or_produce_nan(
    script: list[tuple[str, dict[str, object], int]], wheel: list[float]
) -> None:
    s = system()
    for i, (type_name, ops, cycles) in enumerate(script):
        inst = s.add(type_name, f"I{i}", {})
        for name, v in ops.items():
            inst.inputs[name] = v
        inst.inputs[inst.TRIGGER] = True
        s.ctl.set_feedback_input(s.ctl.axis(4), wheel[i % len(wheel)])
        s.cycle(cycles)
        inst.inputs[inst.TRIGGER] = False
        s.cycle()
        ctl = s.ctl
        for arr in (ctl.cmd_pos, ctl.cmd_vel, ctl.act_pos, ctl.act_vel):
            assert np.all(np.isfinite(arr)), (type_name, ops)
        for inst_ in s.instances.values():
            for v in inst_.outputs.values():
                assert not (isinstance(v, float) and math.isnan(v))
