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
