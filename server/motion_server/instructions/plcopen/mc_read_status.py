"""MC_ReadStatus: the axis's state in the PLCopen state diagram, one output per state.

PLCopen Part 1: "returns in detail the status of the state diagram of the selected axis".
Exactly one of the eight state outputs is TRUE while Valid (the axis's ``PLCopenState``
as the tag ``<Axis>.PLCopenState`` shows it, read after the cycle's kernel step). Enable-
style (:class:`~motion_server.instructions.base.EnableBlock`): Busy while Enable is high,
Error with ErrorID 11 for an axis that does not exist.
"""

from __future__ import annotations

from ...kernel import PLCopenState
from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import StatusField, TagType

#: output name -> the PLCopen state it shows
STATE_OUTPUTS: dict[str, PLCopenState] = {
    "ErrorStop": PLCopenState.ERRORSTOP,
    "Disabled": PLCopenState.DISABLED,
    "Stopping": PLCopenState.STOPPING,
    "Homing": PLCopenState.HOMING,
    "Standstill": PLCopenState.STANDSTILL,
    "DiscreteMotion": PLCopenState.DISCRETE_MOTION,
    "ContinuousMotion": PLCopenState.CONTINUOUS_MOTION,
    "SynchronizedMotion": PLCopenState.SYNCHRONIZED_MOTION,
}


@register
class MC_ReadStatus(EnableBlock):
    TYPE = "MC_ReadStatus"
    DESCRIPTION = "The axis's PLCopen state, one output per state (Enable-style)"
    OPERANDS = (AXIS,)
    OUTPUTS = tuple(
        StatusField(name, TagType.BOOL, f"the axis is in the PLCopen state {state.name}")
        for name, state in STATE_OUTPUTS.items()
    )

    def read(self) -> None:
        state = self.axis().plcopen_state
        for name, s in STATE_OUTPUTS.items():
            self.outputs[name] = state == s
