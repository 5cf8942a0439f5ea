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

Scanned by :func:`~..scan_pass.scan_pass`, the Immediate MAPC of one scan that follow
their master both ways, on slaves without a preloaded cam, start their cams in one
:func:`~...kernel.cam_batch.start_position_cams` call, with the results of executing them
one by one (``batch_job``); the others execute alone.

The CamType operand of RM002 is not modelled (profiles are all of one kind here).

Errors: 23 an Immediate or lock-position MAPC while the slave is position camming (use
Pending, or stop the cam first); 30 / 32 the profile is being calculated / not
calculated; 13 CamLockPosition outside the profile's master range, a scaling that is zero,
not finite or beyond +-2^31, a profile that does not exist (EXERR names the operand); 8 a
command reference to a feedback-only master, or a feedback-only slave; 10 master/slave
loop; 5, 7, 20 the slave's power state.
"""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple

from ...kernel import Axis, AxisType, MasterReference, ProcessKind
from ...kernel.cam_batch import CamStart
from ...kernel.cam_profile import CamProfile
from ...kernel.cams import (
    CamMode,
    CamProcess,
    LockDirection,
    MasterDirection,
    active_cam,
)
from ...kernel.errors import ErrorCode, MotionError
from ...kernel.gearing import check_master
from ...kernel.processes import Process
from ..base import Gate, gate
from ..cam_common import ExecutionSchedule, calculated_profile, scaling, start_cam
from ..logix_common import STARTED_ACTIVE, ProcessInstruction
from ..operands import MASTER_AXIS, SLAVE_AXIS
from ..registry import register
from ..scan_pass import Batch, BatchKind, takes_motion
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
    PARKS = False  # SEGMENT follows the cam every cycle

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

    #: rising edges in one scan (Immediate, master both ways, no cam preloaded on the
    #: slave) start their cams with one ``start_position_cams``
    BATCH = BatchKind.POSITION_CAM
    #: the plan of a command queued in a batch, until the batch started it
    _queued: _Plan | None = None

    def _plan(self) -> _Plan:
        """The checks of ``execute``, in its order, and what the cam is built from."""
        ctl = self.ctl
        slave = self.axis("SlaveAxis")
        master = self.axis("MasterAxis")
        if not takes_motion(slave):
            ctl.require_motion(slave)  # the kernel's refusal, with its error
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
        return _Plan(slave, master, schedule, number, profile, ss, ms, cam_lock, source, direction)

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the cam returned as a
        :class:`~...kernel.cam_batch.CamStart` for ``start_position_cams``; None (executed
        alone) for a schedule other than Immediate, a master direction other than both
        ways (the batch starts cams locked at once, following the master both ways) and
        a slave with a cam preloaded (it would follow the new one). A slave or master
        that a queued cam touches, or a master that follows a queued slave, hands the
        queue over first: the checks then see the cams queued before."""
        op = self.op
        if (
            int(op["ExecutionSchedule"]) != ExecutionSchedule.IMMEDIATE
            or int(op["MasterDirection"]) != MasterDirection.BIDIRECTIONAL
        ):
            return None
        s = int(op["SlaveAxis"])
        m = int(op["MasterAxis"])
        # one walk over the master/slave links: whether the cam closes a loop, whether
        # its master is a queued slave or follows one
        loops, reaches = batch.reaching(m, s)
        flushed = reaches or s in batch.axes
        if flushed:
            batch.flush()  # its checks see the cams queued before it (in full: ``_plan``)
        ctl = self.ctl
        slave = ctl.axis(s)
        if slave.preloaded_cams:
            return None
        # what the checks find from the values and the profile alone (the judge's key and
        # the profile the slot holds): worked out once per set of them in a scan pass
        memo = None
        values = None
        if key is not None and not flushed:
            slot = ctl.cams.slots.get(int(op["CamProfile"]))
            profile = None if slot is None else slot.profile
            if profile is not None:
                memo = (MAPC, key, id(profile))
                values = batch.plans.get(memo)
        if values is None:
            plan = self._plan()
            if memo is not None:
                batch.plans[memo] = (
                    plan.profile,
                    plan.ss,
                    plan.ms,
                    plan.cam_lock,
                    plan.source,
                    CamMode(int(op["ExecutionMode"])),
                    GearDirection(int(op["Direction"])),
                )
            mode = CamMode(int(op["ExecutionMode"]))
        else:
            # the checks of ``_plan`` in its order, those of the values known to pass
            profile, ss, ms, cam_lock, source, mode, selection = values
            master = ctl.axis(m)
            if not takes_motion(slave):
                ctl.require_motion(slave)
            if active_cam(slave, ProcessKind.POSITION_CAM) is not None:
                raise MotionError(
                    ErrorCode.ILLEGAL_DYNAMIC_CHANGE,
                    f"{slave.name} is position camming: use the Pending schedule or stop the cam",
                )
            if loops or (source == _COMMAND and master.type is _FEEDBACK_ONLY):
                check_master(ctl, slave, master, source)  # (it refuses: its error)
            direction = resolve_direction(selection, slave.cam_direction)
            plan = _Plan(
                slave,
                master,
                ExecutionSchedule.IMMEDIATE,
                int(op["CamProfile"]),
                profile,
                ss,
                ms,
                cam_lock,
                source,
                direction,
            )
        master = plan.master
        self._queued = plan
        start = CamStart(
            slave,
            master,
            plan.profile,
            mode,
            plan.direction * plan.ss,
            plan.ms,
            plan.cam_lock,
            plan.source,
            owner=self,
        )
        return start, (s, master.number)

    def batch_started(self, process: Process) -> None:
        plan = self._queued
        self._queued = None
        assert plan is not None and isinstance(process, CamProcess)
        # (the batch builds its cams with the lock position's default: an Immediate cam
        # never reads it, but it is the cam's state as ``execute`` leaves it)
        process.master_lock = float(self.op["MasterLockPosition"])
        plan.slave.cam_direction = plan.direction
        self.ctl.cams.register(plan.number, process)
        self.started_active(process, STARTED_ACTIVE)

    def batch_refused(self) -> None:
        """Nothing to undo: a refused cam changes nothing of its own."""
        self._queued = None

    def execute(self) -> None:
        ctl = self.ctl
        plan = self._plan()
        slave, master, schedule = plan.slave, plan.master, plan.schedule
        profile, ss, ms, cam_lock = plan.profile, plan.ss, plan.ms, plan.cam_lock
        source, direction = plan.source, plan.direction
        pending = schedule == ExecutionSchedule.PENDING

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
        ctl.cams.register(plan.number, proc)
        self.started(proc)


class _Plan(NamedTuple):
    """What MAPC's checks found: the axes, the profile and the cam's parameters."""

    slave: Axis
    master: Axis
    schedule: ExecutionSchedule
    number: int
    profile: CamProfile
    ss: float
    ms: float
    cam_lock: float
    source: MasterReference
    direction: int


_COMMAND = MasterReference.COMMAND
_FEEDBACK_ONLY = AxisType.FEEDBACK_ONLY
