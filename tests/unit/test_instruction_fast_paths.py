"""The instruction layer's fast paths against the plain code they replace, in whole scans.

Many MAJ, MAM and MAG instances on one controller fire in the same scans with random
operands (valid and not: every units selector, merge, S-curve, speeds beyond the axis
maximum, axes that do not exist or cannot move, fraction and real ratios). The same
writes go to a second system whose instances judge operand by operand
(``judge_reference``), plan every MAJ/MAM through the general path
(``SpeedControlledMotion.plan_general``) and write their status one field at a time (the
rising status at once, before judging) with the FLAGS word recomputed after each call,
as before the fast paths. After every cycle
both must show the same outputs on every instance and command the same position and
velocity, bit for bit, on every axis; an instance is marked changed whenever an output
changed (the fast path may skip marking a value set and reset within one scan, never a
real change).
"""

from __future__ import annotations

import struct
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import Instruction, MotionSystem
from motion_server.instructions.base import (
    RUNG_EVENTS,
    LogixInstruction,
    OperandError,
    RungEvent,
)
from motion_server.instructions.judging import judge_reference
from motion_server.instructions.logix.mdsc import SpeedControlledMotion
from motion_server.instructions.logix_common import ProcessInstruction
from motion_server.instructions.registry import instruction_type
from motion_server.instructions.status import LogixBit
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    ErrorCode,
    Limits,
    MotionError,
    ProcessState,
)
from motion_server.kernel.gearing import GearTerm
from motion_server.kernel.processes import Process

from ..support import make_system

#: axes 1..6 servo (on), 7 feedback only; 9 does not exist
AXES = [1, 2, 3, 4, 5, 6, 7, 9]
#: valid values drawn more often than the others (a fired instance mostly executes)
RATES = [40.0, 100.0, 250.0, 0.0]
UNITS = [0, 1, 0, 1, 4]
DYNAMICS: dict[str, list[Any]] = {
    "Speed": [5.0, 50.0, 5000.0, 0.0, 5000.0, -1.0],
    "SpeedUnits": UNITS,
    "AccelRate": RATES,
    "AccelUnits": UNITS,
    "DecelRate": RATES,
    "DecelUnits": UNITS,
    "Profile": [0, 1],
    "AccelJerk": [0.0, 50.0, 100.0],
    "DecelJerk": [0.0, 50.0, 100.0],
    "JerkUnits": [0, 1, 2],
    "Merge": [0, 1],
    "MergeSpeed": [0, 1],
}
POOLS: dict[str, dict[str, list[Any]]] = {
    "MAJ": {"Axis": AXES, "Direction": [0, 1, 2], **DYNAMICS},
    "MAM": {"Axis": AXES, "MoveType": [0, 1, 2], "Position": [-10.0, 0.0, 25.5], **DYNAMICS},
    "MAG": {
        "SlaveAxis": AXES,
        "MasterAxis": AXES,
        "Direction": [0, 1, 2, 3, 4],
        "Ratio": [0.5, -1.25, 0.0, 20.0],
        "SlaveCounts": [0, 1, 3],
        "MasterCounts": [0, 1, 3],
        "MasterReference": [0, 1],
        "RatioFormat": [0, 1],
        "Clutch": [0, 1],
        "AccelRate": RATES,
        "AccelUnits": [0, 1],
    },
}
#: instance name -> type: two of each, so two instances may command one axis in a scan
INSTANCES = {f"{t}{k}": t for t in POOLS for k in (1, 2, 3)}


class _Reference:
    """Mixed into each instance type of the reference system: the plain code."""

    def scan(self) -> None:
        inst: Any = self
        rung = bool(inst.inputs[inst.TRIGGER])
        if not rung and not inst._last_trigger and not inst.outputs["EN"]:
            return
        event = RUNG_EVENTS[(inst._last_trigger, rung)]
        inst._last_trigger = rung
        if event == RungEvent.RISING:
            inst.set_bits(EN=True, DN=False, ER=False, PC=False)
            inst.outputs["ERR"] = 0
            inst.outputs["EXERR"] = 0
            inst.latch()
            try:
                inst.validate()
                inst.execute()
            except OperandError as exc:
                idx = exc.index + (1 if exc.index >= inst.MOTION_CONTROL_INDEX else 0)
                inst.fail(exc.code, idx if exc.code == ErrorCode.PARAMETER_OUT_OF_RANGE else 0)
            except MotionError as exc:
                inst.fail(exc.code)
        elif event == RungEvent.LOW and (inst.bit("DN") or inst.bit("ER")):
            inst.set_bits(EN=False)

    def fail(self, code: int, exerr: int = 0) -> None:
        out = self.outputs  # type: ignore[attr-defined]
        out["ERR"] = int(code)
        out["EXERR"] = int(exerr)
        self.set_bits(ER=True, DN=False, IP=False, PC=False, AC=False)

    def validate(self) -> None:
        judge_reference(self)  # type: ignore[arg-type]

    def plan(self, ax: Any) -> Any:
        return SpeedControlledMotion.plan_general(self, ax)  # type: ignore[arg-type]

    def set_bits(self, **bits: bool) -> None:
        out = self.outputs  # type: ignore[attr-defined]
        for name, value in bits.items():
            out[name] = bool(value)
        out["FLAGS"] = sum(1 << int(b) for b in LogixBit if out[b.name])

    def _write_status(self, values: dict[str, Any]) -> None:
        out = self.outputs  # type: ignore[attr-defined]
        for name, value in values.items():
            out[name] = value
        out["FLAGS"] = sum(1 << int(b) for b in LogixBit if out[b.name])

    def started(self, process: Process, extra: dict[str, Any] | None = None) -> None:
        self.process = process
        self.set_bits(DN=True, IP=process.active, PC=False)
        sets_pc = self.SETS_PC  # type: ignore[attr-defined]
        if not process.active and process.state == ProcessState.DONE and sets_pc:
            self.set_bits(PC=True)
        for name, value in (extra or {}).items():
            self.outputs[name] = value  # type: ignore[attr-defined]


