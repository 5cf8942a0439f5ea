"""Application limits: the axis maxima a program may lower at run time (PLCopen
MaxVelocityAppl, MaxAccelerationAppl, MaxDecelerationAppl, MaxJerkAppl).

An axis has two sets of maxima. The *system* maxima are the site map's
(``Axis.system_config``, PLCopen MaxVelocitySystem ...) and never change while the server
runs. The *application* maxima are those every command is judged and limited against
(``Axis.config``): the system ones at start, lowered (or raised back, never beyond the
system ones) by :func:`set_application_limit`.

A new limit applies to what is commanded from then on: motion already running keeps the
profile it was planned with (it was judged against the limits in force when it started),
as a Logix axis applies a new Maximum Speed to the next motion instruction. A command
issued later is judged against the new limits (a stop or halt, a Motion Change Dynamics;
a buffered command is judged at its edge, not when it starts); an override change
re-plans running motion with its programmed dynamics, as before.
"""

from __future__ import annotations

import math
from dataclasses import replace
from enum import StrEnum
from typing import Protocol

from .axis import Axis
from .errors import ErrorCode, MotionError
from .trapezoid import MAX_DURATION


class Limit(StrEnum):
    """The application limits, by their ``AxisConfig`` field."""

    VELOCITY = "max_velocity"
    ACCELERATION = "max_acceleration"
    DECELERATION = "max_deceleration"
    JERK = "max_jerk"


def application_limit(ax: Axis, limit: Limit) -> float:
    """The limit in force for commands (0 jerk: unlimited)."""
    return float(getattr(ax.config, limit.value))


def system_limit(ax: Axis, limit: Limit) -> float:
    """The site map's limit (0 jerk: unlimited)."""
    return float(getattr(ax.system_config, limit.value))


def set_application_limit(ax: Axis, limit: Limit, value: float) -> None:
    """Set an application limit: finite, above 0 and at most the system limit (for jerk,
    0 means unlimited and is allowed only when the system jerk is unlimited too), and not
    making a ramp longer than the kernel plans (a deceleration so low that a stop from the
    Maximum Speed would last over :data:`~.trapezoid.MAX_DURATION`: the site map's bound).
    MotionError 13 otherwise, and the limit stays as it was."""
    value = float(value)
    top = system_limit(ax, limit)
    unlimited = limit == Limit.JERK and top == 0.0
    if not math.isfinite(value) or value < 0.0 or (value == 0.0 and not unlimited):
        raise MotionError(
            ErrorCode.PARAMETER_OUT_OF_RANGE,
            f"{limit.value} {value!r} must be finite and above 0",
        )
    if not unlimited and value > top:
        raise MotionError(
            ErrorCode.PARAMETER_OUT_OF_RANGE,
            f"{limit.value} {value!r} is above the system limit {top!r} of {ax.name}",
        )
    cfg = ax.config
    if limit == Limit.VELOCITY:
        new = replace(cfg, max_velocity=value)
    elif limit == Limit.ACCELERATION:
        new = replace(cfg, max_acceleration=value)
    elif limit == Limit.DECELERATION:
        new = replace(cfg, max_deceleration=value)
    else:
        new = replace(cfg, max_jerk=value)
    too_long = long_ramps(new)
    if too_long:
        _field, t, what = too_long[0]
        raise MotionError(
            ErrorCode.PARAMETER_OUT_OF_RANGE,
            f"{limit.value} {value!r} of {ax.name}: {what} would take {t:.3g} s "
            f"(at most {MAX_DURATION:g} s)",
        )
    ax.config = new


class RampLimits(Protocol):
    """Axis maxima: a kernel ``AxisConfig`` or a site map's axis section."""

    @property
    def max_velocity(self) -> float: ...
    @property
    def max_acceleration(self) -> float: ...
    @property
    def max_deceleration(self) -> float: ...
    @property
    def max_jerk(self) -> float: ...


def long_ramps(limits: RampLimits) -> list[tuple[str, float, str]]:
    """(field, seconds, what) of each ramp the maxima imply that lasts longer than the
    kernel plans (:data:`~.trapezoid.MAX_DURATION`): reaching max_velocity, stopping
    from it (a group stop from the Maximum Speed must stay a plan the kernel takes),
    reaching the larger rate at max_jerk. The site map is judged by the same bound."""
    v = limits.max_velocity
    ramps = [
        ("max_acceleration", v / limits.max_acceleration, "reaching max_velocity"),
        ("max_deceleration", v / limits.max_deceleration, "stopping from max_velocity"),
    ]
    if limits.max_jerk:
        rate = max(limits.max_acceleration, limits.max_deceleration)
        ramps.append(("max_jerk", rate / limits.max_jerk, "reaching the largest rate"))
    return [(field, t, what) for field, t, what in ramps if not t <= MAX_DURATION]
