"""The drive model's axis-by-axis path gives the very bits of its vectorised path.

Small parts of a group (drives on, drives off) are stepped in Python floats
(``DriveModel.scalar_part``); ``scalar_part=0`` steps everything with numpy. Both run on
copies of the same arrays, from random states that include both zeros, values that
round half-way in encoder counts, huge, infinite and NaN values."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import AxisConfig, AxisType
from motion_server.kernel.drive import DriveModel
from motion_server.kernel.state import AxisArrays

N = 4


def arrays(servo: bool) -> AxisArrays:
    kind = AxisType.SERVO if servo else AxisType.VIRTUAL
    return AxisArrays(
        [
            AxisConfig(1, "A", kind, conversion_constant=1000.0, following_error_limit=0.5),
            AxisConfig(2, "B", kind, conversion_constant=8192.0, drive_bandwidth=25.0),
            AxisConfig(3, "C", kind, conversion_constant=1.0, coast_deceleration=50.0),
            AxisConfig(4, "D", kind, conversion_constant=3.0, following_error_limit=2.0),
        ]
    )


values = st.one_of(
    st.floats(-1e3, 1e3),
    st.sampled_from([0.0, -0.0, 0.0005, -0.0005, 1.5e-3, -1e-12, 1e300, -1e300, 2.5, -2.5]),
    st.sampled_from([math.inf, -math.inf, math.nan]),
)


@settings(max_examples=300, deadline=None)
@given(
    servo=st.booleans(),
    on=st.lists(st.booleans(), min_size=N, max_size=N),
    state=st.lists(values, min_size=7 * N, max_size=7 * N),
    dt=st.sampled_from([0.001, 0.002, 0.004]),
    cycles=st.integers(1, 4),
)
def test_rows_and_vectors_give_the_same_bits(
    servo: bool, on: list[bool], state: list[float], dt: float, cycles: int
) -> None:
    pair = []
    for scalar_part in (0, N):
        s = arrays(servo)
        s.kinematics[:] = np.array(state).reshape(7, N)
        s.drive_on[:] = on
        pair.append((s, DriveModel(s, scalar_part=scalar_part)))
    idx = np.arange(N)
    with np.errstate(all="ignore"):
        for _ in range(cycles):
            beyond = [model.follow(idx, dt, servo) for _, model in pair]
            assert beyond[0] == beyond[1]
            (a, _), (b, _) = pair
            assert a.kinematics.tobytes() == b.kinematics.tobytes()
