"""MATC, Motion Axis Time Cam: the axis follows a cam profile of time.

``MATC(Axis, MotionControl, Direction, CamProfile, DistanceScaling, TimeScaling,
ExecutionMode, ExecutionSchedule)`` (MOTION-RM002): the profile's master values are
seconds,

    axis = axis at start + D x DistanceScaling x (f(x) - f(start)),
    x = start + t / TimeScaling

with t the time since the cam started, counted in whole periods (exact, no sum): a
larger TimeScaling runs slower, a larger DistanceScaling goes further. Execution Mode
Once (completes at the profile's end: PC) or Continuous (repeats, each pass adding its
rise); Persistent is for position cams (ERR 13). Execution Schedule Immediate, or Pending
(takes over when the running time cam completes or passes the end of its profile, with
no jump; preloaded when none runs). Direction as MAPC. Time cams superimpose on the
axis's other motion.

Status: DN and IP in the scan of execution; IP until completed (PC), superseded by a
Pending cam, stopped (MAS All or Time Cam, MGS), merged, shut down or faulted; SEGMENT.
MotionStatus TimeCamStatus while in process, TimeCamLockStatus (bit 14) while it drives
the axis, TimeCamPendingStatus while a Pending time cam waits.

Master Driven: with an MDAC on the axis whose MotionType is All or Time Cam, t is the
MDAC master's travel since the start (master units; TimeScaling is master units per
profile unit) instead of time, and like every master-driven motion the profile advances
with forward master travel only (a master going back holds the axis). The MDAC's AC is
set while the cam runs; a stop that breaks the link (MAS All, MGS, MASD, a fault) ramps
the axis to rest.

Errors: 23 an Immediate MATC on an axis already time camming; 30 / 32 the profile is
being calculated / not calculated; 13 a scaling that is zero, not finite or beyond
+-2^31, a schedule other than Immediate or Pending, Persistent mode, a profile that does
not exist (EXERR names the operand); 8 a feedback-only axis; 5, 7, 20 the power state.
"""

from __future__ import annotations

from ...kernel import ProcessKind
from ...kernel.cams import CamMode, CamProcess, MasterDirection, active_cam
from ...kernel.errors import ErrorCode, MotionError
from ...kernel.master_driven import MotionType, link_reference
from ..cam_common import ExecutionSchedule, calculated_profile, scaling, start_cam
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, TagType
from .mag import DIRECTION, GearDirection, resolve_direction
from .mapc import CamInstruction
from .mccp import CAM_PROFILE


@register
class MATC(CamInstruction):
    TYPE = "MATC"
    DESCRIPTION = "Motion Axis Time Cam: the axis follows a cam profile of time"
    MOTION_CONTROL_INDEX = 1
    OPERANDS = (
        AXIS,
        DIRECTION,
        CAM_PROFILE,
        Operand("DistanceScaling", TagType.REAL, 1.0, description="scales the distance"),
        Operand("TimeScaling", TagType.REAL, 1.0, description="scales the time (s per unit)"),
        Operand(
            "ExecutionMode",
            TagType.DINT,
            CamMode.ONCE,
            enum=CamMode,
            description="0 once, 1 continuous",
        ),
        Operand(
            "ExecutionSchedule",
            TagType.DINT,
            ExecutionSchedule.IMMEDIATE,
            enum=ExecutionSchedule,
            description="0 immediate, 1 pending",
        ),
    )

    def execute(self) -> None:
        ctl = self.ctl
        ax = self.axis()
        ctl.require_motion(ax)
        mode = CamMode(int(self.op["ExecutionMode"]))
        if mode == CamMode.PERSISTENT:
            raise self.out_of_range("ExecutionMode", "a time cam runs Once or Continuous")
        schedule = ExecutionSchedule(int(self.op["ExecutionSchedule"]))
        if schedule not in (ExecutionSchedule.IMMEDIATE, ExecutionSchedule.PENDING):
            raise self.out_of_range("ExecutionSchedule", "a time cam is Immediate or Pending")
        number = int(self.op["CamProfile"])
        if number not in ctl.cams.slots:
            raise self.out_of_range("CamProfile", f"cam profile {number} does not exist")
        profile = calculated_profile(ctl, number)
        ds = scaling(self, "DistanceScaling")
        ts = scaling(self, "TimeScaling")
        if ts < 0.0:
            raise self.out_of_range("TimeScaling", "time runs forward: TimeScaling must be > 0")
        pending = schedule == ExecutionSchedule.PENDING
        if not pending and active_cam(ax, ProcessKind.TIME_CAM) is not None:
            raise MotionError(
                ErrorCode.ILLEGAL_DYNAMIC_CHANGE,
                f"{ax.name} is time camming: use the Pending schedule or stop the cam",
            )
        direction = resolve_direction(GearDirection(int(self.op["Direction"])), ax.cam_direction)

        link = ctl.mdsc.link_for(ax.number, MotionType.TIME_CAM)

        def build() -> CamProcess:
            if link is None:
                return CamProcess(ctl, profile, mode, direction * ds, ts, profile.start, owner=self)
            master = ctl.axis(link.master)
            return CamProcess(
                ctl,
                profile,
                mode,
                direction * ds,
                ts,
                profile.start,
                master=master.index,
                source=link_reference(master, link.reference),
                master_number=master.number,
                direction=MasterDirection.FORWARD_ONLY,
                kind=ProcessKind.TIME_CAM,
                owner=self,
            )

        proc = start_cam(ctl, ax, build, pending)
        ax.cam_direction = direction
        if link is not None:
            link.processes.append(proc)  # the MDAC's AC
        ctl.cams.register(number, proc)
        self.started(proc)
