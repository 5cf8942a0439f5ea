"""Shared shapes of Logix instructions: one-scan axis commands and process followers."""

from __future__ import annotations

from typing import ClassVar

from ..kernel import Axis, ProcessState
from ..kernel.processes import Process
from .base import LogixInstruction
from .operands import AXIS
from .schema import Operand


class AxisCommand(LogixInstruction):
    """A one-scan instruction on one axis (MSO, MSF, MAFR, MASD, MASR): DN at once."""

    OPERANDS: ClassVar[tuple[Operand, ...]] = (AXIS,)

    def execute(self) -> None:
        self.action(self.axis())
        self.set_bits(DN=True)

    def action(self, ax: Axis) -> None:
        raise NotImplementedError


class ProcessInstruction(LogixInstruction):
    """An instruction that starts a motion process: DN at initiation, IP while the
    process runs, PC when it completes (if ``SETS_PC``); IP clears when the process is
    superseded, stopped, shut down or faulted."""

    SETS_PC: ClassVar[bool] = True

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.process: Process | None = None

    def started(self, process: Process) -> None:
        self.process = process
        self.set_bits(DN=True, IP=process.active, PC=False)
        if not process.active and process.state == ProcessState.DONE and self.SETS_PC:
            self.set_bits(PC=True)

    def poll(self) -> None:
        p = self.process
        if p is None:
            return
        if p.state == ProcessState.ACTIVE:
            return
        if p.state == ProcessState.DONE:
            self.set_bits(IP=False, PC=self.SETS_PC)
        elif p.state == ProcessState.ERROR:
            self.outputs["ERR"] = p.error_code
            self.set_bits(IP=False, ER=True)
        else:
            self.set_bits(IP=False)
        self.process = None
