"""MGS, Motion Group Stop: stop every axis of a group.

StopMode Programmed stops each axis by its configured programmed stop mode (Fast Stop,
Fast Disable, Hard Disable, Fast Shutdown, Hard Shutdown); Fast Stop and Fast Disable
force that behaviour on every axis. Ramps use the axis maximum deceleration and are
always trapezoidal. IP is set on the rising edge; DN once the group's next coarse update
has initiated the stop on every axis; then IP stays set until every axis has stopped
(and been disabled or shut down), when PC is set. Every motion instruction on the axes
loses IP (PLCopen blocks report CommandAborted), MDAC links with an axis of the group
break and pending master reassignments are cleared (see ``Controller.group_stop``).
"""

from __future__ import annotations

from enum import IntEnum

from ...kernel import GroupStop, ProgrammedStopMode
from ..base import LogixInstruction
from ..operands import GROUP
from ..registry import register
from ..schema import Operand, TagType


class MGSStopMode(IntEnum):
    PROGRAMMED = 0
    FAST_STOP = 1
    FAST_DISABLE = 2


#: the axis stop mode an explicit MGS StopMode forces (Programmed: each axis's own)
FORCED: dict[MGSStopMode, ProgrammedStopMode | None] = {
    MGSStopMode.PROGRAMMED: None,
    MGSStopMode.FAST_STOP: ProgrammedStopMode.FAST_STOP,
    MGSStopMode.FAST_DISABLE: ProgrammedStopMode.FAST_DISABLE,
}


@register
class MGS(LogixInstruction):
    TYPE = "MGS"
    DESCRIPTION = "Motion Group Stop"
    OPERANDS = (
        GROUP,
        Operand(
            "StopMode",
            TagType.UDINT,
            0,
            enum=MGSStopMode,
            description="0 programmed, 1 fast stop, 2 fast disable",
        ),
    )

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.stop: GroupStop | None = None

    def execute(self) -> None:
        mode = MGSStopMode(int(self.op["StopMode"]))
        self.stop = self.ctl.group_stop(self.group().number, FORCED[mode], owner=self)
        self.set_bits(IP=True)

    def poll(self) -> None:
        stop = self.stop
        if stop is None:
            return
        if stop.initiated and not self.bit("DN"):
            self.set_bits(DN=True)
        if stop.complete:
            self.set_bits(IP=False, PC=True)
            self.stop = None
