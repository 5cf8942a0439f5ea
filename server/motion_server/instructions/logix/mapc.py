"""MAPC, Motion Axis Position Cam: the slave follows a cam profile of the master's position.

``MAPC(SlaveAxis, MasterAxis, MotionControl, Direction, CamProfile, SlaveScaling,
MasterScaling, ExecutionMode, ExecutionSchedule, MasterLockPosition, CamLockPosition,
CamType, MasterReference, MasterDirection)`` (MOTION-RM002). Incremental: after the lock
only the master's change of position since the lock counts,

    slave = slave at lock + D x SlaveScaling x (f(x) - f(CamLockPosition)),
    x = CamLockPosition + (master - master at lock) / MasterScaling

(D +1 Same, -1 Opposite; Reverse toggles the direction of the slave's previous cam,
Unchanged keeps it; a slave that never cammed counts as Same). Execution Mode Once (the
cam completes when the master leaves the profile's range: PC), Continuous (the profile
repeats, each pass adding its rise), Persistent (outside the range the slave holds,
unlocked, and follows again when the master comes back). Execution Schedule: Immediate
(locked at once), Forward only / Reverse only / Bi-directional (locked when the master
passes MasterLockPosition that way, in any turn of a rotary master), Pending (takes over
seamlessly when the running position cam completes or passes its profile's end; with no
cam running it is preloaded and follows the next MAPC; it ignores MasterAxis,
MasterLockPosition and MasterReference). MasterDirection Forward or Reverse only: the
slave follows that master direction only and stays where it was while the master goes
back (:mod:`motion_server.kernel.cams`). Position cams superimpose on the slave's other
motion (a jog, a move, a gear); a merge (MAJ/MAM with Merge) ends them.

Status: DN and IP in the scan of execution; IP until the cam completes (then PC), is
superseded (a Pending cam took over), stopped (MAS All or Position Cam, MGS), merged, shut
down or faulted; SEGMENT is the profile segment the cam is in (0-based).
MotionStatus: PositionCamStatus while the cam is in process (waiting for its lock
position too), PositionCamLockStatus while it is locked and driving the slave,
PositionCamPendingStatus while a Pending cam waits.

The CamType operand of RM002 is not modelled (profiles are all of one kind here).

Errors: 23 an Immediate or lock-position MAPC while the slave is position camming (use
Pending, or stop the cam first); 30 / 32 the profile is being calculated / not
calculated; 13 CamLockPosition outside the profile's master range, a scaling that is zero,
not finite or beyond +-2^31, a profile that does not exist (EXERR names the operand); 8 a
command reference to a feedback-only master, or a feedback-only slave; 10 master/slave
loop; 5, 7, 20 the slave's power state.
"""

from __future__ import annotations

from typing import ClassVar

from ...kernel import MasterReference, ProcessKind
from ...kernel.cams import (
    CamMode,
    CamProcess,
    LockDirection,
    MasterDirection,
    active_cam,
)
from ...kernel.errors import ErrorCode, MotionError
from ...kernel.gearing import check_master
from ..base import Gate, gate
from ..cam_common import ExecutionSchedule, calculated_profile, scaling, start_cam
from ..logix_common import ProcessInstruction
from ..operands import MASTER_AXIS, SLAVE_AXIS
from ..registry import register
from ..schema import Operand, Quantity, StatusField, TagType
from .mag import DIRECTION, GearDirection, resolve_direction
from .mccp import CAM_PROFILE

LOCKS = {
    ExecutionSchedule.IMMEDIATE: LockDirection.IMMEDIATE,
    ExecutionSchedule.PENDING: LockDirection.IMMEDIATE,
    ExecutionSchedule.FORWARD_ONLY: LockDirection.FORWARD,
    ExecutionSchedule.REVERSE_ONLY: LockDirection.REVERSE,
    ExecutionSchedule.BIDIRECTIONAL: LockDirection.BIDIRECTIONAL,
}

SEGMENT = StatusField("SEGMENT", TagType.DINT, "profile segment the cam is in (0-based)")


class CamInstruction(ProcessInstruction):
    """A Logix cam (MAPC, MATC): SEGMENT follows the cam while it is in process."""

    OUTPUTS = (SEGMENT,)

    def poll(self) -> None:
        p = self.process
        if isinstance(p, CamProcess) and p.active:
            if p.lane is not None:
                p.lane.sync(p)
            prof = p.profile
            x = p.x
            if p.mode == CamMode.CONTINUOUS:
                x -= p.k * prof.length
            self.outputs["SEGMENT"] = prof.segment(x)
        super().poll()


