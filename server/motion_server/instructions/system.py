"""A controller with its instruction instances: one call runs one PLC scan.

An exception inside one instance (a bug, never an operand: operands are judged) is
contained there: the instance shows the internal error (Logix ER, PLCopen Error, code
1005), the axes its axis operands name are stopped at their maximum deceleration, and the
scan goes on for every other instance. The host drains :attr:`MotionSystem.internal_errors`
and logs each one with its traceback.
"""

from __future__ import annotations

from typing import Any

from ..kernel import Controller, MotionError
from .base import Instruction
from .registry import instruction_type


class MotionSystem:
    """The kernel plus named instruction instances, scanned in a fixed order.

    ``cycle()``: every instance latches and executes on its trigger edge, the kernel
    steps one base period, every instance updates its status from the kernel. Outside run
    mode (``Controller.set_mode``) the instances are not scanned, like a program that is
    not executed; their status still follows the kernel.
    """

    def __init__(self, ctl: Controller) -> None:
        self.ctl = ctl
        self.instances: dict[str, Instruction] = {}
        #: names of the instances whose outputs changed since the host last looked
        self.changed_outputs: set[str] = set()
        #: (instance name, exception) of instances that raised, for the host to log
        self.internal_errors: list[tuple[str, BaseException]] = []

    def add(self, type_name: str, name: str, defaults: dict[str, Any] | None = None) -> Instruction:
        if name in self.instances:
            raise ValueError(f"duplicate instruction instance {name!r}")
        inst = instruction_type(type_name)(name, self.ctl, defaults)
        self.adopt(inst)
        return inst

    def adopt(self, inst: Instruction) -> None:
        """Add a built instance (``add`` builds it from the catalog)."""
        if inst.name in self.instances:
            raise ValueError(f"duplicate instruction instance {inst.name!r}")
        self.instances[inst.name] = inst
        inst.outputs.changed = self.changed_outputs
        self.changed_outputs.add(inst.name)

    def __getitem__(self, name: str) -> Instruction:
        return self.instances[name]

    def cycle(self, count: int = 1) -> None:
        instances = list(self.instances.values())
        for _ in range(count):
            if self.ctl.run_mode:
                for inst in instances:
                    try:
                        inst.scan()
                    except Exception as exc:
                        self._contain(inst, exc)
            self.ctl.step()
            for inst in instances:
                try:
                    inst.update()
                except Exception as exc:
                    self._contain(inst, exc)

    def _contain(self, inst: Instruction, exc: Exception) -> None:
        """``inst`` raised: the internal error on it, its axes stopped, noted for the host."""
        self.internal_errors.append((inst.name, exc))
        try:
            inst.fail_internal()
        except Exception as again:  # a broken state table: still report the first one
            self.internal_errors.append((inst.name, again))
        ctl = self.ctl
        for ax in inst.commanded_axes():
            if ax.drive_enabled and any(p.active for p in ax.processes):
                try:
                    ctl.stop(ax, None, ax.config.max_deceleration, bounded=True)
                except MotionError:
                    continue
