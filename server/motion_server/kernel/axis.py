"""An axis: configuration, power state and its motion processes.

Positions, velocities and drive state live in the controller's numpy arrays (the hot
path touches every axis each cycle); :class:`Axis` reads them through ``index``. The
PLCopen state and the Logix MotionStatus bits are derived here from the power state and
the processes: they are never stored.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

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
from .processes import Process

if TYPE_CHECKING:
    from .controller import Controller, Pending


class Axis:
    def __init__(self, ctl: Controller, config: AxisConfig, index: int) -> None:
        self._ctl = ctl
        self.config = config
        self.index = index
        self.number = config.number
        self.name = config.name
        self.type = config.type
        self.state = AxisState.AXIS_READY
        self.fault = 0
        self.homed = False
        self.base = 0.0
        self.processes: list[Process] = []
        #: a buffered PLCopen process waiting for the active ones (factory, owner)
        self.buffered: Pending | None = None
        self.after_stop = AfterStop.NOTHING
        self.group: int = 0
        #: MC_Stop holds the axis in Stopping while its Execute stays high
        self.stop_latch: object | None = None
        self.feedback_input = 0.0

    # -- kinematic values (views into the controller arrays) ---------------------------------
    @property
    def command_position_unwound(self) -> float:
        return float(self._ctl.cmd_pos[self.index])

    @property
    def actual_position_unwound(self) -> float:
        return float(self._ctl.act_pos[self.index])

    @property
    def command_position(self) -> float:
        return self.wrap(self.command_position_unwound)

    @property
    def actual_position(self) -> float:
        return self.wrap(self.actual_position_unwound)

    @property
    def command_velocity(self) -> float:
        return float(self._ctl.cmd_vel[self.index])

    @property
    def command_acceleration(self) -> float:
        return float(self._ctl.cmd_acc[self.index])

    @property
    def actual_velocity(self) -> float:
        return float(self._ctl.act_vel[self.index])

    @property
    def position_error(self) -> float:
        return float(self._ctl.cmd_pos[self.index] - self._ctl.act_pos[self.index])

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
        return self.state == AxisState.SERVO_CONTROL

    @property
    def drive_enabled(self) -> bool:
        return self.servo_on and self.type != AxisType.FEEDBACK_ONLY

    def active(self, kind: ProcessKind | None = None) -> list[Process]:
        return [p for p in self.processes if p.active and (kind is None or p.kind == kind)]

    @property
    def stopping(self) -> bool:
        return self.stop_latch is not None or any(p.stopping for p in self.processes if p.active)

    @property
    def moving(self) -> bool:
        """Any commanded motion left (processes, or a coasting axis still turning)."""
        if any(p.active for p in self.processes):
            return True
        return not self.drive_enabled and self.actual_velocity != 0.0

    # -- derived status -------------------------------------------------------------------
    @property
    def motion_status(self) -> int:
        bits = 0
        v, a = self.command_velocity, self.command_acceleration
        if v * a > 0.0:
            bits |= 1 << MotionStatusBit.ACCEL
        elif v * a < 0.0:
            bits |= 1 << MotionStatusBit.DECEL
        for p in self.processes:
            if not p.active:
                continue
            if p.stopping:
                bits |= 1 << MotionStatusBit.STOPPING
            elif p.kind == ProcessKind.MOVE:
                bits |= 1 << MotionStatusBit.MOVE
            elif p.kind == ProcessKind.JOG:
                bits |= 1 << MotionStatusBit.JOG
            elif p.kind == ProcessKind.GEAR:
                bits |= 1 << MotionStatusBit.GEARING
                if getattr(p, "locked", False):
                    bits |= 1 << MotionStatusBit.GEARING_LOCK
        if self.stop_latch is not None:
            bits |= 1 << MotionStatusBit.STOPPING
        if self.homed:
            bits |= 1 << MotionStatusBit.HOMED
        return bits

    @property
    def plcopen_state(self) -> PLCopenState:
        if self.state == AxisState.AXIS_FAULTED:
            return PLCopenState.ERRORSTOP
        if self.state != AxisState.SERVO_CONTROL:
            return PLCopenState.DISABLED
        if self.stopping:
            return PLCopenState.STOPPING
        kinds = {p.kind for p in self.processes if p.active}
        if ProcessKind.GEAR in kinds:
            return PLCopenState.SYNCHRONIZED_MOTION
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
        return f"Axis({self.number}, {self.name!r}, {self.state.name})"
