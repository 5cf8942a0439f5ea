"""Motion groups: a set of axes sharing a coarse update period, and group stops."""

from __future__ import annotations

from enum import IntEnum
from typing import TYPE_CHECKING

import numpy as np

from .config import GroupConfig
from .enums import AfterStop, AxisState, AxisType

if TYPE_CHECKING:
    from .axis import Axis


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
    """Handle of a group stop in progress (MGS, leaving run mode): complete when every
    axis has come to rest and its after-stop action (disable, shutdown) has been applied."""

    def __init__(self, group: MotionGroup, owner: object = None) -> None:
        self.group = group
        self.owner = owner
        self.complete = False

    def update(self) -> None:
        if self.complete:
            return
        self.complete = all(
            not a.moving and a.after_stop == AfterStop.NOTHING
            for a in self.group.axes
            if a.type != AxisType.FEEDBACK_ONLY
        )
