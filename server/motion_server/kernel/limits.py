"""The dynamics limits of one motion profile, validated before any planner sees them."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import ErrorCode, MotionError

INF = math.inf


@dataclass(frozen=True)
class Limits:
    """Dynamics of one profile; jerk 0 or inf means trapezoidal."""

    velocity: float
    acceleration: float
    deceleration: float
    jerk: float = 0.0

    def validated(self) -> Limits:
        if (
            0.0 < self.velocity < INF
            and 0.0 < self.acceleration < INF
            and 0.0 < self.deceleration < INF
            and self.jerk >= 0.0
        ):
            return self  # the usual case, in one expression (NaN fails every comparison)
        for name in ("velocity", "acceleration", "deceleration"):
            value = getattr(self, name)
            if not math.isfinite(value) or value <= 0.0:
                raise MotionError(
                    ErrorCode.PARAMETER_OUT_OF_RANGE, f"{name} must be > 0 and finite, got {value}"
                )
        if math.isnan(self.jerk) or self.jerk < 0.0:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE, f"jerk must be >= 0, got {self.jerk}"
            )
        return self

    @property
    def trapezoidal(self) -> bool:
        """No jerk limit: planned in closed form (:mod:`.trapezoid`), not by ruckig."""
        return self.jerk == 0.0 or math.isinf(self.jerk)

    @property
    def ruckig_jerk(self) -> float:
        return INF if self.jerk == 0.0 or math.isinf(self.jerk) else self.jerk


def group_stop_deceleration(velocity: float, deceleration: float, max_velocity: float) -> float:
    """The deceleration of a group stop from ``velocity``: the axis's maximum
    ``deceleration``, or, from beyond its ``max_velocity`` (gearing, master-driven or
    superimposed motion can command more), the rate that still ends the stop within
    ``max_velocity / deceleration``, the time a stop from the Maximum Speed needs."""
    v = abs(velocity)
    if v <= max_velocity:
        return deceleration
    return deceleration * (v / max_velocity)
