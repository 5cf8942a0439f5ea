"""MC_SetOverride: scale the velocity, acceleration and jerk of an axis's motion.

PLCopen Part 1 (and TwinCAT Tc2_MC2, CODESYS SM3_Basic): an Enable-style block that
"sets the values of override for the whole axis, and all functions that are working on
that axis". While Enable is high the factors (1.0 = 100 %) are written every cycle; a
change takes effect on the running motion in the same cycle (:mod:`~motion_server.kernel.
override`): the axis's moves and jogs are re-planned from where they are with velocity x
VelFactor, acceleration and deceleration x AccFactor, jerk x JerkFactor. VelFactor 0
brings the axis to rest without changing its state; a factor above 0 resumes the motion.
Synchronized motion (gears, master-driven motion), superimposed moves, stops and homing
are not scaled: a slave follows its master.

Ranges: VelFactor 0 to 1, AccFactor and JerkFactor above 0 up to 1 (as TwinCAT MC3: an
override never raises the programmed dynamics beyond the axis's limits); out of range is
Error with ErrorID 13 and the axis keeps the factors it has. Enabled while the factors
are set; Busy follows Enable. Enable low: the override ends (factors back to 1, the
motion re-planned with its programmed dynamics) and the outputs clear.
"""

from __future__ import annotations

from ...kernel import MotionError, Override
from ...kernel.override import NEUTRAL
from ..base import EnableBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType


def _factor(name: str, minimum: float, exclusive: bool, what: str) -> Operand:
    return Operand(
        name,
        TagType.LREAL,
        1.0,
        minimum=minimum,
        maximum=1.0,
        exclusive_min=exclusive,
        description=f"{what} factor (1.0 = 100 %)",
    )


@register
class MC_SetOverride(EnableBlock):
    TYPE = "MC_SetOverride"
    DESCRIPTION = "Scale the velocity, acceleration and jerk of an axis's moves and jogs"
    OPERANDS = (
        AXIS,
        _factor("VelFactor", 0.0, False, "velocity (0 to 1; 0 holds the axis at rest)"),
        _factor("AccFactor", 0.0, True, "acceleration and deceleration (> 0 to 1)"),
        _factor("JerkFactor", 0.0, True, "jerk (> 0 to 1)"),
    )
    COMMON_STATUS = (
        StatusField("Enabled", TagType.BOOL, "the override factors are set"),
        StatusField("Busy", TagType.BOOL, "Enable is high: the factors are written every cycle"),
        StatusField("Error", TagType.BOOL, "the factors cannot be set, see ErrorID"),
        StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
    )

    def scan(self) -> None:
        was_enabled = self._last_trigger
        super().scan()
        if not self._last_trigger:
            if was_enabled:
                self._release()
            return
        if self._error:
            return
        factors = Override(
            float(self.op["VelFactor"]), float(self.op["AccFactor"]), float(self.op["JerkFactor"])
        )
        try:
            self.ctl.set_override(self.axis(), factors)
        except MotionError as exc:
            self._error = int(exc.code)

    def _release(self) -> None:
        """Enable fell: the axis's motion goes back to its programmed dynamics."""
        try:
            ax = self.axis()
        except MotionError:
            return
        try:
            self.ctl.set_override(ax, NEUTRAL)
        except MotionError as exc:
            # cannot happen with factors of 1 (the programmed plan was plannable); if
            # it did, the factors stay and the error shows until the next Enable
            self._error = int(exc.code)

    def read(self) -> None:
        """Nothing to read: the factors were set in the scan."""

    def _publish(self) -> None:
        enabled = self._last_trigger
        out = self.outputs
        out["Busy"] = enabled
        out["Error"] = enabled and bool(self._error)
        out["Enabled"] = enabled and not self._error
        out["ErrorID"] = self._error if enabled else 0
