"""MC_Power: level-controlled power stage. Enable high: Servo Control; low: drive off.

Status follows the power stage, Valid when Status holds without error. A faulted axis
cannot be enabled: Error with ErrorID 20 until MC_Reset.
"""

from __future__ import annotations

from ...kernel import AxisState, MotionError
from ..base import PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType


@register
class MC_Power(PLCopenBlock):
    TYPE = "MC_Power"
    DESCRIPTION = "Power stage on/off (level-controlled by Enable)"
    TRIGGER = "Enable"
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

    def _status(self) -> None:
        try:
            on = self.ctl.axis(int(self.op["Axis"])).servo_on
        except (MotionError, TypeError, ValueError, OverflowError):
            on = False
        self.outputs["Status"] = on
        self.outputs["Valid"] = on and not self.outputs["Error"]