def reference_type(type_name: str) -> type[Instruction]:
    cls = instruction_type(type_name)
    assert issubclass(cls, ProcessInstruction) and issubclass(cls, LogixInstruction)
    return type(f"Reference{cls.__name__}", (_Reference, cls), {})


def build(reference: bool) -> MotionSystem:
    axes = [
        AxisConfig(n, f"A{n}", AxisType.SERVO, max_velocity=1000.0, max_acceleration=500.0,
                   max_deceleration=400.0)
        for n in range(1, 7)
    ] + [AxisConfig(7, "A7", AxisType.FEEDBACK_ONLY)]  # fmt: skip
    system = make_system(*axes, period=0.002)
    for ax in system.ctl.axes[:6]:
        system.ctl.servo_on(ax)
    for name, type_name in INSTANCES.items():
        cls = reference_type(type_name) if reference else instruction_type(type_name)
        system.adopt(cls(name, system.ctl))
    return system


@st.composite
def scans(draw: st.DrawFn) -> list[list[tuple[str, dict[str, Any], bool]]]:
    """Cycles of (instance, operands written, trigger) for a few instances each."""
    out = []
    for _ in range(draw(st.integers(1, 8))):
        names = draw(st.lists(st.sampled_from(sorted(INSTANCES)), max_size=7, unique=True))
        cycle = []
        for name in names:
            pool = POOLS[INSTANCES[name]]
            keys = draw(st.lists(st.sampled_from(sorted(pool)), max_size=4, unique=True))
            values = {k: draw(st.sampled_from(pool[k])) for k in keys}
            cycle.append((name, values, draw(st.booleans())))
        out.append(cycle)
    return out


def bits(x: float) -> bytes:
    return struct.pack("<d", x)


def simple(value: Any) -> bool:
    return isinstance(value, bool | int | float | str | Limits | GearTerm)


def digest(process: Process) -> list[tuple[str, str]]:
    """What a process was planned with: its plain attributes (floats by their bits) and
    those of the objects it holds (a clutch ramp, a profile), not its owner."""
    out = [("type", type(process).__name__)]
    for name, value in sorted(vars(process).items()):
        if name == "owner":
            continue
        if simple(value):
            out.append((name, repr(bits(value) if isinstance(value, float) else value)))
        elif isinstance(value, tuple) and all(simple(v) for v in value):
            out.append((name, repr(value)))
        elif hasattr(value, "__dict__") and not isinstance(value, Instruction | Controller):
            for key, inner in sorted(vars(value).items()):
                if simple(inner):
                    out.append((f"{name}.{key}", repr(inner)))
    return out


@settings(max_examples=300, deadline=None)
@given(plan=scans())
def test_instances_fired_together_act_as_the_plain_code(
    plan: list[list[tuple[str, dict[str, Any], bool]]],
) -> None:
    fast, ref = build(False), build(True)
    for k, cycle in enumerate(plan + [[]] * 3):
        for system in (fast, ref):
            for name, values, rung in cycle:
                inst = system[name]
                inst.inputs.update(values)
                inst.inputs[inst.TRIGGER] = rung
            system.changed_outputs.clear()
        before = {name: dict(inst.outputs) for name, inst in fast.instances.items()}
        fast.cycle()
        ref.cycle()
        for name, inst in fast.instances.items():
            assert inst.outputs == ref[name].outputs, (k, name, cycle)
            if inst.outputs != before[name]:
                assert name in fast.changed_outputs, (k, name)
        assert fast.changed_outputs <= ref.changed_outputs
        for a, b in zip(fast.ctl.axes, ref.ctl.axes, strict=True):
            assert bits(a.command_position) == bits(b.command_position), (k, a.name)
            assert bits(a.command_velocity) == bits(b.command_velocity), (k, a.name)
            assert [digest(p) for p in a.processes] == [digest(p) for p in b.processes], (
                k,
                a.name,
            )
