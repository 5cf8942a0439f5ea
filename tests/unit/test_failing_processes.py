"""A command that fails never moves an axis: not when it is refused at once, not when a
buffered command is judged as it starts, not when a process fails while moving."""

from __future__ import annotations

import numpy as np

from motion_server.instructions import MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    ErrorCode,
    MotionError,
    Process,
    ProcessKind,
)

from ..support import make_system, trigger

DT = 0.002


def jogging_pair() -> MotionSystem:
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.VIRTUAL, max_velocity=500.0, max_acceleration=5000.0,
                   max_deceleration=5000.0),
        AxisConfig(2, "Axis2", AxisType.SERVO, max_velocity=1000.0, max_acceleration=2000.0,
                   max_deceleration=2000.0),
    )  # fmt: skip
    for n in (1, 2):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
    maj = system.add("MAJ", "MAJ_1", {"Axis": 2, "Speed": 100.0, "AccelRate": 2000.0,
                                      "DecelRate": 2000.0})  # fmt: skip
    trigger(system, maj)
    return system


def test_a_buffered_gear_in_pos_judged_inconsistent_as_it_starts_leaves_the_jog_alone() -> None:
    system = jogging_pair()
    ax = system.ctl.axis(2)
    # buffered (the default) while the jog ramps up: it starts once the jog is at speed
    # (100 / 2000 = 0.05 s = 25 cycles), where its default operands are inconsistent
    gip = system.add("MC_GearInPos", "MC_GearInPos_1", {"Master": 1, "Slave": 2})
    trigger(system, gip)
    velocities = []
    for _ in range(60):
        system.cycle()
        velocities.append(ax.command_velocity)
    assert gip.outputs["Error"] and gip.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert velocities[-30:] == [100.0] * 30  # the jog never stopped
    assert len(ax.active(ProcessKind.JOG)) == 1


class FailsAfter(Process):
    """Runs at a constant velocity, then fails (as a profile that cannot be planned)."""

    kind = ProcessKind.MOVE

    def __init__(self, velocity: float, cycles: int) -> None:
        super().__init__()
        self.velocity = velocity
        self.left = cycles

    def step(self, ctl: Controller, dt: float) -> None:
        self.left -= 1
        if self.left < 0:
            raise MotionError(ErrorCode.PROFILE_FAILED, "test failure")
        self.position += self.velocity * dt


def test_a_process_that_fails_while_moving_ramps_down_at_the_maximum_deceleration() -> None:
    system = jogging_pair()
    ctl = system.ctl
    ax = ctl.axis(1)
    ctl.start(ax, lambda v, a: FailsAfter(100.0, 10), replace=None)
    vel = []
    for _ in range(30):
        system.cycle()
        vel.append(ax.command_velocity)
    # 10 cycles at 100, then 100 / (5000 · 0.002) = 10 cycles down to rest, 10 mm/s each
    expected = [100.0] * 10 + list(np.maximum(100.0 - 10.0 * np.arange(1, 21), 0.0))
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert not ax.active()
