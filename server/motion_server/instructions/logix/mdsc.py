"""Master Driven Speed Control: what MAJ and MAM share.

Both start their process time-driven (rates per second or % of maximum) or master-driven
(rates per master unit, after an MDAC names the slave's master). A master-driven start
may switch a pending MDAC reassignment, and is refused when the change of master would
leave the slave with an idle master (ERR 97) or under 5 % of its speed (ERR 103).
``TrackingMaster`` shows while the slave follows its master at the programmed speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from typing import ClassVar

from ...kernel import Axis, ErrorCode, Limits, MotionError, ProcessKind
from ...kernel.master_driven import MasterDrivenProcess
from ...kernel.mdac_links import MasterFactory
from ...kernel.processes import Process
from .. import dynamics
from ..base import Gate, gate
from ..dynamics import DriveMode, MergeMode, MergeSpeed, ProfileType
from ..logix_common import ProcessInstruction
from ..operands import TRACKING_MASTER
from ..schema import StatusField


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

    @property
    def merging(self) -> bool:
        return int(self.op["Merge"]) == MergeMode.ENABLED

    @property
    def merge_at_current_speed(self) -> bool:
        return self.merging and int(self.op["MergeSpeed"]) == MergeSpeed.CURRENT

    def plan(self, ax: Axis) -> tuple[DriveMode, float, Limits]:
        """Drive mode, programmed speed (units/s or units per master unit) and limits."""
        mode = dynamics.logix_drive_mode(self)
        speed = dynamics.speed(self, ax)
        if self.merge_at_current_speed and mode == DriveMode.TIME_DRIVEN:
            speed = abs(ax.command_velocity)
        limits = dynamics.logix_limits(self, ax, max(speed, 0.0))
        return mode, speed, limits

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
        self.outputs["TrackingMaster"] = False
        mdsc = self.ctl.mdsc
        if mode == DriveMode.MASTER_DRIVEN:
            # at the current speed the change of master cannot slow the slave down
            check = math.inf if self.merge_at_current_speed else speed
            p = mdsc.start_master_driven(ax, kind, check, make_master, replace)
        else:
            p = mdsc.start(ax, kind, make_time, replace)
        self.started(p)
        self._track()

    def poll(self) -> None:
        super().poll()
        self._track()

    def _track(self) -> None:
        p = self.process
        self.outputs["TrackingMaster"] = (
            isinstance(p, MasterDrivenProcess) and p.active and p.tracking
        )
