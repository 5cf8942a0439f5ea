"""Cam profiles: a table of points made into a piecewise polynomial slave = f(master).

A :class:`CamProfile` is what MCCP and MC_CamTableSelect compute from a cam table: the
points' master values ``x`` (strictly increasing), and for every segment ``k`` (from point
``k`` up to, not including, point ``k + 1``) the coefficients of

    f(x) = a + u (b + u (c + u d)),   u = x - x[k]

Segment types (the Logix CAM element's ``SegmentType``, for the segment from this point to
the next): 0 linear, 1 cubic. The cubic segments are a clamped cubic spline through their
points (Logix MCCP: "cubic spline"; Start and End Slope are its boundary conditions, 0 =
smooth start and end from rest). Where a run of cubic segments meets a linear segment the
spline takes the linear segment's slope there, so that the slave's velocity never steps
at the join (the documents leave it open; docs/semantics.md). A profile is immutable:
editing the table afterwards changes nothing that runs on it.

Evaluation is the same arithmetic in Python floats (:meth:`CamProfile.evaluate`) and in
numpy arrays (:meth:`CamProfile.evaluate_many`, the fast lanes), in the same order, so the
two agree to the bit.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from .errors import ErrorCode, MotionError


class SegmentType(IntEnum):
    """Logix CAM ``SegmentType``: how the segment from a point to the next is shaped."""

    LINEAR = 0
    CUBIC = 1


class CamError(MotionError):
    """A table that cannot become a profile; ``point`` is the offending point (0-based
    within the points given) or -1."""

    def __init__(self, code: ErrorCode, message: str, point: int = -1) -> None:
        self.point = point
        super().__init__(code, message)


@dataclass(frozen=True, eq=False)
class CamProfile:
    """A computed cam profile (see the module docstring). ``x`` holds the points' master
    values; ``a``..``d`` the coefficients of each segment (one fewer than points)."""

    x: tuple[float, ...]
    a: tuple[float, ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    d: tuple[float, ...]
    #: where the profile came from (table number), for status and messages
    source: int = 0

    def __post_init__(self) -> None:
        self._derive()

    def _derive(self) -> None:
        """What is computed once from the points (the profile never changes): numpy
        copies for the fast lanes, and the range and rise that every cam started on the
        profile reads (a cam start costs a few attribute reads, not a search)."""
        object.__setattr__(self, "_xs", np.array(self.x[:-1], dtype=float))
        # the inner points: counting those at or below x gives x's segment, the end
        # segments extended beyond the ends (what :meth:`segment` clips to), in one call
        object.__setattr__(self, "_inner", np.array(self.x[1:-1], dtype=float))
        for name in "abcd":
            object.__setattr__(self, f"_{name}s", np.array(getattr(self, name), dtype=float))
        object.__setattr__(self, "_last", len(self.x) - 2)
        object.__setattr__(self, "_start", self.x[0])
        object.__setattr__(self, "_end", self.x[-1])
        object.__setattr__(self, "_length", self.x[-1] - self.x[0])
        object.__setattr__(self, "_rise", self.value(self.x[-1]) - self.a[0])

    def __setstate__(self, state: dict[str, object]) -> None:
        # (a profile pickled before the derived values were kept: derived again)
        self.__dict__.update(state)
        if "_inner" not in state:
            self._derive()

    @property
    def start(self) -> float:
        """Master value of the first point."""
        return self._start  # type: ignore[attr-defined]

    @property
    def end(self) -> float:
        """Master value of the last point."""
        return self._end  # type: ignore[attr-defined]

    @property
    def length(self) -> float:
        """Master span of the profile."""
        return self._length  # type: ignore[attr-defined]

    @property
    def points(self) -> int:
        return len(self.x)

    @property
    def rise(self) -> float:
        """f(end) - f(start): what one pass of the profile adds to the slave."""
        return self._rise  # type: ignore[attr-defined]

    def segment(self, x: float) -> int:
        """The segment holding master value ``x`` (the first or last one beyond the ends)."""
        k = bisect.bisect_right(self.x, x) - 1
        last: int = self._last  # type: ignore[attr-defined]
        return 0 if k < 0 else (last if k > last else k)

    def value(self, x: float) -> float:
        k = self.segment(x)
        u = x - self.x[k]
        return self.a[k] + u * (self.b[k] + u * (self.c[k] + u * self.d[k]))

    def evaluate(self, x: float) -> tuple[float, float, float]:
        """f(x), f'(x) and f''(x) (the end segments extended beyond the ends)."""
        k = self.segment(x)
        u = x - self.x[k]
        b, c, d = self.b[k], self.c[k], self.d[k]
        f = self.a[k] + u * (b + u * (c + u * d))
        f1 = b + u * (2.0 * c + u * (3.0 * d))
        f2 = 2.0 * c + u * (6.0 * d)
        return f, f1, f2

    def evaluate_many(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`evaluate` for an array of master values, bit for bit."""
        xs: np.ndarray = self._xs  # type: ignore[attr-defined]
        inner: np.ndarray = self._inner  # type: ignore[attr-defined]
        k = np.searchsorted(inner, x, side="right")
        u = x - xs[k]
        b = self._bs[k]  # type: ignore[attr-defined]
        c = self._cs[k]  # type: ignore[attr-defined]
        d = self._ds[k]  # type: ignore[attr-defined]
        f = self._as[k] + u * (b + u * (c + u * d))  # type: ignore[attr-defined]
        f1 = b + u * (2.0 * c + u * (3.0 * d))
        f2 = 2.0 * c + u * (6.0 * d)
        return f, f1, f2


def _judge(masters: Sequence[float], slaves: Sequence[float], types: Sequence[int]) -> None:
    n = len(masters)
    if n < 2:
        raise CamError(ErrorCode.ILLEGAL_CAM_LENGTH, f"a cam needs at least 2 points, got {n}")
    for k in range(n):
        if not (math.isfinite(masters[k]) and math.isfinite(slaves[k])):
            raise CamError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"point {k}: values must be finite", k)
    for k in range(n - 1):
        if int(types[k]) not in (SegmentType.LINEAR, SegmentType.CUBIC):
            raise CamError(
                ErrorCode.ILLEGAL_CAM_TYPE,
                f"point {k}: SegmentType {types[k]} is neither 0 (linear) nor 1 (cubic)",
                k,
            )
        if not masters[k + 1] > masters[k]:
            raise CamError(
                ErrorCode.ILLEGAL_CAM_ORDER,
                f"point {k + 1}: master value {masters[k + 1]:g} is not greater than "
                f"{masters[k]:g} of point {k}",
                k + 1,
            )


def _spline_slopes(h: Sequence[float], delta: Sequence[float], m0: float, mn: float) -> list[float]:
    """Slopes at the points of a clamped cubic spline over segments of widths ``h`` and
    secants ``delta``, the end slopes given (continuous second derivative inside):

        h[i] m[i-1] + 2 (h[i-1] + h[i]) m[i] + h[i-1] m[i+1] = 3 (h[i] d[i-1] + h[i-1] d[i])

    solved by the Thomas algorithm (the system is diagonally dominant)."""
    n = len(h)  # segments; points n + 1; unknowns m[1..n-1]
    m = [0.0] * (n + 1)
    m[0], m[n] = m0, mn
    if n == 1:
        return m
    # rows i = 1..n-1: lower l, diagonal q, upper r, right-hand side y
    cp = [0.0] * (n + 1)
    yp = [0.0] * (n + 1)
    for i in range(1, n):
        lower = h[i]
        diag = 2.0 * (h[i - 1] + h[i])
        upper = h[i - 1]
        rhs = 3.0 * (h[i] * delta[i - 1] + h[i - 1] * delta[i])
        if i == 1:
            rhs -= lower * m0
            lower = 0.0
        if i == n - 1:
            rhs -= upper * mn
            upper = 0.0
        denom = diag - lower * cp[i - 1]
        cp[i] = upper / denom
        yp[i] = (rhs - lower * yp[i - 1]) / denom
    m[n - 1] = yp[n - 1]
    for i in range(n - 2, 0, -1):
        m[i] = yp[i] - cp[i] * m[i + 1]
    return m


def compute_profile(
    masters: Sequence[float],
    slaves: Sequence[float],
    types: Sequence[int],
    start_slope: float = 0.0,
    end_slope: float = 0.0,
    source: int = 0,
) -> CamProfile:
    """The profile through the points (``types[k]`` shapes the segment after point
    ``k``; the last point's type is not used). Raises :class:`CamError`: ERR 26 fewer than
    two points, 28 a segment type other than 0 or 1, 29 master values not strictly
    increasing, 13 a value that is not finite (Start/End Slope included)."""
    masters = [float(v) for v in masters]
    slaves = [float(v) for v in slaves]
    _judge(masters, slaves, types)
    for name, slope in (("StartSlope", start_slope), ("EndSlope", end_slope)):
        if not math.isfinite(slope):
            raise CamError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"{name} must be finite")
    n = len(masters) - 1
    h = [masters[k + 1] - masters[k] for k in range(n)]
    delta = [(slaves[k + 1] - slaves[k]) / h[k] for k in range(n)]
    b = list(delta)
    c = [0.0] * n
    d = [0.0] * n
    k = 0
    while k < n:
        if int(types[k]) != SegmentType.CUBIC:
            k += 1
            continue
        j = k
        while j + 1 < n and int(types[j + 1]) == SegmentType.CUBIC:
            j += 1
        # a run of cubic segments k..j: clamped at the profile's ends by Start/End Slope,
        # at a linear neighbour by its slope
        m0 = float(start_slope) if k == 0 else delta[k - 1]
        mn = float(end_slope) if j == n - 1 else delta[j + 1]
        m = _spline_slopes(h[k : j + 1], delta[k : j + 1], m0, mn)
        for i in range(k, j + 1):
            # Hermite segment with end slopes m0, m1 as a + b u + c u^2 + d u^3
            m_0, m_1 = m[i - k], m[i - k + 1]
            hi, di = h[i], delta[i]
            b[i] = m_0
            c[i] = (3.0 * di - 2.0 * m_0 - m_1) / hi
            d[i] = (m_0 + m_1 - 2.0 * di) / (hi * hi)
        k = j + 1
    return CamProfile(tuple(masters), tuple(slaves[:-1]), tuple(b), tuple(c), tuple(d), source)