@register
class MAPC(CamInstruction):
    TYPE = "MAPC"
    DESCRIPTION = "Motion Axis Position Cam: the slave follows a cam of the master's position"
    MOTION_CONTROL_INDEX = 2
    GATES: ClassVar[dict[str, tuple[Gate, ...]]] = {
        "MasterLockPosition": (
            gate(
                "ExecutionSchedule",
                ExecutionSchedule.FORWARD_ONLY,
                ExecutionSchedule.REVERSE_ONLY,
                ExecutionSchedule.BIDIRECTIONAL,
            ),
        ),
    }
    OPERANDS = (
        SLAVE_AXIS,
        MASTER_AXIS,
        DIRECTION,
        CAM_PROFILE,
        Operand("SlaveScaling", TagType.REAL, 1.0, description="scales the slave values"),
        Operand("MasterScaling", TagType.REAL, 1.0, description="scales the master distance"),
        Operand(
            "ExecutionMode",
            TagType.DINT,
            CamMode.ONCE,
            enum=CamMode,
            description="0 once, 1 continuous, 2 persistent",
        ),
        Operand(
            "ExecutionSchedule",
            TagType.DINT,
            ExecutionSchedule.IMMEDIATE,
            enum=ExecutionSchedule,
            description="0 immediate, 1 pending, 2 forward only, 3 reverse only, 4 bi-directional",
        ),
        Operand(
            "MasterLockPosition",
            TagType.REAL,
            0.0,
            quantity=Quantity.POSITION,
            description="master position that locks the cam (master units)",
        ),
        Operand(
            "CamLockPosition", TagType.REAL, 0.0, description="profile master value at the lock"
        ),
        Operand(
            "MasterReference",
            TagType.DINT,
            MasterReference.ACTUAL,
            enum=MasterReference,
            description="0 actual, 1 command",
        ),
        Operand(
            "MasterDirection",
            TagType.DINT,
            MasterDirection.BIDIRECTIONAL,
            enum=MasterDirection,
            description="0 bi-directional, 1 forward only, 2 reverse only",
        ),
    )

    def execute(self) -> None:
        ctl = self.ctl
        slave = self.axis("SlaveAxis")
        master = self.axis("MasterAxis")
        ctl.require_motion(slave)
        schedule = ExecutionSchedule(int(self.op["ExecutionSchedule"]))
        number = int(self.op["CamProfile"])
        if number not in ctl.cams.slots:
            raise self.out_of_range("CamProfile", f"cam profile {number} does not exist")
        profile = calculated_profile(ctl, number)
        ss = scaling(self, "SlaveScaling")
        ms = scaling(self, "MasterScaling")
        cam_lock = float(self.op["CamLockPosition"])
        if not profile.start <= cam_lock <= profile.end:
            raise self.out_of_range(
                "CamLockPosition",
                f"CamLockPosition {cam_lock:g} is outside the profile's range "
                f"[{profile.start:g}, {profile.end:g}]",
            )
        pending = schedule == ExecutionSchedule.PENDING
        current = active_cam(slave, ProcessKind.POSITION_CAM)
        if current is not None and not pending:
            raise MotionError(
                ErrorCode.ILLEGAL_DYNAMIC_CHANGE,
                f"{slave.name} is position camming: use the Pending schedule or stop the cam",
            )
        source = MasterReference(int(self.op["MasterReference"]))
        if current is not None:
            master = ctl.axes[current.index] if current.index is not None else master
            source = current.source
        check_master(ctl, slave, master, source)
        direction = resolve_direction(GearDirection(int(self.op["Direction"])), slave.cam_direction)

        def build() -> CamProcess:
            return CamProcess(
                ctl,
                profile,
                CamMode(int(self.op["ExecutionMode"])),
                direction * ss,
                ms,
                cam_lock,
                master=master.index,
                source=source,
                master_number=master.number,
                lock=LOCKS[schedule],
                master_lock=float(self.op["MasterLockPosition"]),
                rollover=master.config.rollover,
                direction=MasterDirection(int(self.op["MasterDirection"])),
                owner=self,
            )

        proc = start_cam(ctl, slave, build, pending)
        slave.cam_direction = direction
        ctl.cams.register(number, proc)
        self.started(proc)
