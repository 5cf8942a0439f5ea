"""Shared fixtures, and the hypothesis profiles.

Property tests explore new random examples on every local run; under CI (``CI`` set, as
`.ci/run` runs) they are derandomised, so a landing is judged on reproducible examples.
A failure found locally prints the example to add as a regression test.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType

from .support import make_system

#: pytester: runs pytest on throwaway test files (the pytest plugin's own tests)
pytest_plugins = ["pytester"]

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


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
