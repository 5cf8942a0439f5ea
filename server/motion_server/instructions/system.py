"""A controller with its instruction instances: one call runs one PLC scan."""

from __future__ import annotations

from typing import Any

from ..kernel import Controller
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

    def add(self, type_name: str, name: str, defaults: dict[str, Any] | None = None) -> Instruction:
        if name in self.instances:
            raise ValueError(f"duplicate instruction instance {name!r}")
        inst = instruction_type(type_name)(name, self.ctl, defaults)
        self.instances[name] = inst
        return inst

    def __getitem__(self, name: str) -> Instruction:
        return self.instances[name]

    def cycle(self, count: int = 1) -> None:
        instances = list(self.instances.values())
        for _ in range(count):
            if self.ctl.run_mode:
                for inst in instances:
                    inst.scan()
            self.ctl.step()
            for inst in instances:
                inst.update()
