"""The simulated homing sensors of an axis: a home switch and an encoder marker.

Both are fixed to the machine, so they are placed in **raw** feedback coordinates: the
positions the axis reads before any redefinition (MRP, MC_SetPosition, a home event).
The axis reads ``raw + Axis.position_offset``; a redefinition changes the offset, never
where a sensor is.

- The home switch is a cam engaged on the closed interval [``home_switch``,
  ``home_switch + home_switch_width``]; on a rotary axis the cam repeats every turn.
- The marker (an encoder's index pulse) is at ``marker_offset + k * marker_interval``
  for every integer k.

The sensors see the continuous drive position (``act_x``, what the load does), and a
crossing is latched at the exact position of the edge or marker, as registration
hardware latches it; the motion controller reacts in the next cycle. Events are found
between the raw position at the start of a cycle ``r0`` and at its end ``r1``, in the
direction of travel: moving up, an edge at x counts when r0 < x <= r1; moving down,
when r1 <= x < r0 (so a point reached exactly at the end of one cycle is not found
again in the next).
"""

from __future__ import annotations

import math
from enum import IntEnum

from .config import AxisConfig


class SensorEvent(IntEnum):
    """What a sensor reports (the events homing sequences wait for)."""

    SWITCH_ON = 0
    SWITCH_OFF = 1
    MARKER = 2


def _next_up(points: float, period: float, r0: float, r1: float) -> float | None:
    """The first of ``points + k * period`` (``period`` 0: the point alone) in (r0, r1]."""
    if period > 0.0:
        x = points + (math.floor((r0 - points) / period) + 1) * period
        if x <= r0:  # rounding put it on the start point
            x += period
    else:
        x = points
    return x if r0 < x <= r1 else None


def _next_down(points: float, period: float, r0: float, r1: float) -> float | None:
    """The first of ``points + k * period`` in [r1, r0), going down from r0."""
    if period > 0.0:
        x = points + (math.ceil((r0 - points) / period) - 1) * period
        if x >= r0:
            x -= period
    else:
        x = points
    return x if r1 <= x < r0 else None


class HomeSensors:
    """The home switch and marker of one axis (either may be absent)."""

    def __init__(self, cfg: AxisConfig) -> None:
        self.switch_low = cfg.home_switch
        self.switch_width = cfg.home_switch_width
        self.rollover = cfg.rollover if cfg.rollover > 0.0 else 0.0
        self.marker_interval = cfg.marker_interval if cfg.marker_interval > 0.0 else 0.0
        self.marker_offset = cfg.marker_offset

    @property
    def has_switch(self) -> bool:
        return self.switch_low is not None

    @property
    def has_marker(self) -> bool:
        return self.marker_interval > 0.0

    def engaged(self, raw: float) -> bool:
        """The home switch at the raw position ``raw``."""
        low = self.switch_low
        if low is None:
            return False
        if self.rollover > 0.0:
            return (raw - low) % self.rollover <= self.switch_width
        return low <= raw <= low + self.switch_width

    def first(self, event: SensorEvent, r0: float, r1: float) -> float | None:
        """Raw position of the first ``event`` met travelling from r0 to r1 (None: none)."""
        if r1 == r0:
            return None
        up = r1 > r0
        if event == SensorEvent.MARKER:
            if not self.has_marker:
                return None
            points, period = self.marker_offset, self.marker_interval
        else:
            low = self.switch_low
            if low is None:
                return None
            # moving up the cam engages at its low edge and clears past its high edge;
            # moving down the other way round
            at_low = (event == SensorEvent.SWITCH_ON) == up
            points = low if at_low else low + self.switch_width
            period = self.rollover
        if up:
            return _next_up(points, period, r0, r1)
        return _next_down(points, period, r0, r1)
