"""Helpers shared by the tests: small systems built directly and stepped by hand."""

from __future__ import annotations

import numpy as np

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import AxisConfig, Controller, GroupConfig


def make_system(*axes: AxisConfig, period: float = 0.002) -> MotionSystem:
    """A controller with ``axes`` in one group, and no instruction instances yet."""
    group = GroupConfig(1, "Group1", tuple(a.number for a in axes), period)
    return MotionSystem(Controller(list(axes), [group]))


def trigger(system: MotionSystem, inst: Instruction, **operands: object) -> None:
    """Write operands, then raise the trigger for one cycle (the rising edge)."""
    for name, value in operands.items():
        inst.inputs[name] = value
    inst.inputs[inst.TRIGGER] = True
    system.cycle()


def sample(system: MotionSystem, axis: int, cycles: int, what: str = "command") -> np.ndarray:
    """Run ``cycles`` cycles and return the axis position after each one."""
    ax = system.ctl.axis(axis)
    out = np.empty(cycles)
    for k in range(cycles):
        system.cycle()
        out[k] = ax.command_position_unwound if what == "command" else ax.actual_position_unwound
    return out
