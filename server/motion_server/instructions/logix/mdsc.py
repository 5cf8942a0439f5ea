"""Master Driven Speed Control: what MAJ and MAM share.

Both start their process time-driven (rates per second or % of maximum) or master-driven
(rates per master unit, after an MDAC names the slave's master). A master-driven start
may switch a pending MDAC reassignment, and is refused when the change of master would
leave the slave with an idle master (ERR 97) or under 5 % of its speed (ERR 103).
``TrackingMaster`` shows while the slave follows its master at the programmed speed.

Master-driven operands are judged before a profile is planned (ERR 13, EXERR naming the
operand): a Speed that would drive the slave beyond its maximum velocity when its master
runs at its own (Speed x master MaxVelocity > slave MaxVelocity: refused, not limited as
a time-driven speed is, since a master-driven speed is the coupling ratio the program
relies on), and rates or jerks so small (or a move so slow) that the profile would take
more than ``MAX_MASTER_TRAVEL`` of master travel (ruckig would raise on them).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from typing import ClassVar

from ...kernel import Axis, ErrorCode, Limits, MotionError, ProcessKind
from ...kernel.master_driven import (
    Dynamic,
    MasterDrivenProcess,
    MasterProfileError,
    judge_master_profile,
)
from ...kernel.mdac_links import MasterFactory
from ...kernel.processes import Process
from .. import dynamics
from ..base import Gate, OperandError, gate
from ..dynamics import (
    MASTER_UNITS,
    AccelUnits,
    DriveMode,
    MergeMode,
    MergeSpeed,
    ProfileType,
    SpeedUnits,
)
from ..judging import TABLE_SIZE
from ..logix_common import ProcessInstruction
from ..operands import TRACKING_MASTER
from ..scan_pass import Batch, takes_motion
from ..schema import StatusField

#: the operand that gives each master-driven quantity (jerk: the smaller jerk operand)
OPERAND_OF: dict[Dynamic, str] = {
    Dynamic.SPEED: "Speed",
    Dynamic.ACCELERATION: "AccelRate",
    Dynamic.DECELERATION: "DecelRate",
    Dynamic.DISTANCE: "Position",
}
#: the units selectors of a time-driven rate (per second, % of maximum)
_TIME_UNITS = frozenset(int(u) for u in (*SpeedUnits, *AccelUnits) if int(u) != MASTER_UNITS)
#: the selector and mode values the trapezoidal plan compares with, as plain ints
_PERCENT = int(SpeedUnits.PERCENT_OF_MAXIMUM)
_ACCEL_PERCENT = int(AccelUnits.PERCENT_OF_MAXIMUM)
_MERGE = int(MergeMode.ENABLED)
_AT_CURRENT = int(MergeSpeed.CURRENT)
_S_CURVE = int(ProfileType.S_CURVE)
_TIME_DRIVEN = DriveMode.TIME_DRIVEN
#: trapezoidal limits by (speed, acceleration, deceleration): a Limits is immutable, so
#: the instances that plan the same dynamics share one (bounded as the operand verdicts)
_LIMITS: dict[tuple[float, float, float], Limits] = {}
#: the TrackingMaster output as a process starts (see :meth:`launch`)
_TRACKING: dict[str, bool] = {"TrackingMaster": True}
_NOT_TRACKING: dict[str, bool] = {"TrackingMaster": False}
#: relative resolution of the Speed x master maximum comparison (REAL operands)
SPEED_TOLERANCE = 1e-6


class SpeedControlledMotion(ProcessInstruction):
    """A Logix single-axis motion (MAJ, MAM) that can run time- or master-driven.

    The jerk operands count only for an S-curve profile, MergeSpeed only with Merge
    enabled (``GATES``: not judged otherwise)."""

    OUTPUTS: ClassVar[tuple[StatusField, ...]] = (TRACKING_MASTER,)
    GATES: ClassVar[dict[str, tuple[Gate, ...]]] = {
        "AccelJerk": (gate("Profile", ProfileType.S_CURVE),),
        "DecelJerk": (gate("Profile", ProfileType.S_CURVE),),
        "JerkUnits": (gate("Profile", ProfileType.S_CURVE),),
        "MergeSpeed": (gate("Merge", MergeMode.ENABLED),),
    }

    def check_axis(self, ax: Axis) -> None:
        """Motion preconditions; new motion waits until a group stop has finished."""
        self.ctl.require_motion(ax)
        if self.ctl.group_stopping(ax):
            raise MotionError(
                ErrorCode.NOT_ALLOWED_WHILE_STOPPING,
                f"the group of {ax.name} is stopping (MGS): motion is refused until it is done",
            )

    def batch_axis(self, batch: Batch) -> Axis | None:
        """The axis of a rising edge that may join ``batch`` (its queue handed over
        first if a queued command touches the axis), checked as :meth:`check_axis`
        checks it but in full only where it refuses (the kernel's error): an axis in a
        state that takes motion, in a group not stopping (known once per group until
        the batch is handed over), passes; None under a pending MDAC switch (the
        instruction executes alone)."""
        ax = self.ctl.axis(int(self.op["Axis"]))
        number = ax.number
        batch.before_axis(number)
        if self.ctl.mdsc.pending(number) is not None:
            return None
        if not takes_motion(ax):
            self.check_axis(ax)  # the kernel's refusal, with its error
        else:
            stopping = batch.stopping.get(ax.group)
            if stopping is None:
                stopping = batch.stopping[ax.group] = self.ctl.group_stopping(ax)
            if stopping:
                self.check_axis(ax)
        return ax

    @property
    def merging(self) -> bool:
        return int(self.op["Merge"]) == MergeMode.ENABLED

    @property
    def merge_at_current_speed(self) -> bool:
        return self.merging and int(self.op["MergeSpeed"]) == MergeSpeed.CURRENT

    def plan(self, ax: Axis) -> tuple[DriveMode, float, Limits]:
        """Drive mode, programmed speed (units/s or units per master unit) and limits."""
        op = self.op
        if (
            int(op["Profile"]) != _S_CURVE
            and int(op["SpeedUnits"]) in _TIME_UNITS
            and int(op["AccelUnits"]) in _TIME_UNITS
            and int(op["DecelUnits"]) in _TIME_UNITS
        ):
            return self._plan_trapezoidal(ax)
        return self.plan_general(ax)

    def plan_general(self, ax: Axis) -> tuple[DriveMode, float, Limits]:
        """:meth:`plan` for any units and profile (the reference of the trapezoidal
        path in the tests)."""
        mode = dynamics.logix_drive_mode(self)
        speed = dynamics.speed(self, ax)
        if self.merge_at_current_speed and mode == DriveMode.TIME_DRIVEN:
            speed = abs(ax.command_velocity)
        limits = dynamics.logix_limits(self, ax, max(speed, 0.0))
        return mode, speed, limits

    def _plan_trapezoidal(self, ax: Axis) -> tuple[DriveMode, float, Limits]:
        """:meth:`plan` for the common case, in one pass over the operands: a trapezoidal
        profile, every rate per second or in % of maximum (time-driven). The same
        arithmetic and the same errors in the same order as the general path."""
        op = self.op
        cfg = ax.config
        top = cfg.max_velocity
        speed = float(op["Speed"])
        if int(op["SpeedUnits"]) == _PERCENT:
            speed = speed / 100.0 * top
        speed = min(speed, top)  # limited to the axis Maximum Speed
        if int(op["Merge"]) == _MERGE and int(op["MergeSpeed"]) == _AT_CURRENT:
            speed = abs(ax.command_velocity)
        acc = float(op["AccelRate"])
        if int(op["AccelUnits"]) == _ACCEL_PERCENT:
            acc = acc / 100.0 * cfg.max_acceleration
        if acc <= 0.0:
            raise self.out_of_range("AccelRate", "AccelRate must be > 0")
        dec = float(op["DecelRate"])
        if int(op["DecelUnits"]) == _ACCEL_PERCENT:
            dec = dec / 100.0 * cfg.max_deceleration
        if dec <= 0.0:
            raise self.out_of_range("DecelRate", "DecelRate must be > 0")
        if speed > 0.0:  # (never -0.0 or NaN: equal keys are the same numbers)
            key = (speed, acc, dec)
            limits = _LIMITS.get(key)
            if limits is None:
                if len(_LIMITS) >= TABLE_SIZE:
                    _LIMITS.clear()
                limits = _LIMITS[key] = Limits(speed, acc, dec, 0.0)
        else:
            limits = Limits(max(speed, 0.0), acc, dec, 0.0)
        return _TIME_DRIVEN, speed, limits

    def judge_master_driven(
        self,
        slave: Axis,
        master: Axis,
        speed: float,
        limits: Limits,
        ratio: float,
        distance: float | None = None,
    ) -> None:
        """Judge a master-driven start against ``master`` (see the module docstring):
        the profile from the inherited ``ratio`` and, for a jog, its way back to rest."""
        top = slave.config.max_velocity
        if abs(speed) * master.config.max_velocity > top * (1.0 + SPEED_TOLERANCE):
            raise self.out_of_range(
                "Speed",
                f"Speed {speed:g} per master unit drives {slave.name} beyond its maximum "
                f"velocity {top:g} when {master.name} runs at its "
                f"{master.config.max_velocity:g}",
            )
        try:
            if distance is None:
                judge_master_profile(limits, ratio, speed, None)
                judge_master_profile(limits, speed, 0.0, None)  # stopping it later
            else:
                judge_master_profile(limits, ratio, None, distance)
        except MasterProfileError as exc:
            raise self._operand_of(exc) from None

    def _operand_of(self, exc: MasterProfileError) -> OperandError:
        if exc.quantity == Dynamic.JERK:
            accel_jerk = float(self.op["AccelJerk"]) <= float(self.op["DecelJerk"])
            name = "AccelJerk" if accel_jerk else "DecelJerk"
        else:
            name = OPERAND_OF[exc.quantity]
        return self.out_of_range(name, str(exc))

    def launch(
        self,
        ax: Axis,
        kind: ProcessKind,
        mode: DriveMode,
        speed: float,
        make_time: Callable[[float, float], Process],
        make_master: MasterFactory,
        replace: Collection[ProcessKind] | None,
    ) -> None:
        """Start the process (through the MDSC assignments) and follow it."""
        mdsc = self.ctl.mdsc
        try:
            if mode == DriveMode.MASTER_DRIVEN:
                # at the current speed the change of master cannot slow the slave down
                check = math.inf if self.merge_at_current_speed else speed
                p = mdsc.start_master_driven(ax, kind, check, make_master, replace)
            else:
                p = mdsc.start(ax, kind, make_time, replace)
        except BaseException:
            self.outputs["TrackingMaster"] = False  # a refused start tracks nothing
            raise
        self.started(p, tracking_status(p))

    def parked_on(self) -> Process | None:
        """As a process instruction's, for a time-driven process only (a master-driven
        one's TrackingMaster changes while it runs)."""
        p = super().parked_on()
        if p is None or isinstance(p, MasterDrivenProcess) or self.outputs["TrackingMaster"]:
            return None
        return p

    def poll(self) -> None:
        super().poll()
        self._track()

    def _track(self) -> None:
        self.outputs["TrackingMaster"] = self._tracking(self.process)

    @staticmethod
    def _tracking(p: Process | None) -> bool:
        return isinstance(p, MasterDrivenProcess) and p.active and p.tracking


def tracking_status(p: Process) -> dict[str, bool]:
    """The TrackingMaster output as process ``p`` starts (shared, not to be changed)."""
    tracking = isinstance(p, MasterDrivenProcess) and p.active and p.tracking
    return _TRACKING if tracking else _NOT_TRACKING
