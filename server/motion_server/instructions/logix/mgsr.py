"""MGSR, Motion Group Shutdown Reset: every shut-down axis of the group to Axis Ready.

Faults are cleared as well (as MASR does); the axes can then be enabled with MSO. DN in
the scan it executes.
"""

from __future__ import annotations

from ..base import LogixInstruction
from ..operands import GROUP
from ..registry import register


@register
class MGSR(LogixInstruction):
    TYPE = "MGSR"
    DESCRIPTION = "Motion Group Shutdown Reset"
    OPERANDS = (GROUP,)

    def execute(self) -> None:
        self.ctl.group_shutdown_reset(self.group().number)
        self.set_bits(DN=True)
