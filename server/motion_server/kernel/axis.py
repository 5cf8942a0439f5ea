"""An axis: configuration, power state and its motion processes.

Positions, velocities and drive state live in the shared :class:`~.state.AxisArrays`
(the hot path touches every axis each cycle); :class:`Axis` reads them through ``index``.
The PLCopen state and the Logix MotionStatus bits are derived here from the power state and
the processes: they are never stored as the truth. The status arrays published by the
front-ends are caches of these derivations: every attribute that feeds them marks the
axis ``dirty`` when it changes (the kernel marks it when its processes change), so
:meth:`Controller.status_arrays <.controller.Controller.status_arrays>` re-derives only
those axes.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from .config import AxisConfig
from .enums import (
    AfterStop,
    AxisState,
    AxisType,
    MotionStatusBit,
    PLCopenState,
    ProcessKind,
    ProgrammedStopMode,
)
from .override import NEUTRAL, Override
from .processes import Pending, Process
from .state import AxisArrays

_ACCEL = 1 << MotionStatusBit.ACCEL
_DECEL = 1 << MotionStatusBit.DECEL
_BITS: dict[ProcessKind, int] = {
    ProcessKind.MOVE: 1 << MotionStatusBit.MOVE,
    ProcessKind.JOG: 1 << MotionStatusBit.JOG,
    ProcessKind.GEAR: 1 << MotionStatusBit.GEARING,
    ProcessKind.HOME: 1 << MotionStatusBit.HOMING,
    ProcessKind.POSITION_CAM: 1 << MotionStatusBit.POSITION_CAM,
    ProcessKind.TIME_CAM: 1 << MotionStatusBit.TIME_CAM,
}
#: the lock bit of a following process (``locked``): gear, position cam, time cam
_LOCK_BITS: dict[ProcessKind, int] = {
    ProcessKind.GEAR: 1 << MotionStatusBit.GEARING_LOCK,
    ProcessKind.POSITION_CAM: 1 << MotionStatusBit.POSITION_CAM_LOCK,
    ProcessKind.TIME_CAM: 1 << MotionStatusBit.TIME_CAM_LOCK,
}
#: the pending bit of a cam waiting to take over (``successor``) or preloaded
_PENDING_BITS: dict[ProcessKind, int] = {
    ProcessKind.POSITION_CAM: 1 << MotionStatusBit.POSITION_CAM_PENDING,
    ProcessKind.TIME_CAM: 1 << MotionStatusBit.TIME_CAM_PENDING,
}
_HOMING = 1 << MotionStatusBit.HOMING


class StopRowsLike(Protocol):
    """What an axis asks of the stop rows holding its ramp (:mod:`.lanes.stop_rows`)."""

    def materialise(self, ax: Axis) -> None:
        """Make the axis's ramp object and give the axis its processes."""


