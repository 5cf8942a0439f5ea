"""One-axis profiles: trapezoidal in closed form (:mod:`.trapezoid`), jerk-limited velocity
and position targets in closed form (:mod:`.scurve`, :mod:`.scurve_position`), the states
those do not cover through ruckig (one online update per cycle, :class:`Profile`).

A profile plans in displacement from its own origin, so a process can add its position to
the others (superposition). Inputs are validated here before ruckig sees them: ruckig
raises on bad input, and a controller must answer ER instead. Jerk 0 (or infinite) means a
trapezoidal velocity profile: :func:`profile_for` then gives a
:class:`~.trapezoid.TrapezoidProfile`; otherwise a :class:`~.scurve.SCurveProfile`, which
hands what its closed forms do not cover to a :class:`Profile`. The fast lanes sample the
closed forms as arrays.
``intermediate_positions`` is never set.
"""

from __future__ import annotations

from .limits import INF, Limits
from .ruckig_profile import Profile, apply_input, capture_input, time_before
from .scurve import SCurveProfile
from .trapezoid import TrapezoidProfile

__all__ = [
    "INF",
    "Limits",
    "OnlineProfile",
    "Profile",
    "SCurveProfile",
    "TrapezoidProfile",
    "apply_input",
    "capture_input",
    "profile_for",
    "time_before",
]


#: a process's profile: the closed forms, trapezoidal or jerk-limited (ruckig inside for
#: what they do not cover); a bare ruckig profile where a caller builds one
OnlineProfile = Profile | TrapezoidProfile | SCurveProfile


def profile_for(
    limits: Limits,
    dt: float,
    velocity: float = 0.0,
    acceleration: float = 0.0,
    position: float = 0.0,
) -> OnlineProfile:
    """The profile that plans ``limits``: trapezoidal in closed form, else jerk-limited
    (in closed form, ruckig for the states the closed forms leave)."""
    if limits.trapezoidal:
        return TrapezoidProfile(dt, velocity, acceleration, position)
    return SCurveProfile(dt, velocity, acceleration, position)
