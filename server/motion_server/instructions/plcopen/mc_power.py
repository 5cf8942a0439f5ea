"""MC_Power: the power stage, switched by the edges of Enable.

A rising edge of Enable switches the axis to Servo Control, a falling edge switches the
drive off. Between edges the block does not touch the power stage: Logix MSO/MSF, an MGS
Fast Disable, a shutdown or a fault keep the state they set, instead of being undone by
this block on the next scan (an axis disabled by a stop never re-enables by itself; raise
Enable again to re-enable it). Status follows the power stage, Valid when Status holds
without error. A faulted axis cannot be enabled: Error with ErrorID 20 on the rising
edge; reset it (MC_Reset) and raise Enable again.
"""

from __future__ import annotations

from ...kernel import AxisState, ErrorCode, MotionError
from ..base import PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType


@register
class MC_Power(PLCopenBlock):
    TYPE = "MC_Power"
    DESCRIPTION = "Power stage on/off (switched by the edges of Enable)"
    TRIGGER = "Enable"
    FOLLOWS_AXIS_STATE = True
    OPERANDS = (
        AXIS,
        Operand("EnablePositive", TagType.BOOL, True, description="reserved: always allowed"),
        Operand("EnableNegative", TagType.BOOL, True, description="reserved: always allowed"),
    )
    COMMON_STATUS = (
        StatusField("Status", TagType.BOOL, "the power stage is on"),
        StatusField("Valid", TagType.BOOL, "Status is valid (no error)"),
        StatusField("Busy", TagType.BOOL, "Enable is high"),
        StatusField("Error", TagType.BOOL, "the power stage could not be switched"),
        StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
    )

    def scan(self) -> None:
        enable = bool(self.inputs[self.TRIGGER])
        edge = enable != self._last_trigger
        self._last_trigger = enable
        if edge:
            self.latch()
            self.outputs["Error"] = False
            self.outputs["ErrorID"] = 0
            try:
                self.validate()
                ax = self.axis()
                if enable and ax.state != AxisState.SERVO_CONTROL:
                    self.ctl.servo_on(ax)
                elif not enable and ax.state == AxisState.SERVO_CONTROL:
                    self.ctl.servo_off(ax)
            except MotionError as exc:
                self.outputs["Error"] = True
                self.outputs["ErrorID"] = int(exc.code)
        self.outputs["Busy"] = enable
        self._status()

    def update(self) -> None:
        self._status()

    def asleep(self) -> bool:
        # Status follows the axis's power state: the system wakes the block whenever an
        # axis changes state (FOLLOWS_AXIS_STATE); otherwise nothing changes while Enable
        # stays low
        return not (self.inputs[self.TRIGGER] or self._last_trigger)

    def _status(self) -> None:
        try:
            ax = self.ctl.axis(int(self.op["Axis"]))
        except (MotionError, TypeError, ValueError, OverflowError):
            ax = None
        on = ax is not None and ax.servo_on
        if ax is not None and self._last_trigger and ax.state == AxisState.AXIS_FAULTED:
            # the power stage dropped under a held Enable: report why
            self.outputs["Error"] = True
            self.outputs["ErrorID"] = int(ErrorCode.AXIS_FAULTED)
        self.outputs["Status"] = on
        self.outputs["Valid"] = on and not self.outputs["Error"]
