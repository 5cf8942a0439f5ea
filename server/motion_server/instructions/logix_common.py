"""Shared shapes of Logix instructions: one-scan axis commands and process followers."""

from __future__ import annotations

from typing import Any, ClassVar

from ..kernel import Axis, ProcessState
from ..kernel.processes import Process
from .base import LogixInstruction
from .operands import AXIS
from .schema import Operand
from .status import LogixBit

# read every cycle by poll(), as module constants (see motion_server.kernel.enums)
_ACTIVE = ProcessState.ACTIVE
_DONE = ProcessState.DONE
_ERROR = ProcessState.ERROR
#: FLAGS of a process just started and active: DN and IP (EN and AC added by the write)
_STARTED_FLAGS = (1 << LogixBit.DN.value) | (1 << LogixBit.IP.value)
#: the status an active process starts with (see :meth:`ProcessInstruction.started_active`)
STARTED_ACTIVE: dict[str, Any] = {"DN": True, "IP": True, "PC": False}


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
    #: while its process runs, the instance only waits for it to end (:meth:`parked_on`):
    #: True where ``scan``, ``update`` and ``poll`` are these (a subclass that follows
    #: more than the process's state, as a cam's SEGMENT, says False)
    PARKS: ClassVar[bool] = True

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.process: Process | None = None

    def started(self, process: Process, extra: dict[str, Any] | None = None) -> None:
        """Follow ``process``: DN, IP while it runs (PC if it is already done), and the
        outputs ``extra`` in the same write."""
        self.process = process
        active = bool(process.active)
        status = {
            "DN": True,
            "IP": active,
            "PC": bool(not active and process.state == _DONE and self.SETS_PC),
        }
        if extra:
            status.update(extra)
        self._write_status(status)

    def started_active(self, process: Process, status: dict[str, Any]) -> None:
        """:meth:`started` on a rising rung for a ``process`` known to be active, with
        ``status`` = {DN: True, IP: True, PC: False} and the extra outputs: one write."""
        self.process = process
        if self._rising and process.state == _ACTIVE:
            self._write_started(status, _STARTED_FLAGS)
        else:
            extra = {k: v for k, v in status.items() if k not in ("DN", "IP", "PC")}
            self.started(process, extra)

    def parked_on(self) -> Process | None:
        """The running process, when nothing but its end can change this instance:
        IP set, no MDAC link shown (AC), the rung steady (no edge to come, EN already
        cleared on a low rung), no rising status owed."""
        p = self.process
        if p is None or p.state is not _ACTIVE or not self.PARKS:
            return None
        out = self.outputs
        if not out["IP"] or out["AC"] or not self.rung_steady():
            return None
        return p

    def end_parked(self) -> bool:
        """:meth:`update` of this instance parked on its process (:meth:`parked_on`),
        now that the process has left ACTIVE; True if the instance is asleep after it.
        While parked, nothing but the process changed (IP set, AC and TrackingMaster
        clear, the rung steady: a write would have woken it): so IP clears, PC follows
        a completion and the instance sleeps, without the full update and the sleep
        test (a group stop ending 256 jogs in one cycle). A process in error takes the
        full update."""
        p = self.process
        state = None if p is None else p.state
        if state is None or state is _ERROR or state is _ACTIVE or self._rising:
            self.update()
            return self.asleep()
        self.process = None
        self.clear_ip(self.SETS_PC if state is _DONE else None)
        return True

    def poll(self) -> None:
        p = self.process
        if p is None:
            return
        state = p.state
        if state == _ACTIVE:
            return
        if state == _DONE:
            self.clear_ip(self.SETS_PC)
        elif state == _ERROR:
            self.outputs["ERR"] = p.error_code
            self.set_bits(IP=False, ER=True)
        else:
            self.clear_ip()
        self.process = None
