"""MCSV, Motion Calculate Slave Values: a cam profile's slave value and slopes at a master
value.

``MCSV(MotionControl, CamProfile, MasterValue, SlaveValue, SlopeValue, SlopeDerivative)``
(MOTION-RM002): for profile ``CamProfile`` and ``MasterValue``, the slave value, its first
derivative and its second derivative with respect to the master. A pure calculation: no
axis moves. DN in the scan of the rising edge, the outputs hold until the next execution.

Errors: 32 the profile is not calculated; 13 a profile number that does not exist, or a
MasterValue outside the profile's master range (the documents do not say what a
controller answers there; a value outside the profile has no slave value, so it is
refused rather than extrapolated, EXERR naming MasterValue).
"""

from __future__ import annotations

from ..base import LogixInstruction
from ..registry import register
from ..schema import Operand, StatusField, TagType
from .mccp import CAM_PROFILE


@register
class MCSV(LogixInstruction):
    TYPE = "MCSV"
    DESCRIPTION = "Motion Calculate Slave Values: slave value and slopes of a cam profile"
    MOTION_CONTROL_INDEX = 0
    OPERANDS = (
        CAM_PROFILE,
        Operand("MasterValue", TagType.REAL, 0.0, description="master value to evaluate at"),
    )
    OUTPUTS = (
        StatusField("SlaveValue", TagType.REAL, "slave value at MasterValue", default=0.0),
        StatusField("SlopeValue", TagType.REAL, "first derivative dSlave/dMaster", default=0.0),
        StatusField(
            "SlopeDerivative", TagType.REAL, "second derivative d2Slave/dMaster2", default=0.0
        ),
    )

    def execute(self) -> None:
        store = self.ctl.cams
        number = int(self.op["CamProfile"])
        if number not in store.slots:
            raise self.out_of_range("CamProfile", f"cam profile {number} does not exist")
        profile = store.use(number)
        x = float(self.op["MasterValue"])
        if not profile.start <= x <= profile.end:
            raise self.out_of_range(
                "MasterValue",
                f"MasterValue {x:g} is outside the profile's range "
                f"[{profile.start:g}, {profile.end:g}]",
            )
        f, f1, f2 = profile.evaluate(x)
        self.outputs["SlaveValue"] = f
        self.outputs["SlopeValue"] = f1
        self.outputs["SlopeDerivative"] = f2
        self.set_bits(DN=True)
