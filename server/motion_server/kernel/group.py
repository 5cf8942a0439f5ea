"""Motion groups: a set of axes sharing a coarse update period, group stops, and the
controller's operating mode (leaving run mode stops every group).

A group stop watches every axis of its group each coarse update until all have come to
rest; it reads the shared status arrays (``busy``, ``after_stop``, the drive state and
actual velocity) for all of them at once, and touches an axis in Python only when it
comes to rest (to release its Stopping latch).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from .axis import Axis
from .config import GroupConfig
from .enums import AfterStop, AxisState, AxisType, MotionStatusBit, ProgrammedStopMode
from .state import AxisArrays

#: what follows the ramp of a fast programmed stop mode (the hard modes have no ramp)
AFTER_FAST_STOP: dict[ProgrammedStopMode, AfterStop] = {
    ProgrammedStopMode.FAST_STOP: AfterStop.NOTHING,
    ProgrammedStopMode.FAST_DISABLE: AfterStop.DISABLE,
    ProgrammedStopMode.FAST_SHUTDOWN: AfterStop.SHUTDOWN,
}


_STOPPING_BIT = 1 << MotionStatusBit.STOPPING


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


# read at every publish, as module constants (see .enums)
_NORMAL = GroupState.NORMAL
_STOPPING = GroupState.STOPPING


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
        #: array indices of the group's axes, of those that are not feedback only, and of
        #: its servo and virtual axes
        self.idx = np.array([a.index for a in axes], dtype=np.intp)
        self.motion_idx = np.array(
            [a.index for a in axes if a.type != AxisType.FEEDBACK_ONLY], dtype=np.intp
        )
        self.by_index = {a.index: a for a in axes}
        self.servo_idx = np.array(
            [a.index for a in axes if a.type == AxisType.SERVO], dtype=np.intp
        )
        self.virtual_idx = np.array(
            [a.index for a in axes if a.type == AxisType.VIRTUAL], dtype=np.intp
        )
        self.feedback_axes = [a for a in axes if a.type == AxisType.FEEDBACK_ONLY]
        self.order: list[Axis] = list(axes)
        #: the shared status arrays of the group's axes (None for a group without axes)
        self._s: AxisArrays | None = axes[0]._s if axes else None
        #: (AxisArrays.state_changes, Faulted / Shutdown / None) when last read
        self._power: tuple[int, GroupState | None] | None = None

    @property
    def state(self) -> GroupState:
        """Read from the status arrays (the scan publishes it every cycle): Python work
        only for the axes whose status changed since the arrays were last brought up to
        date (``AxisArrays.dirty``) and for those whose Stopping bit is set."""
        s = self._s
        if s is None:
            return (
                GroupState.STOPPING
                if any(not x.complete for x in self.stops)
                else (GroupState.NORMAL)
            )
        power = self._power
        if power is None or power[0] != s.state_changes:
            # Faulted / Shutdown: from the axis states, again only once one has changed
            motion = self.motion_idx
            if (s.axis_state[self.idx] == AxisState.AXIS_FAULTED).any():
                held: GroupState | None = GroupState.FAULTED
            elif motion.size and (s.axis_state[motion] == AxisState.AXIS_SHUTDOWN).all():
                held = GroupState.SHUTDOWN
            else:
                held = None
            power = self._power = (s.state_changes, held)
        if power[1] is not None:
            return power[1]
        if self.stops and any(not x.complete for x in self.stops):
            return _STOPPING
        # Axis.stopping is the MotionStatus Stopping bit (Axis.process_bits), current in
        # ``motion_bits`` for every axis not in ``dirty``
        dirty = s.dirty
        for i in dirty:
            ax = self.by_index.get(i)
            if ax is not None and ax.stopping:
                return _STOPPING
        stopping = s.motion_bits[self.idx] & _STOPPING_BIT
        if not dirty:
            return _STOPPING if stopping.any() else _NORMAL
        if any(int(i) not in dirty for i in self.idx[stopping != 0]):
            return _STOPPING
        return _NORMAL

    @property
    def time(self) -> float:
        return self.cycles * self.period


def moving(s: AxisArrays, idx: np.ndarray) -> np.ndarray:
    """``Axis.moving`` of the axes ``idx`` at once: an active process, or a drive that is
    off while the axis still turns."""
    return s.busy[idx] | (~s.drive_on[idx] & (s.act_vel[idx] != 0.0))


def at_standstill(s: AxisArrays, idx: np.ndarray, dt: float) -> np.ndarray:
    """The drives of ``idx`` have settled: less than one count per coarse update (a
    disable or shutdown after a fast stop waits for this, so the axis does not coast on
    the servo lag). Axes without a servo drive on are always settled."""
    return ~s.drive_on[idx] | ~s.servo_type[idx] | (np.abs(s.act_vel[idx]) * dt * s.cpu[idx] < 1.0)


def after_stops_due(s: AxisArrays, g: MotionGroup, dt: float) -> tuple[list[Axis], bool]:
    """The axes of ``g`` whose after-stop action (disable, shutdown) is due now (no active
    process, drive settled), in group order; and whether others still wait."""
    idx = g.idx[s.after_stop[g.idx] != AfterStop.NOTHING]
    if idx.size == 0:
        return [], False
    ready = ~s.busy[idx] & at_standstill(s, idx, dt)
    due = [g.by_index[int(i)] for i in idx[ready]]
    return due, bool(not ready.all())


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
        #: the axes (array indices) this stop may still hold in Stopping
        self._latched = group.motion_idx

    def update(self, s: AxisArrays) -> None:
        """Called after each coarse update of the group."""
        self.initiated = True
        if self.complete:
            return
        idx = self.group.motion_idx
        waiting = moving(s, idx) | (s.after_stop[idx] != AfterStop.NOTHING)
        latched = self._latched
        if latched.size:
            rest = ~(moving(s, latched) | (s.after_stop[latched] != AfterStop.NOTHING))
            if rest.any():
                by_index = self.group.by_index
                cleared = []
                for i in latched[rest].tolist():
                    a = by_index[i]
                    if a._stop_latch is self:
                        # this axis is at rest: StoppingStatus ends (``a.stop_latch = None``
                        # with the status marked stale once for all: a group comes to
                        # rest in one cycle)
                        a._stop_latch = None
                        cleared.append(i)
                s.dirty.update(cleared)
                self._latched = latched[~rest]
        self.complete = not waiting.any()
