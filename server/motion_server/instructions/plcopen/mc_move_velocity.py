"""MC_MoveVelocity: run at Velocity in Direction until another command takes over.

The block never completes: it stays Busy and Active while it controls the axis, and sets
InVelocity once the commanded velocity is reached. InVelocity is reset with the falling
edge of Execute (after being shown for at least one cycle), but the motion goes on.
CommandAborted when another aborting command (a move, MC_Stop, MC_Halt ...) takes over.
Velocity 0 is allowed: the axis ramps to rest and stays in ContinuousMotion.
Direction: positive 1, negative 3, current 4 (the direction the axis moves in when the
command starts; positive at rest). Shortest way (2) has no meaning here: ErrorID 13.

Blocks in the aborting modes, positive or negative, executed on many axes in the same
scan start their jogs in one ``Controller.start_jogs`` call (``replace=None``); the
others (buffered, current direction) execute alone.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any

from ...kernel import Controller, JogProcess
from ...kernel.processes import Process
from ..operands import AXIS, plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MotionBlock, follows_as
from ..registry import register
from ..scan_pass import Batch, BatchKind
from ..schema import Operand, Quantity, StatusField, TagType


class VelocityDirection(IntEnum):
    POSITIVE = 1
    NEGATIVE = 3
    CURRENT = 4


@register
class MC_MoveVelocity(MotionBlock):
    TYPE = "MC_MoveVelocity"
    DESCRIPTION = "Run at a velocity until another command takes over"
    DONE_ON_FINISH = False
    OPERANDS = (
        AXIS,
        Operand(
            "Velocity",
            TagType.LREAL,
            10.0,
            minimum=0.0,
            quantity=Quantity.VELOCITY,
            description="speed (>= 0); the sign comes from Direction",
        ),
        *plcopen_dynamics(with_velocity=False),
        Operand(
            "Direction",
            TagType.DINT,
            VelocityDirection.POSITIVE,
            enum=VelocityDirection,
            description="1 positive, 3 negative, 4 current",
        ),
        BUFFER_MODE,
    )
    OUTPUTS = (StatusField("InVelocity", TagType.BOOL, "the commanded velocity is reached"),)

    def __init__(self, name: str, ctl: Controller, defaults: dict[str, Any] | None = None) -> None:
        super().__init__(name, ctl, defaults)
        #: InVelocity was published: with Execute low it is reset at the next scan
        self._in_velocity_seen = False

    BATCH = BatchKind.VELOCITY

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the jog returned as (axis, signed
        velocity, limits) for ``Controller.start_jogs``; None for a buffered block or
        the current direction, which reads the velocity the jog inherits (it executes
        alone). Raises what ``execute`` raises before its command. The jog depends on
        the operands' values (``key``) and the axis's maxima only: blocks with the same
        values on axes with the same maxima work it out once (one target, the same
        object: ``start_jogs`` copies a jog from rest to it)."""
        ax = self.axis()
        number = ax.number
        batch.before_axis(number)
        self.check_axis(ax)
        cfg = ax.config
        memo = None
        if key is not None:
            memo = (MC_MoveVelocity, key, cfg.max_velocity, cfg.max_acceleration,
                    cfg.max_deceleration, cfg.max_jerk)  # fmt: skip
            planned = batch.plans.get(memo)
            if planned is not None:
                return (ax, *planned), (number,)
        speed = float(self.op["Velocity"])
        direction = VelocityDirection(int(self.op["Direction"]))
        limits = self.limits(speed or cfg.max_velocity)
        if direction == VelocityDirection.CURRENT or self.buffered():
            return None
        sign = -1.0 if direction == VelocityDirection.NEGATIVE else 1.0
        target = sign * speed
        if memo is not None and speed > 0.0:
            # (not a speed of zero: 0.0 and -0.0 are one key but give targets of two signs)
            batch.plans[memo] = (target, limits)
        return (ax, target, limits), (number,)

    def execute(self) -> None:
        ax = self.axis()
        self.check_axis(ax)
        speed = float(self.op["Velocity"])
        direction = VelocityDirection(int(self.op["Direction"]))
        limits = self.limits(speed or ax.config.max_velocity)
        dt = self.ctl.dt(ax)

        def make(v: float, a: float) -> Process:
            # the direction is judged when the command starts (a buffered one starts later)
            if direction == VelocityDirection.CURRENT:
                sign = -1.0 if v < 0.0 else 1.0
            else:
                sign = -1.0 if direction == VelocityDirection.NEGATIVE else 1.0
            return JogProcess(dt, sign * speed, limits, v, a, owner=self)

        self.begin(ax, make)

    def on_restart(self) -> None:
        self._in_velocity_seen = False

    #: InVelocity follows the jog's ``at_speed``: a parked block wakes when it falls
    PARKED_WATCH = "at_speed"

    def parked_on(self) -> Process | None:
        """The jog, once at speed with InVelocity as it stays (shown while Execute is
        high, reset when low): until the jog leaves its speed (a new speed, an
        override) or ends, or an operand is written, nothing changes."""
        p = self.running()
        if (
            not isinstance(p, JogProcess)
            or not p.at_speed
            or bool(self.outputs["InVelocity"]) != bool(self.inputs[self.TRIGGER])
            or not self._in_velocity_seen
            or not follows_as(type(self), MC_MoveVelocity)
        ):
            return None
        return p

    def update(self) -> None:
        super().update()
        if self.outputs["InVelocity"]:
            self._in_velocity_seen = True

    def publish_extra(self) -> None:
        p = self.process
        at_speed = self.outputs["Busy"] and isinstance(p, JogProcess) and p.active and p.at_speed
        held = bool(self.inputs[self.TRIGGER]) or not self._in_velocity_seen
        self.outputs["InVelocity"] = bool(at_speed and held)
