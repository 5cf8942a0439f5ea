"""MGSD, Motion Group Shutdown: every axis of the group to Axis Shutdown at once.

The drives are off and moving axes coast; motion instructions on the axes error with
ERR 7 until MGSR (or MASR for one axis) returns them to Axis Ready. A shut-down master
releases its followers and breaks its MDAC links (see ``Controller.shutdown``). DN in
the scan it executes.
"""

from __future__ import annotations

from ..base import LogixInstruction
from ..operands import GROUP
from ..registry import register


@register
class MGSD(LogixInstruction):
    TYPE = "MGSD"
    DESCRIPTION = "Motion Group Shutdown"
    OPERANDS = (GROUP,)

    def execute(self) -> None:
        self.ctl.group_shutdown(self.group().number)
        self.set_bits(DN=True)
