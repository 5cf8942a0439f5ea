"""MC_Power: the power stage, enabled as long as Enable is high.

PLCopen Part 1: "As long as 'Enable' is true, power is being enabled"; "If the MC_Power FB
is called with the 'Enable' = true while being in 'Disabled', the axis state changes to
'Standstill'". A rising edge of Enable switches the axis to Servo Control, a falling edge
switches the drive off. While Enable stays high, an axis that a reset brings back to Axis
Ready (MC_Reset / MAFR from a fault, MASR / MGSR from a shutdown: ``power.RESETS``) is
enabled again in the block's next scan, and Error clears. A deliberate disable while
Enable is high (Logix MSF, an MGS Fast Disable, a programmed stop's disable action) is
not undone: those are commands of their own, which the block would otherwise reverse on
the next scan; lower and raise Enable to re-enable after them. Status follows the power
stage, Valid when Status holds without error. A faulted axis cannot be enabled: Error with
ErrorID 20 (shut down: 7) until it is reset.
"""

from __future__ import annotations

from ...kernel import AxisState, ErrorCode, MotionError
from ...kernel.power import RESETS
from ..base import PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, StatusField, TagType


@register
class MC_Power(PLCopenBlock):
    TYPE = "MC_Power"
    DESCRIPTION = "Power stage on/off (enabled while Enable is high)"
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
        elif enable:
            self._hold()
        self.outputs["Busy"] = enable
        self._status()

    def update(self) -> None:
        self._status()

    def _hold(self) -> None:
        """Enable held high: an axis a reset left in Axis Ready is enabled again."""
        try:
            ax = self.axis()
        except MotionError:
            return  # the edge reported it; a later write to Axis is a new edge's business
        if ax.state != AxisState.AXIS_READY or ax.power_event not in RESETS:
            return
        try:
            self.ctl.servo_on(ax)
        except MotionError as exc:
            self.outputs["Error"] = True
            self.outputs["ErrorID"] = int(exc.code)
            return
        self.outputs["Error"] = False
        self.outputs["ErrorID"] = 0

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
