"""Motion groups: a set of axes sharing a coarse update period, group stops, and the
controller's operating mode (leaving run mode stops every group)."""

from __future__ import annotations

from enum import IntEnum
from typing import TYPE_CHECKING

import numpy as np

from .config import GroupConfig
from .enums import AfterStop, AxisState, AxisType, ProgrammedStopMode

if TYPE_CHECKING:
    from .axis import Axis


#: what follows the ramp of a fast programmed stop mode (the hard modes have no ramp)
AFTER_FAST_STOP: dict[ProgrammedStopMode, AfterStop] = {
    ProgrammedStopMode.FAST_STOP: AfterStop.NOTHING,
    ProgrammedStopMode.FAST_DISABLE: AfterStop.DISABLE,
    ProgrammedStopMode.FAST_SHUTDOWN: AfterStop.SHUTDOWN,
}


class OperatingMode(IntEnum):
    """The controller's operating mode. Leaving RUN runs the programmed stop of every
    group (as a Logix controller does on Run -> Program) and breaks every MDAC link;
    in PROGRAM mode instructions are not executed."""

    PROGRAM = 0
    RUN = 1


class GroupState(IntEnum):
    """Derived state of a group, as published in ``GroupN.GroupState``."""

    NORMAL = 0
    STOPPING = 1
    SHUTDOWN = 2
    FAULTED = 3


class MotionGroup:
    def __init__(self, config: GroupConfig, axes: list[Axis], every: int) -> None:
        self.config = config
        self.number = config.number
        self.name = config.name
        self.period = config.coarse_update_period
        #: the group steps once every ``every`` controller ticks
        self.every = every
        self.axes = axes
        self.cycles = 0
        self.stops: list[GroupStop] = []
        #: some axis has an after-stop action (disable, shutdown) waiting for rest
        self.after_stops = False
        self.servo_idx = np.array(
            [a.index for a in axes if a.type == AxisType.SERVO], dtype=np.intp
        )
        self.virtual_idx = np.array(
            [a.index for a in axes if a.type == AxisType.VIRTUAL], dtype=np.intp
        )
        self.feedback_axes = [a for a in axes if a.type == AxisType.FEEDBACK_ONLY]
        self.order: list[Axis] = list(axes)

    @property
    def state(self) -> GroupState:
        if any(a.state == AxisState.AXIS_FAULTED for a in self.axes):
            return GroupState.FAULTED
        motion_axes = [a for a in self.axes if a.type != AxisType.FEEDBACK_ONLY]
        if motion_axes and all(a.state == AxisState.AXIS_SHUTDOWN for a in motion_axes):
            return GroupState.SHUTDOWN
        if any(not s.complete for s in self.stops) or any(a.stopping for a in self.axes):
            return GroupState.STOPPING
        return GroupState.NORMAL

    @property
    def time(self) -> float:
        return self.cycles * self.period


class GroupStop:
    """Handle of a group stop in progress (MGS, leaving run mode).

    ``initiated`` once the group's next coarse update has applied the stop to every axis
    (MGS DN); ``complete`` when every axis has come to rest and its after-stop action
    (disable, shutdown) has been applied (MGS PC).
    """

    def __init__(self, group: MotionGroup, owner: object = None) -> None:
        self.group = group
        self.owner = owner
        self.initiated = False
        self.complete = False

    def update(self) -> None:
        """Called after each coarse update of the group."""
        self.initiated = True
        if self.complete:
            return
        done = True
        for a in self.group.axes:
            if a.type == AxisType.FEEDBACK_ONLY:
                continue
            if a.moving or a.after_stop != AfterStop.NOTHING:
                done = False
            elif a.stop_latch is self:
                a.stop_latch = None  # this axis is at rest: StoppingStatus ends
        self.complete = done
