"""ruckig's plan of a jerk-limited target as segments of constant jerk.

The states the closed forms of :mod:`.scurve` do not cover (beyond the velocity limit,
moving away from the target, too close to stop, an acceleration beyond its limit) are
planned by ruckig. Its trajectory is a brake of up to two phases (back within the
limits) followed by a profile of seven phases, each of constant jerk (ruckig's
``Profile``: durations ``t`` and jerks ``j``; ``brake`` the same). Integrating those
phases from the start state, as :func:`~.scurve._build` integrates the closed forms'
(ruckig's own formula), gives a :class:`~.scurve.JerkPlan`
(:func:`~.scurve.plan_from_ruckig`) that every cycle samples without ruckig, as the
S-curve lane samples any plan. The samples agree with ruckig's own online update within
its precision (its clock is a running sum of the period, the plan's a product, so they
may differ in the last bits).

Phases of zero duration are left out (integrating them changes nothing, bit for bit);
what is left is padded to four or eight segments, as the closed forms' plans are. A plan
with more than eight phases left, a final acceleration phase (ruckig's ``accel``: only
for a target acceleration, never asked here), an end beyond ruckig's precision of the
target, or a plan the closed forms would refuse (longer than 7,600 s: ruckig plans a few
such states) gives None: the profile is then stepped by ruckig itself.
"""

from __future__ import annotations

from typing import Any

#: ruckig's velocity precision (``Profile::v_precision``)
V_PRECISION = 1e-8


def ruckig_segments(trajectory: Any, most: int) -> list[tuple[float, float]] | None:
    """(duration, jerk) of each phase of ``trajectory`` (a one-DoF ``ruckig.Trajectory``)
    with a duration, the brake's first; None when more than ``most`` or when it ends with
    an acceleration phase."""
    (profile,) = trajectory.profiles[0]
    if profile.accel.duration > 0.0:
        return None
    brake = profile.brake
    segments = [(t, j) for t, j in zip(brake.t, brake.j, strict=True) if t > 0.0]
    segments += [(t, j) for t, j in zip(profile.t, profile.j, strict=True) if t > 0.0]
    if len(segments) > most:
        return None
    return segments
