"""The PLCopen axis parameters (Part 1, MC_ReadParameter / MC_WriteParameter) as our axes
hold them: number, type, how to read it, and for the one that can be written, how.

The numbers are PLCopen's (TwinCAT MC_AxisParameter and CODESYS SM3_Basic use the same
1-17). What our axes have:

- 1 CommandedPosition, 10 ActualVelocity, 11 CommandedVelocity: as the axis tags show
  them after the cycle;
- 6 EnablePosLagMonitoring (BOOL): the following error is monitored (switched on and a
  limit above 0); writable (MC_WriteBoolParameter): FALSE switches the monitoring off
  and keeps the limit, TRUE switches it on again (refused while the limit is 0);
  7 MaxPositionLag: that limit (site map ``following_error_limit``), writable
  (MC_WriteParameter): a value >= 0, 0 turning the monitoring off; both effective from
  the next cycle;
- 8 / 9 MaxVelocity, 12 / 13 MaxAcceleration, 14 / 15 MaxDeceleration, 16 / 17 MaxJerk
  (0: unlimited): the axis's maxima; an axis here has one limit, so System and Appl read
  the same value;
- 4 / 5 EnableLimitPos / EnableLimitNeg (BOOL): FALSE, the simulated axes have no
  software limits; 2 / 3 SWLimitPos / SWLimitNeg: none to read (ErrorID 13).

A number that is not in the table, a BOOL parameter read as a number or the other way
round, and a write to a read-only parameter are refused with ErrorID 13 naming the
ParameterNumber operand.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from ...kernel import Axis, Controller, ErrorCode, MotionError


class MCAxisParameter(IntEnum):
    """PLCopen Part 1 parameter numbers."""

    COMMANDED_POSITION = 1
    SW_LIMIT_POS = 2
    SW_LIMIT_NEG = 3
    ENABLE_LIMIT_POS = 4
    ENABLE_LIMIT_NEG = 5
    ENABLE_POS_LAG_MONITORING = 6
    MAX_POSITION_LAG = 7
    MAX_VELOCITY_SYSTEM = 8
    MAX_VELOCITY_APPL = 9
    ACTUAL_VELOCITY = 10
    COMMANDED_VELOCITY = 11
    MAX_ACCELERATION_SYSTEM = 12
    MAX_ACCELERATION_APPL = 13
    MAX_DECELERATION_SYSTEM = 14
    MAX_DECELERATION_APPL = 15
    MAX_JERK_SYSTEM = 16
    MAX_JERK_APPL = 17


Reader = Callable[[Controller, Axis], float]
Writer = Callable[[Controller, Axis, float], None]


@dataclass(frozen=True)
class Parameter:
    boolean: bool
    read: Reader
    write: Writer | None = None


def _fe_limit(ctl: Controller, ax: Axis) -> float:
    return ax.lag_limit


def _set_fe_limit(ctl: Controller, ax: Axis, value: float) -> None:
    ctl.set_following_error_limit(ax, value)


def _lag_watched(ctl: Controller, ax: Axis) -> float:
    return float(ctl.fe_limit[ax.index] > 0.0)


def _set_lag_watched(ctl: Controller, ax: Axis, value: float) -> None:
    ctl.set_lag_monitoring(ax, bool(value))


P = MCAxisParameter
PARAMETERS: dict[MCAxisParameter, Parameter] = {
    P.COMMANDED_POSITION: Parameter(False, lambda c, a: a.command_position),
    P.ENABLE_LIMIT_POS: Parameter(True, lambda c, a: 0.0),
    P.ENABLE_LIMIT_NEG: Parameter(True, lambda c, a: 0.0),
    P.ENABLE_POS_LAG_MONITORING: Parameter(True, _lag_watched, _set_lag_watched),
    P.MAX_POSITION_LAG: Parameter(False, _fe_limit, _set_fe_limit),
    P.MAX_VELOCITY_SYSTEM: Parameter(False, lambda c, a: a.config.max_velocity),
    P.MAX_VELOCITY_APPL: Parameter(False, lambda c, a: a.config.max_velocity),
    P.ACTUAL_VELOCITY: Parameter(False, lambda c, a: a.actual_velocity),
    P.COMMANDED_VELOCITY: Parameter(False, lambda c, a: a.command_velocity),
    P.MAX_ACCELERATION_SYSTEM: Parameter(False, lambda c, a: a.config.max_acceleration),
    P.MAX_ACCELERATION_APPL: Parameter(False, lambda c, a: a.config.max_acceleration),
    P.MAX_DECELERATION_SYSTEM: Parameter(False, lambda c, a: a.config.max_deceleration),
    P.MAX_DECELERATION_APPL: Parameter(False, lambda c, a: a.config.max_deceleration),
    P.MAX_JERK_SYSTEM: Parameter(False, lambda c, a: a.config.max_jerk),
    P.MAX_JERK_APPL: Parameter(False, lambda c, a: a.config.max_jerk),
}
del P


def lookup(number: int, boolean: bool, write: bool = False) -> Parameter:
    """The parameter ``number`` of the kind asked for; MotionError 13 when there is none
    (the caller names the operand)."""
    try:
        param = PARAMETERS[MCAxisParameter(number)]
    except (KeyError, ValueError):
        raise MotionError(
            ErrorCode.PARAMETER_OUT_OF_RANGE, f"parameter {number} is not held by the axes"
        ) from None
    if param.boolean != boolean:
        kind = "BOOL" if param.boolean else "numeric"
        raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"parameter {number} is {kind}")
    if write and param.write is None:
        raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"parameter {number} is read-only")
    return param
