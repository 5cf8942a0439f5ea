"""Property tests (hypothesis): determinism, robustness against any operand values, and
"a failed instruction never moves an axis".

A script is a list of instruction triggers, each with operand values and the number of
cycles the trigger is held high and then low. Operand values come from the whole range of
the tag's type (a tag accepts any value of its type; the instruction judges it): NaN, inf,
negative, huge and tiny numbers, unknown enumeration values, unconfigured axis numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from motion_server.instructions import Instruction, Kind, MotionSystem, Operand, TagType, catalog
from motion_server.instructions.base import BlockState, LogixInstruction, PLCopenBlock
from motion_server.kernel import AxisConfig, AxisType, FeedbackSignal

from ..support import make_system

TYPES = sorted(catalog())


def build() -> MotionSystem:
    """Four axes of every kind, one instance of every instruction type (``<TYPE>_1``)."""
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.VIRTUAL, max_velocity=500.0, max_acceleration=5000.0),
        AxisConfig(
            2,
            "Axis2",
            AxisType.SERVO,
            max_velocity=1000.0,
            max_acceleration=20000.0,
            max_deceleration=20000.0,
            max_jerk=1e6,
            coast_deceleration=500.0,
            following_error_limit=10.0,
        ),
        AxisConfig(3, "Axis3", AxisType.SERVO, units="deg", rollover=360.0, max_velocity=3600.0),
        AxisConfig(
            4,
            "Axis4",
            AxisType.FEEDBACK_ONLY,
            conversion_constant=100.0,
            feedback_signal=FeedbackSignal.SINE,
            signal_amplitude=5.0,
            signal_frequency=2.0,
        ),
    )
    for t in TYPES:
        system.add(t, f"{t}_1")
    return system


# -- operand values over the whole range of their tag type ---------------------------------
NASTY = [math.nan, math.inf, -math.inf, 0.0, -0.0, -1.0, 1e-300, 1e30]


def values(op: Operand) -> st.SearchStrategy[Any]:
    if op.kind == Kind.AXIS:
        return st.sampled_from([1, 2, 3, 4]) | st.integers(-3, 9) | st.just(2**31 - 1)
    if op.type == TagType.BOOL:
        return st.booleans()
    if op.type.is_float:
        width = 32 if op.type == TagType.REAL else 64
        nasty = [v for v in NASTY if width == 64 or abs(v) < 3.4e38 or not math.isfinite(v)]
        return (
            st.floats(-500.0, 500.0, width=width)
            | st.sampled_from(nasty)
            | st.floats(width=width, allow_nan=True, allow_infinity=True)
        )
    lo, hi = op.type.bounds
    if op.enum is not None:
        members = [int(m) for m in op.enum]
        return st.sampled_from(members) | st.integers(-2, 12) | st.integers(int(lo), int(hi))
    return st.integers(int(lo), int(hi))


@dataclass
class Step:
    """Trigger ``name`` with ``operands``: the trigger high for ``high`` cycles, then low
    for ``low`` cycles."""

    name: str
    operands: dict[str, Any]
    high: int
    low: int


@st.composite
def steps(draw: st.DrawFn) -> Step:
    t = draw(st.sampled_from(TYPES))
    cls = catalog()[t]
    ops = {}
    for op in cls.OPERANDS:
        if draw(st.booleans()):
            ops[op.name] = draw(values(op))
    return Step(f"{t}_1", ops, draw(st.integers(1, 3)), draw(st.integers(0, 40)))


# a few well-formed steps up front so that most scripts have powered, moving axes
POWER_UP = [
    Step("MSO_1", {"Axis": 1}, 1, 1),
    Step("MSO_1", {"Axis": 2}, 1, 1),
    Step("MC_Power_1", {"Axis": 3}, 2, 0),
    Step("MAJ_1", {"Axis": 2, "Speed": 100.0, "AccelRate": 2000.0, "DecelRate": 2000.0}, 1, 0),
]

scripts = st.lists(steps(), min_size=1, max_size=12).map(lambda s: POWER_UP + s)


def run(script: list[Step], skip: int | None = None) -> tuple[MotionSystem, np.ndarray]:
    """Run a script; return the system and the trace (one row per cycle: command and
    actual position and velocity of every axis). Step ``skip`` is left out."""
    system = build()
    ctl = system.ctl
    rows = []

    def cycle() -> None:
        system.cycle()
        rows.append(np.concatenate([ctl.cmd_pos, ctl.act_pos, ctl.cmd_vel, ctl.act_vel]))

    for k, step in enumerate(script):
        inst = system[step.name]
        for name, value in step.operands.items():
            inst.inputs[name] = value
        if k == skip:
            # the operands are written (they stay in the tag image), the trigger is not
            for _ in range(step.high + step.low):
                cycle()
            continue
        if step.name == "MC_Power_1":
            # level-controlled: Enable stays as the step leaves it
            inst.inputs["Enable"] = True
            for _ in range(step.high):
                cycle()
            inst.inputs["Enable"] = step.low % 2 == 0
            for _ in range(step.low):
                cycle()
            continue
        inst.inputs[inst.TRIGGER] = True
        for _ in range(step.high):
            cycle()
        inst.inputs[inst.TRIGGER] = False
        for _ in range(step.low):
            cycle()
    return system, np.array(rows)


def failed(inst: Instruction) -> bool:
    if isinstance(inst, LogixInstruction):
        return bool(inst.outputs["ER"])
    if isinstance(inst, PLCopenBlock):
        return inst.state == BlockState.ERROR
    return False


FAST = settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


@FAST
@given(scripts)
def test_same_script_gives_a_bit_identical_trace(script: list[Step]) -> None:
    _, a = run(script)
    _, b = run(script)
    assert a.shape == b.shape
    assert a.tobytes() == b.tobytes()


@FAST
@given(scripts)
def test_random_triggers_never_crash_nor_produce_nan(script: list[Step]) -> None:
    system, trace = run(script)
    assert np.isfinite(trace).all()
    for inst in system.instances.values():
        for name, value in inst.outputs.items():
            assert not (isinstance(value, float) and math.isnan(value)), (inst.name, name)


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(scripts, st.data())
def test_a_failed_instruction_never_moves_an_axis(script: list[Step], data: st.DataObject) -> None:
    k = data.draw(st.integers(len(POWER_UP), len(script) - 1), label="step under test")
    step = script[k]
    # judge the step's own verdict at the end of its trigger cycle
    probe, _ = run([*script[:k], Step(step.name, step.operands, 1, 0)])
    inst = probe[step.name]
    if not failed(inst):
        return
    event(f"failed: {step.name}")
    _, with_step = run(script)
    _, without = run(script, skip=k)
    assert with_step.tobytes() == without.tobytes()
