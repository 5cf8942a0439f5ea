"""Speed, acceleration and jerk operands as Logix and PLCopen express them.

Logix gives each rate with a units selector (units per second, % of the axis maximum,
...). These helpers turn the latched operands into kernel :class:`Limits`, raising the
ERR 13 of the operand at fault.

Master-driven speed control (MDSC): selector value 4 gives a rate per master unit (speed
in units per MasterUnit, acceleration and deceleration per MasterUnit², jerk per
MasterUnit³). All dynamics of one instruction are then in master units, or all in time
units; a mix is a runtime error (ERR 105). Jerk in % of time fits both modes.

Commands beyond the axis's limits (Logix): a time-driven speed above the axis Maximum
Speed (in units/s or in % of it) is limited to it: the instruction is accepted and runs at
the Maximum Speed, so no single instruction drives the axis beyond it and a stop from its
motion takes at most Maximum Speed / Maximum Deceleration. Rates are taken as programmed
(a steeper ramp reaches the same limited speed sooner; a steeper deceleration only ends a
motion sooner). A speed per master unit is not limited here (it scales with the master).
"""

from __future__ import annotations

from enum import IntEnum
from typing import TYPE_CHECKING

from ..kernel import Axis, ErrorCode, Limits, MotionError

if TYPE_CHECKING:
    from .base import Instruction


class SpeedUnits(IntEnum):
    UNITS_PER_SEC = 0
    PERCENT_OF_MAXIMUM = 1
    UNITS_PER_MASTER_UNIT = 4


class AccelUnits(IntEnum):
    UNITS_PER_SEC2 = 0
    PERCENT_OF_MAXIMUM = 1
    UNITS_PER_MASTER_UNIT2 = 4


class JerkUnits(IntEnum):
    UNITS_PER_SEC3 = 0
    PERCENT_OF_MAXIMUM = 1
    PERCENT_OF_TIME = 2
    UNITS_PER_MASTER_UNIT3 = 4


class DriveMode(IntEnum):
    """Whether an instruction's profile advances with time or with master travel."""

    TIME_DRIVEN = 0
    MASTER_DRIVEN = 1


#: the selector value that means "per master unit" (speed, accel/decel and jerk alike)
MASTER_UNITS = 4


class ProfileType(IntEnum):
    TRAPEZOIDAL = 0
    S_CURVE = 1


class MergeMode(IntEnum):
    DISABLED = 0
    ENABLED = 1


class MergeSpeed(IntEnum):
    PROGRAMMED = 0
    CURRENT = 1


def drive_mode(inst: Instruction, units: tuple[str, ...], jerk_units: str | None) -> DriveMode:
    """Time- or master-driven, from the units selectors ``units`` (and ``jerk_units``
    when the jerk is used). A mix of the two is refused with ERR 105."""
    judged = list(units)
    if jerk_units is not None and int(inst.op[jerk_units]) != JerkUnits.PERCENT_OF_TIME:
        judged.append(jerk_units)
    master = [u for u in judged if int(inst.op[u]) == MASTER_UNITS]
    if len(master) == len(judged):
        return DriveMode.MASTER_DRIVEN
    if not master:
        return DriveMode.TIME_DRIVEN
    mixed = ", ".join(master)
    raise MotionError(
        ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
        f"{mixed} in master units but not every other rate: all dynamics of one instruction "
        "must be time-driven or all master-driven",
    )


def logix_drive_mode(inst: Instruction) -> DriveMode:
    """Drive mode of a MAJ/MAM from SpeedUnits, AccelUnits, DecelUnits (and JerkUnits for
    an S-curve profile)."""
    s_curve = int(inst.op["Profile"]) == ProfileType.S_CURVE
    return drive_mode(
        inst, ("SpeedUnits", "AccelUnits", "DecelUnits"), "JerkUnits" if s_curve else None
    )


def speed(inst: Instruction, ax: Axis, value: str = "Speed", units: str = "SpeedUnits") -> float:
    v = float(inst.op[value])
    sel = int(inst.op[units])
    if sel == SpeedUnits.PERCENT_OF_MAXIMUM:
        v = v / 100.0 * ax.config.max_velocity
    if sel != SpeedUnits.UNITS_PER_MASTER_UNIT:
        v = min(v, ax.config.max_velocity)  # limited to the axis Maximum Speed
    return v


def rate(inst: Instruction, ax: Axis, value: str, units: str, maximum: float) -> float:
    a = float(inst.op[value])
    if int(inst.op[units]) == AccelUnits.PERCENT_OF_MAXIMUM:
        a = a / 100.0 * maximum
    if a <= 0.0:
        raise inst.out_of_range(value, f"{value} must be > 0")
    return a


def jerk(
    inst: Instruction, ax: Axis, value: str, speed_: float, accel: float, units: str = "JerkUnits"
) -> float:
    """Jerk in units/s^3; 0 means trapezoidal. % of time: the share of the ramp spent
    changing acceleration (100 % = a triangular acceleration, jerk = a^2 / v)."""
    j = float(inst.op[value])
    sel = int(inst.op[units])
    if sel == JerkUnits.PERCENT_OF_MAXIMUM:
        if ax.config.max_jerk <= 0.0:
            raise inst.out_of_range(value, "the axis has no maximum jerk configured")
        j = j / 100.0 * ax.config.max_jerk
    elif sel == JerkUnits.PERCENT_OF_TIME:
        if j <= 0.0 or j > 100.0:
            raise inst.out_of_range(value, "% of time must be in (0, 100]")
        j = accel * accel / (max(speed_, 1e-12) * j / 100.0)
    if j <= 0.0:
        raise inst.out_of_range(value, f"{value} must be > 0 for an S-curve profile")
    return j


def logix_limits(inst: Instruction, ax: Axis, speed_: float) -> Limits:
    """Limits of a Logix MAJ/MAM from Speed/Accel/Decel/Profile/Jerk operands."""
    cfg = ax.config
    acc = rate(inst, ax, "AccelRate", "AccelUnits", cfg.max_acceleration)
    dec = rate(inst, ax, "DecelRate", "DecelUnits", cfg.max_deceleration)
    j = 0.0
    if int(inst.op["Profile"]) == ProfileType.S_CURVE:
        ja = jerk(inst, ax, "AccelJerk", speed_, acc)
        jd = jerk(inst, ax, "DecelJerk", speed_, dec)
        # one jerk limit per ruckig profile: the smaller respects both operands
        j = min(ja, jd)
    return Limits(speed_, acc, dec, j)
