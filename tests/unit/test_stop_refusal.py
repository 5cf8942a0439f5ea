"""The group stop's quick judgement of its ramps (:func:`motion_server.kernel.stop_plan._within`)
only ever accepts batches that the element-by-element checks accept: whatever it lets
through, the ramps' constructors would have accepted one by one (``Limits.validated``
and ``judge_ramp``), so the arrays' path never skips a refusal the reference path raises."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel.limits import Limits
from motion_server.kernel.stop_plan import _refused_exactly, _within, refused
from motion_server.kernel.trapezoid import MAX_DURATION, judge_ramp

#: velocities and decelerations where the checks change their answer: zero of both
#: signs, the smallest and largest floats, beyond a ramp's longest duration, NaN, inf
SPECIAL = [
    0.0, -0.0, 5e-324, 1e-9, 1.0, -1.0, 2500.0, -2500.0, 1e154, -1e154, 1e300, -1e300,
    8.9e307, 1.79e308, float("inf"), float("-inf"), float("nan"),
    MAX_DURATION, MAX_DURATION * 2500.0, MAX_DURATION * 2500.0 * 1.0000001,
]  # fmt: skip
VALUES = st.one_of(st.sampled_from(SPECIAL), st.floats(allow_nan=True, allow_infinity=True))


def constructors_accept(v: float, d: float, maximum: float | None) -> bool:
    """What the ramp's constructor does with (velocity, deceleration), one at a time."""
    try:
        Limits(max(abs(v), 1e-9) * 2.0, d, d, 0.0).validated()
        judge_ramp(v, d)
    except Exception:
        return False
    return maximum is None or (np.isfinite(maximum) and maximum > 0.0)


@settings(max_examples=500, deadline=None)
@given(
    rows=st.lists(st.tuples(VALUES, VALUES, VALUES), min_size=1, max_size=6),
    with_maximum=st.booleans(),
)
def test_what_the_extremes_accept_every_ramp_accepts(
    rows: list[tuple[float, float, float]], with_maximum: bool
) -> None:
    v = np.array([r[0] for r in rows])
    d = np.array([r[1] for r in rows])
    m = np.array([r[2] for r in rows]) if with_maximum else None
    if _within(v, d, m):
        assert not _refused_exactly(v, d, m)
        assert all(
            constructors_accept(float(v[k]), float(d[k]), None if m is None else float(m[k]))
            for k in range(len(rows))
        )
    assert refused(v, d, m) == _refused_exactly(v, d, m)


def test_the_usual_batch_is_accepted_by_its_extremes() -> None:
    """Axes at speed and at rest, their maximum decelerations: no element-by-element pass."""
    v = np.array([100.0, -80.0, 0.0, 1000.0])
    d = np.array([2500.0, 2500.0, 5000.0, 2500.0])
    assert _within(v, d, d)
    assert not _within(v, np.array([2500.0, 0.0, 5000.0, 2500.0]), None)
    assert not _within(np.array([100.0, float("nan")]), d[:2], None)
