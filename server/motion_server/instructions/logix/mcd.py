"""MCD, Motion Change Dynamics: change the speed, acceleration, deceleration or jerk of the
jog or move in progress on an axis, on the fly.

The operands follow the Logix ST order (Axis, MotionControl, MotionType, ChangeSpeed,
Speed, ... JerkUnits), so EXERR numbers them as a Logix controller does. Each value is
applied, and judged, only when its Change selector is Yes. The active processes of the
selected kind are re-planned from their current state toward the same target (a move)
or the same direction (a jog); a move given speed 0 ramps to rest and waits, still in
process, until a later MCD gives it a speed again. Jerk changes apply to S-curve profiles
only (one jerk limit per profile: the smaller of the changed ones).

DN is set in the same scan. A feedback-only axis has no motion planner: ERR 8. An axis
with no jog (or move) in progress is left as it is and the instruction is done.
"""

from __future__ import annotations

from enum import IntEnum

from ...kernel import Axis, AxisType, ErrorCode, JogProcess, Limits, MotionError, MoveProcess
from ...kernel.enums import ProcessKind
from .. import dynamics
from ..base import Gate, LogixInstruction, gate
from ..dynamics import AccelUnits, JerkUnits, SpeedUnits
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, Quantity, TagType
from .mas import YesNo


class MotionType(IntEnum):
    JOG = 0
    MOVE = 1


MOTION_KINDS = {MotionType.JOG: ProcessKind.JOG, MotionType.MOVE: ProcessKind.MOVE}


def _change(name: str) -> Operand:
    return Operand(name, TagType.DINT, 0, enum=YesNo, description="0 no, 1 yes")


def _rate(name: str, quantity: Quantity) -> Operand:
    return Operand(name, TagType.REAL, 100.0, minimum=0.0, exclusive_min=True, quantity=quantity)


def _when_yes(*selectors: str) -> tuple[Gate, ...]:
    return tuple(gate(s, YesNo.YES) for s in selectors)


#: value operand -> the Change selectors that make it count (``Instruction.GATES``)
GATES: dict[str, tuple[Gate, ...]] = {
    "Speed": _when_yes("ChangeSpeed"),
    "SpeedUnits": _when_yes("ChangeSpeed"),
    "AccelRate": _when_yes("ChangeAccel"),
    "AccelUnits": _when_yes("ChangeAccel"),
    "DecelRate": _when_yes("ChangeDecel"),
    "DecelUnits": _when_yes("ChangeDecel"),
    "AccelJerk": _when_yes("ChangeAccelJerk"),
    "DecelJerk": _when_yes("ChangeDecelJerk"),
    "JerkUnits": _when_yes("ChangeAccelJerk", "ChangeDecelJerk"),
}


@register
class MCD(LogixInstruction):
    TYPE = "MCD"
    DESCRIPTION = "Motion Change Dynamics: new speed/accel/decel/jerk for a jog or move"
    OPERANDS = (
        AXIS,
        Operand("MotionType", TagType.DINT, 0, enum=MotionType, description="0 jog, 1 move"),
        _change("ChangeSpeed"),
        Operand("Speed", TagType.REAL, 10.0, minimum=0.0, quantity=Quantity.VELOCITY),
        _change("ChangeAccel"),
        _rate("AccelRate", Quantity.ACCELERATION),
        _change("ChangeDecel"),
        _rate("DecelRate", Quantity.ACCELERATION),
        _change("ChangeAccelJerk"),
        Operand("AccelJerk", TagType.REAL, 100.0, minimum=0.0, quantity=Quantity.JERK),
        _change("ChangeDecelJerk"),
        Operand("DecelJerk", TagType.REAL, 100.0, minimum=0.0, quantity=Quantity.JERK),
        Operand("SpeedUnits", TagType.DINT, 0, enum=SpeedUnits),
        Operand("AccelUnits", TagType.DINT, 0, enum=AccelUnits),
        Operand("DecelUnits", TagType.DINT, 0, enum=AccelUnits),
        Operand("JerkUnits", TagType.DINT, 2, enum=JerkUnits),
    )

    GATES = GATES

    def changes(self, selector: str) -> bool:
        return int(self.op[selector]) == YesNo.YES

    def execute(self) -> None:
        ax = self.axis()
        if ax.type == AxisType.FEEDBACK_ONLY:
            raise MotionError(ErrorCode.WRONG_AXIS_TYPE, f"{ax.name} has no motion planner")
        kind = MOTION_KINDS[MotionType(int(self.op["MotionType"]))]
        cfg = ax.config
        speed = dynamics.speed(self, ax) if self.changes("ChangeSpeed") else None
        acc = dec = None
        if self.changes("ChangeAccel"):
            acc = dynamics.rate(self, ax, "AccelRate", "AccelUnits", cfg.max_acceleration)
        if self.changes("ChangeDecel"):
            dec = dynamics.rate(self, ax, "DecelRate", "DecelUnits", cfg.max_deceleration)
        # plan every change first: a refused operand must leave all motion untouched
        plans: list[tuple[JogProcess | MoveProcess, Limits]] = []
        for p in ax.active(kind):
            if not isinstance(p, JogProcess | MoveProcess):
                continue
            lim = p.limits
            a = lim.acceleration if acc is None else acc
            d = lim.deceleration if dec is None else dec
            plans.append((p, Limits(lim.velocity, a, d, self._jerk(ax, lim, speed, a, d))))
        for p, limits in plans:
            p.change_dynamics(limits, speed)
        self.set_bits(DN=True)

    def _jerk(self, ax: Axis, lim: Limits, speed: float | None, acc: float, dec: float) -> float:
        """The profile's new jerk limit (S-curve profiles only; 0 stays trapezoidal)."""
        if lim.jerk == 0.0:
            return 0.0
        ref = speed or lim.velocity
        new = []
        if self.changes("ChangeAccelJerk"):
            new.append(dynamics.jerk(self, ax, "AccelJerk", ref, acc))
        if self.changes("ChangeDecelJerk"):
            new.append(dynamics.jerk(self, ax, "DecelJerk", ref, dec))
        return min(new) if new else lim.jerk