class Axis:
    def __init__(self, arrays: AxisArrays, config: AxisConfig, index: int) -> None:
        self._s = arrays
        #: the configuration commands are judged against: the site map's, with the
        #: application maxima a program may lower (:mod:`.appl_limits`)
        self.config = config
        #: the site map's configuration, as loaded (the system maxima)
        self.system_config = config
        self.index = index
        self.number = config.number
        self.name = config.name
        self.type = config.type
        self._state = AxisState.AXIS_READY
        #: the PowerEvent (as int) that last changed the power state, -1 before any
        #: (:mod:`.power`; MC_Power re-enables after a reset, not after a disable)
        self.power_event = -1
        self._homed = False
        self._stop_latch: object | None = None
        self._after_stop = AfterStop.NOTHING
        self.base = 0.0
        self._processes: list[Process] = []
        #: the stop rows (:class:`~.lanes.stop_rows.StopRows`) holding this axis's group
        #: stop ramp as arrays, its object not made yet; reading :attr:`processes` makes it
        self.stop_rows: StopRowsLike | None = None
        #: a buffered PLCopen process waiting for the active ones (factory, owner)
        self.buffered: Pending | None = None
        self.group: int = 0
        #: coarse update period of the axis's group (s)
        self.period: float = 0.0
        self.feedback_input = 0.0
        #: +1 (same) or -1 (opposite): the direction of the latest gear started on this
        #: slave; MAG Reverse and Unchanged act relative to it (+1 if never geared)
        self.gear_direction = 1
        #: what a redefinition added to the raw feedback: the axis reads raw + offset
        #: (:mod:`.redefine`; the homing sensors sit in raw coordinates, :mod:`.sensors`)
        self.position_offset = 0.0
        self._homing_armed: object | None = None
        #: factors scaling the axis's moves and jogs (MC_SetOverride, :mod:`.override`)
        self.override: Override = NEUTRAL
        #: the following error limit (PLCopen MaxPositionLag) and whether it is monitored
        #: (EnablePosLagMonitoring): the drive watches ``lag_limit`` only while
        #: ``lag_monitoring`` (``AxisArrays.fe_limit`` holds what it watches, 0: nothing)
        self.lag_limit = float(config.following_error_limit)
        self.lag_monitoring = True
        #: cams started with the Pending schedule while no cam of their kind ran: they
        #: wait here, moving nothing, for the next cam of their kind to follow (Logix
        #: "preload"); a stop of all motion or of their kind ends them
        self.preloaded_cams: list[Process] = []
        #: +1 (same) or -1 (opposite): the direction of the latest cam of this slave (MAPC
        #: and MATC Reverse and Unchanged act on it; +1 if it never cammed)
        self.cam_direction = 1

    def __setstate__(self, state: dict[str, Any]) -> None:
        # state saved before ``processes`` became a property kept it under that name
        if "processes" in state:
            state["_processes"] = state.pop("processes")
        state.setdefault("stop_rows", None)
        self.__dict__.update(state)

    @property
    def processes(self) -> list[Process]:
        """The axis's motion processes, in the order they compose. A group stop planned
        as arrays leaves its ramp as a row of the stop lane (``stop_rows``): the ramp's
        object is made here, the first time anything reads the processes."""
        if self.stop_rows is not None:
            self.stop_rows.materialise(self)
        return self._processes

    @processes.setter
    def processes(self, value: list[Process]) -> None:
        if self.stop_rows is not None:
            self.stop_rows.materialise(self)
        self._processes = value

    # -- status attributes (each keeps the shared status arrays current) ---------------------
    @property
    def state(self) -> AxisState:
        """Logix AxisState (the power state; changed through :mod:`.power`)."""
        return self._state

    @state.setter
    def state(self, value: AxisState) -> None:
        self._state = value
        s = self._s
        s.axis_state[self.index] = int(value)
        s.dirty.add(self.index)
        s.state_changes += 1

    @property
    def fault(self) -> int:
        """AxisFault bits."""
        return int(self._s.fault[self.index])

    @fault.setter
    def fault(self, bits: int) -> None:
        s = self._s
        s.fault[self.index] = int(bits)
        s.fault_changes += 1
        s.dirty.add(self.index)  # PLCopenState: ErrorStop in Servo Control

    @property
    def homed(self) -> bool:
        return self._homed

    @homed.setter
    def homed(self, value: bool) -> None:
        self._homed = bool(value)
        self._s.dirty.add(self.index)

    @property
    def homing_armed(self) -> object | None:
        """The passive homing waiting for its home event on this axis (HomingStatus
        while it waits), or None."""
        return self._homing_armed

    @homing_armed.setter
    def homing_armed(self, watch: object | None) -> None:
        self._homing_armed = watch
        self._s.dirty.add(self.index)

    @property
    def stop_latch(self) -> object | None:
        """Who holds the axis in Stopping while it is at rest (MC_Stop with Execute high,
        a group stop until the axis has stopped), or None."""
        return self._stop_latch

    @stop_latch.setter
    def stop_latch(self, holder: object | None) -> None:
        self._stop_latch = holder
        self._s.dirty.add(self.index)

    @property
    def after_stop(self) -> AfterStop:
        """What happens to the power state once the axis has come to rest."""
        return self._after_stop

    @after_stop.setter
    def after_stop(self, action: AfterStop) -> None:
        self._after_stop = action
        self._s.after_stop[self.index] = int(action)

    def motion_changed(self, busy: bool | None = None) -> None:
        """The kernel changed this axis's processes (or stepped them in Python); ``busy``
        when the caller knows whether one is active."""
        s = self._s
        if busy is None:
            busy = any(p.active for p in self.processes)
        s.scalars.busy[self.index] = busy
        s.dirty.add(self.index)

    # -- kinematic values (views into the shared arrays) -----------------------------------
    @property
    def command_position_unwound(self) -> float:
        return float(self._s.cmd_pos[self.index])

    @property
    def actual_position_unwound(self) -> float:
        return float(self._s.act_pos[self.index])

    @property
    def command_position(self) -> float:
        return self.wrap(self.command_position_unwound)

    @property
    def actual_position(self) -> float:
        return self.wrap(self.actual_position_unwound)

    @property
    def command_velocity(self) -> float:
        return float(self._s.cmd_vel[self.index])

    @property
    def command_acceleration(self) -> float:
        return float(self._s.cmd_acc[self.index])

    @property
    def actual_velocity(self) -> float:
        return float(self._s.act_vel[self.index])

    @property
    def position_error(self) -> float:
        return float(self._s.cmd_pos[self.index] - self._s.act_pos[self.index])

    def unwound_target(self, target: float, near: float) -> float:
        """The unwound position that reads ``target``: on a rotary axis, in the turn
        nearest the unwound position ``near``."""
        r = self.config.rollover
        if r <= 0.0:
            return target
        return target + round((near - target) / r) * r

    def wrap(self, position: float) -> float:
        r = self.config.rollover
        if r > 0.0:
            w = math.fmod(position, r)
            return w + r if w < 0.0 else w
        return position

    # -- power state ----------------------------------------------------------------------
    @property
    def servo_on(self) -> bool:
        return self._state == AxisState.SERVO_CONTROL

    @property
    def drive_enabled(self) -> bool:
        return self.servo_on and self.type != AxisType.FEEDBACK_ONLY

    def active(self, kind: ProcessKind | None = None) -> list[Process]:
        return [p for p in self.processes if p.active and (kind is None or p.kind == kind)]

    @property
    def stopping(self) -> bool:
        return self._stop_latch is not None or any(p.stopping for p in self.processes if p.active)

    @property
    def moving(self) -> bool:
        """Any commanded motion left (processes, or a coasting axis still turning)."""
        if any(p.active for p in self.processes):
            return True
        return not self.drive_enabled and self.actual_velocity != 0.0

    # -- derived status -------------------------------------------------------------------
    def process_bits(self) -> int:
        """The MotionStatus bits that do not depend on the acceleration: the processes',
        the Stopping latch's and Homed."""
        bits = 0
        if self.stop_rows is not None:
            # a ramp still in the stop lane's rows: active and stopping (not made for this)
            bits |= 1 << MotionStatusBit.STOPPING
        for p in self._processes if self.stop_rows is None else ():
            if not p.active:
                continue
            if p.stopping:
                bits |= 1 << MotionStatusBit.STOPPING
            elif p.kind in _BITS:
                kind = p.kind
                bits |= _BITS[kind]
                if kind in _LOCK_BITS and getattr(p, "locked", False):
                    bits |= _LOCK_BITS[kind]
                if kind in _PENDING_BITS and getattr(p, "successor", None) is not None:
                    bits |= _PENDING_BITS[kind]
        for p in self.preloaded_cams:
            if p.active:
                bits |= _PENDING_BITS[p.kind]
        if self._stop_latch is not None:
            bits |= 1 << MotionStatusBit.STOPPING
        if self._homed:
            bits |= 1 << MotionStatusBit.HOMED
        if self._homing_armed is not None:
            bits |= _HOMING
        return bits

    @property
    def motion_status(self) -> int:
        bits = self.process_bits()
        v, a = self.command_velocity, self.command_acceleration
        if v * a > 0.0:
            bits |= _ACCEL
        elif v * a < 0.0:
            bits |= _DECEL
        return bits

    @property
    def plcopen_state(self) -> PLCopenState:
        if self._state == AxisState.AXIS_FAULTED:
            return PLCopenState.ERRORSTOP
        if self._state != AxisState.SERVO_CONTROL:
            return PLCopenState.DISABLED
        if self.fault:
            # a fault whose action keeps the drive on (an overtravel: Stop Planner)
            return PLCopenState.ERRORSTOP
        if self.stopping:
            return PLCopenState.STOPPING
        kinds = {p.kind for p in self.processes if p.active}
        if ProcessKind.HOME in kinds:
            return PLCopenState.HOMING
        if ProcessKind.GEAR in kinds or ProcessKind.POSITION_CAM in kinds:
            return PLCopenState.SYNCHRONIZED_MOTION
        if ProcessKind.TIME_CAM in kinds:
            return PLCopenState.CONTINUOUS_MOTION
        if ProcessKind.JOG in kinds:
            return PLCopenState.CONTINUOUS_MOTION
        if ProcessKind.MOVE in kinds or ProcessKind.STOP in kinds:
            # a ramp that is not a stop (MC_Halt) is discrete motion until at rest
            return PLCopenState.DISCRETE_MOTION
        return PLCopenState.STANDSTILL

    @property
    def programmed_stop_mode(self) -> ProgrammedStopMode:
        return self.config.programmed_stop_mode

    def __repr__(self) -> str:
        return f"Axis({self.number}, {self.name!r}, {self._state.name})"


def latch_stops(
    s: AxisArrays, axes: list[Axis], idx: np.ndarray, actions: list[AfterStop], holder: object
) -> None:
    """``ax.after_stop = action`` and ``ax.stop_latch = holder`` for every axis of
    ``axes`` (array indices ``idx``) and its action, the status arrays written once for
    all (a group stop's axes)."""
    if not actions:
        return
    first = actions[0]
    if actions.count(first) == len(actions):
        # one action for all (a forced stop mode, or one programmed for every axis): the
        # array takes it as one value, not as a list of enum members to convert
        for ax in axes:
            ax._after_stop = first
            ax._stop_latch = holder
        s.after_stop[idx] = int(first)
    else:
        for ax, action in zip(axes, actions, strict=True):
            ax._after_stop = action
            ax._stop_latch = holder
        s.after_stop[idx] = actions
    s.dirty.update(idx.tolist())
