"""MCCP, Motion Calculate Cam Profile: compute a cam profile from a cam table's points.

``MCCP(MotionControl, Cam, Length, StartSlope, EndSlope, CamProfile)`` (MOTION-RM002):
``Length`` elements of cam table ``Cam`` from element ``CamStart`` (Logix writes the start
as the Cam array's index; here it is an operand of its own, after the others so that
EXERR numbers the Logix operands as the faceplate does) become profile ``CamProfile``:
linear or cubic segments as each element's SegmentType says, the cubic ones a clamped
spline with Start and End Slope at the profile's ends (:mod:`motion_server.kernel.cam_profile`).
The profile is a snapshot: editing the table afterwards changes nothing until the next
MCCP. Executes in one scan: DN at once, the profile's Status is 2.

Errors: 26 Length below 2 or beyond the table; 27 the profile holds fewer points than
Length; 28 a SegmentType other than 0 or 1; 29 master values not strictly increasing;
31 the profile is used by a running MAPC, MATC or MC_CamIn (its Status is above 2); 13 a
table or profile number that does not exist, or a slope that is not finite (EXERR names
the operand).
"""

from __future__ import annotations

from ...kernel.errors import ErrorCode, MotionError
from ..base import LogixInstruction
from ..registry import register
from ..schema import Operand, TagType

CAM = Operand("Cam", TagType.DINT, 1, minimum=1, description="cam table number")
CAM_PROFILE = Operand("CamProfile", TagType.DINT, 1, minimum=1, description="cam profile number")


@register
class MCCP(LogixInstruction):
    TYPE = "MCCP"
    DESCRIPTION = "Motion Calculate Cam Profile: a cam table's points become a profile"
    #: MCCP(MotionControl, Cam, Length, StartSlope, EndSlope, CamProfile)
    MOTION_CONTROL_INDEX = 0
    OPERANDS = (
        CAM,
        Operand("Length", TagType.DINT, 2, description="number of cam elements used (>= 2)"),
        Operand("StartSlope", TagType.REAL, 0.0, description="slope dy/dx at the first point"),
        Operand("EndSlope", TagType.REAL, 0.0, description="slope dy/dx at the last point"),
        CAM_PROFILE,
        Operand("CamStart", TagType.DINT, 0, minimum=0, description="first element used"),
    )

    def execute(self) -> None:
        store = self.ctl.cams
        for name, known in (("Cam", store.tables), ("CamProfile", store.slots)):
            if int(self.op[name]) not in known:
                raise self.out_of_range(name, f"{name} {self.op[name]} does not exist")
        slot = store.slot(int(self.op["CamProfile"]))
        if slot.status == 1:
            raise MotionError(
                ErrorCode.CAM_PROFILE_BEING_CALCULATED,
                f"cam profile {slot.number} is being calculated",
            )
        store.calculate(
            int(self.op["Cam"]),
            int(self.op["CamStart"]),
            int(self.op["Length"]),
            float(self.op["StartSlope"]),
            float(self.op["EndSlope"]),
            slot.number,
        )
        self.set_bits(DN=True)
