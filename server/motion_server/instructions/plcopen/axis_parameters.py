"""The PLCopen axis parameters (Part 1, MC_ReadParameter / MC_WriteParameter) as our axes
hold them: number, type, how to read it, and for the one that can be written, how.

The numbers are PLCopen's (TwinCAT MC_AxisParameter and CODESYS SM3_Basic use the same
1-17). What our axes have (PLCopen's R/W column, checked row by row: 1, 8, 10, 11, 12,
14, 16 are R; 2-7, 9, 13, 15, 17 are R/W, of which only 9 is basic):

- 1 CommandedPosition, 10 ActualVelocity, 11 CommandedVelocity: as the axis tags show
  them after the cycle;
- 6 EnablePosLagMonitoring (BOOL): the following error is monitored (switched on and a
  limit above 0); writable (MC_WriteBoolParameter): FALSE switches the monitoring off
  and keeps the limit, TRUE switches it on again (refused while the limit is 0);
  7 MaxPositionLag: that limit (site map ``following_error_limit``), writable
  (MC_WriteParameter): a value >= 0, 0 turning the monitoring off; both effective from
  the next cycle;
- 8 MaxVelocitySystem, 12 MaxAccelerationSystem, 14 MaxDecelerationSystem, 16
  MaxJerkSystem (0: unlimited): the site map's maxima, read-only (R in PLCopen's table);
- 9 MaxVelocityAppl, 13 MaxAccelerationAppl, 15 MaxDecelerationAppl, 17 MaxJerkAppl: the
  maxima commands are judged against, R/W as in PLCopen's table (9 is "B", basic):
  the System value at start, writable (MC_WriteParameter) with a value above 0 and at
  most the System one (jerk 0, unlimited, only when the System jerk is unlimited); a
  new value applies to commands from then on, motion already running keeps its profile
  (:mod:`motion_server.kernel.appl_limits`);
- 4 / 5 EnableLimitPos / EnableLimitNeg (BOOL): FALSE, the simulated axes have no
  software limits (extended parameters, which PLCopen lets an implementation leave
  out); 2 / 3 SWLimitPos / SWLimitNeg: none to read or write (ErrorID 13); writing 4 / 5
  is refused too (ErrorID 13), as switching on limits that do not exist would mislead.

A number that is not in the table, a BOOL parameter read as a number or the other way
round, and a write to a read-only parameter are refused with ErrorID 13 naming the
ParameterNumber operand.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from ...kernel import Axis, Controller, ErrorCode, MotionError
from ...kernel.appl_limits import Limit, application_limit, set_application_limit, system_limit


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


def _system(limit: Limit) -> Parameter:
    return Parameter(False, lambda c, a: system_limit(a, limit))


def _appl(limit: Limit) -> Parameter:
    def write(ctl: Controller, ax: Axis, value: float) -> None:
        set_application_limit(ax, limit, value)

    return Parameter(False, lambda c, a: application_limit(a, limit), write)


P = MCAxisParameter
PARAMETERS: dict[MCAxisParameter, Parameter] = {
    P.COMMANDED_POSITION: Parameter(False, lambda c, a: a.command_position),
    P.ENABLE_LIMIT_POS: Parameter(True, lambda c, a: 0.0),
    P.ENABLE_LIMIT_NEG: Parameter(True, lambda c, a: 0.0),
    P.ENABLE_POS_LAG_MONITORING: Parameter(True, _lag_watched, _set_lag_watched),
    P.MAX_POSITION_LAG: Parameter(False, _fe_limit, _set_fe_limit),
    P.MAX_VELOCITY_SYSTEM: _system(Limit.VELOCITY),
    P.MAX_VELOCITY_APPL: _appl(Limit.VELOCITY),
    P.ACTUAL_VELOCITY: Parameter(False, lambda c, a: a.actual_velocity),
    P.COMMANDED_VELOCITY: Parameter(False, lambda c, a: a.command_velocity),
    P.MAX_ACCELERATION_SYSTEM: _system(Limit.ACCELERATION),
    P.MAX_ACCELERATION_APPL: _appl(Limit.ACCELERATION),
    P.MAX_DECELERATION_SYSTEM: _system(Limit.DECELERATION),
    P.MAX_DECELERATION_APPL: _appl(Limit.DECELERATION),
    P.MAX_JERK_SYSTEM: _system(Limit.JERK),
    P.MAX_JERK_APPL: _appl(Limit.JERK),
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
