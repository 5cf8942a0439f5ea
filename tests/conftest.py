"""Shared fixtures."""

from __future__ import annotations

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType

from .support import make_system


@pytest.fixture
def servo_system() -> MotionSystem:
    """One linear servo axis: 100 mm/s, 1000 mm/s^2, 1000 counts/mm, no FE limit."""
    return make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.SERVO,
            max_velocity=100.0,
            max_acceleration=1000.0,
            max_deceleration=1000.0,
        )
    )
