"""Cam profiles against closed forms (kernel/cam_profile.py, MCCP's interpolation).

A cubic segment between two points with both end slopes 0 is the smooth step
y0 + (y1 - y0)(3u^2 - 2u^3), u = (x - x0)/(x1 - x0): 0.028 at u = 0.1 and 0.104 at u = 0.2
(the cubic motion law's table); with end slopes equal to the secant it is the straight
line. The clamped spline's inner slopes solve
h[i] m[i-1] + 2 (h[i-1] + h[i]) m[i] + h[i-1] m[i+1] = 3 (h[i] d[i-1] + h[i-1] d[i]),
worked by hand below.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import ErrorCode, MotionError
from motion_server.kernel.cam_profile import CamError, compute_profile
from motion_server.kernel.cam_tables import CamStore, CamTableConfig

LINEAR, CUBIC = 0, 1


def test_a_two_point_cubic_from_rest_is_the_smooth_step() -> None:
    p = compute_profile([0.0, 1.0], [0.0, 1.0], [CUBIC, CUBIC])
    assert p.value(0.1) == pytest.approx(0.028, abs=1e-15)
    assert p.value(0.2) == pytest.approx(0.104, abs=1e-15)
    f, f1, f2 = p.evaluate(0.5)
    assert (f, f1, f2) == (0.5, 1.5, 0.0)  # 3u^2-2u^3, 6u-6u^2, 6-12u at u = 1/2
    assert p.evaluate(0.0)[1] == 0.0 and p.evaluate(1.0)[1] == 0.0  # from rest, to rest


def test_scaled_span_and_stroke() -> None:
    # the same law over master 0..200 and slave 10..60: y = 10 + 50 (3u^2 - 2u^3)
    p = compute_profile([0.0, 200.0], [10.0, 60.0], [CUBIC, CUBIC])
    u = 0.25
    assert p.value(50.0) == pytest.approx(10.0 + 50.0 * (3 * u**2 - 2 * u**3), abs=1e-12)
    # dy/dx = 50/200 (6u - 6u^2)
    assert p.evaluate(50.0)[1] == pytest.approx(0.25 * (6 * u - 6 * u**2), abs=1e-15)


def test_end_slopes_equal_to_the_secant_give_the_straight_line() -> None:
    p = compute_profile([0.0, 1.0], [0.0, 1.0], [CUBIC, CUBIC], start_slope=1.0, end_slope=1.0)
    for x in (0.1, 0.3, 0.77):
        assert p.value(x) == pytest.approx(x, abs=1e-15)
        assert p.evaluate(x)[2] == pytest.approx(0.0, abs=1e-14)


def test_a_symmetric_three_point_spline() -> None:
    # (0,0) (1,1) (2,0), slopes 0 at the ends: 4 m1 = 3 (1 - 1) -> m1 = 0
    p = compute_profile([0.0, 1.0, 2.0], [0.0, 1.0, 0.0], [CUBIC, CUBIC, CUBIC])
    assert p.value(0.5) == pytest.approx(0.5, abs=1e-15)
    assert p.value(1.5) == pytest.approx(0.5, abs=1e-15)
    assert p.evaluate(1.0)[1] == pytest.approx(0.0, abs=1e-15)
    assert p.evaluate(1.0)[2] == pytest.approx(-6.0, abs=1e-12)


def test_an_unequal_three_point_spline_solved_by_hand() -> None:
    # (0,0) (1,1) (3,1): h = 1, 2; secants 1, 0; 6 m1 = 3 (2 x 1 + 1 x 0) -> m1 = 1.
    # segment 0: b 0, c 3-0-1 = 2, d 0+1-2 = -1 -> f(0.5) = 2/4 - 1/8 = 0.375
    # segment 1: b 1, c (0-2-0)/2 = -1, d (1+0-0)/4 = 0.25 -> f(3) = 1 + 2 - 4 + 2 = 1
    p = compute_profile([0.0, 1.0, 3.0], [0.0, 1.0, 1.0], [CUBIC, CUBIC, CUBIC])
    assert p.value(0.5) == pytest.approx(0.375, abs=1e-15)
    assert p.value(2.0) == pytest.approx(1.25, abs=1e-15)
    assert p.value(3.0) == pytest.approx(1.0, abs=1e-15)
    # the second derivative is continuous at the inner point: 2c + 6d = -2 both sides
    assert p.evaluate(1.0 - 1e-12)[2] == pytest.approx(-2.0, abs=1e-9)
    assert p.evaluate(1.0)[2] == pytest.approx(-2.0, abs=1e-12)


def test_a_cubic_between_linear_segments_takes_their_slopes() -> None:
    # linear 0..1 (slope 1), cubic 1..2, linear 2..3 (slope 2): the cubic is clamped to
    # 1 and 2: b 1, c (3x2 - 2 - 2) = 2, d (1 + 2 - 4) = -1 -> f(1.5) = 1 + .5 + .5 - .125
    p = compute_profile([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 3.0, 5.0], [LINEAR, CUBIC, LINEAR, 0])
    assert p.value(1.5) == pytest.approx(1.875, abs=1e-15)
    assert p.evaluate(1.0)[1] == pytest.approx(1.0, abs=1e-15)
    assert p.evaluate(2.0)[1] == pytest.approx(2.0, abs=1e-15)
    assert p.value(2.5) == pytest.approx(4.0, abs=1e-15)


def test_linear_segments_interpolate_exactly() -> None:
    p = compute_profile([0.0, 100.0, 200.0], [0.0, 50.0, 50.0], [LINEAR, LINEAR, LINEAR])
    assert p.value(25.0) == 12.5
    assert p.value(150.0) == 50.0
    assert p.rise == 50.0
    assert p.evaluate(25.0)[1:] == (0.5, 0.0)


@pytest.mark.parametrize(
    ("masters", "slaves", "types", "code"),
    [
        ([0.0], [0.0], [0], ErrorCode.ILLEGAL_CAM_LENGTH),
        ([0.0, 1.0], [0.0, 1.0], [2, 0], ErrorCode.ILLEGAL_CAM_TYPE),
        ([0.0, 1.0, 1.0], [0.0, 1.0, 2.0], [0, 0, 0], ErrorCode.ILLEGAL_CAM_ORDER),
        ([0.0, 2.0, 1.0], [0.0, 1.0, 2.0], [0, 0, 0], ErrorCode.ILLEGAL_CAM_ORDER),
        ([0.0, math.nan], [0.0, 1.0], [0, 0], ErrorCode.PARAMETER_OUT_OF_RANGE),
    ],
)
def test_bad_tables_are_refused_with_the_documented_codes(
    masters: list[float], slaves: list[float], types: list[int], code: ErrorCode
) -> None:
    with pytest.raises(CamError) as caught:
        compute_profile(masters, slaves, types)
    assert caught.value.code == code


def test_the_store_judges_lengths_and_use() -> None:
    store = CamStore(
        [
            CamTableConfig(1, "A", 4, ((0, 0, 1), (1, 1, 1), (2, 0, 1))),
            CamTableConfig(2, "B", 2, ((0, 0, 0), (1, 1, 0))),
        ]
    )
    with pytest.raises(MotionError) as caught:
        store.calculate(1, 0, 5, 0.0, 0.0, 1)  # beyond the table's 4 elements
    assert caught.value.code == ErrorCode.ILLEGAL_CAM_LENGTH
    with pytest.raises(MotionError) as failed:
        store.calculate(1, 0, 3, 0.0, 0.0, 2)  # profile 2 holds 2 points
    assert failed.value.code == ErrorCode.ILLEGAL_CAM_PROFILE_LENGTH
    assert store.slot(1).status == 0
    store.calculate(1, 0, 3, 0.0, 0.0, 1)
    assert store.slot(1).status == 2


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(2, 12),
    data=st.data(),
)
def test_numpy_evaluation_is_bit_identical_to_python(n: int, data: st.DataObject) -> None:
    steps = data.draw(st.lists(st.floats(0.01, 50.0), min_size=n - 1, max_size=n - 1))
    xs = list(np.cumsum([0.0, *steps]))
    ys = data.draw(st.lists(st.floats(-100.0, 100.0), min_size=n, max_size=n))
    types = data.draw(st.lists(st.integers(0, 1), min_size=n, max_size=n))
    slopes = data.draw(st.tuples(st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)))
    p = compute_profile(xs, ys, types, *slopes)
    probe = np.array(
        data.draw(st.lists(st.floats(xs[0] - 10.0, xs[-1] + 10.0), min_size=1, max_size=30)) + xs
    )
    many = p.evaluate_many(probe)
    for j, x in enumerate(probe):
        one = p.evaluate(float(x))
        assert (many[0][j], many[1][j], many[2][j]) == one
    # the spline passes through every point
    for x, y in zip(xs, ys, strict=True):
        assert p.value(x) == pytest.approx(y, abs=1e-9 * (1.0 + abs(y)))
