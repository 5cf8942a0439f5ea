"""A catch-up ruckig cannot plan (a jerk of 1e-300 is > 0, yet no profile exists) is
refused when the gearing block executes, before it replaces the slave's motion: the jog it
would have aborted goes on exactly as without the block."""

from __future__ import annotations

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, ErrorCode

from ..support import make_system, trigger


def jogging() -> MotionSystem:
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.VIRTUAL),
        AxisConfig(2, "Axis2", AxisType.SERVO, max_acceleration=5000.0),
    )
    for n in (1, 2):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
    maj = system.add("MAJ", "MAJ_1", {"Axis": 2, "Speed": 100.0, "AccelRate": 2000.0,
                                      "DecelRate": 2000.0})  # fmt: skip
    trigger(system, maj)
    return system


def test_gear_in_with_a_jerk_ruckig_cannot_plan_leaves_the_jog_alone() -> None:
    systems = [jogging(), jogging()]
    gear = systems[0].add("MC_GearIn", "MC_GearIn_1", {"Master": 1, "Slave": 2, "Jerk": 1e-300})
    trigger(systems[0], gear)
    systems[1].cycle()
    assert gear.outputs["Error"] and gear.outputs["ErrorID"] == ErrorCode.PROFILE_FAILED
    for _ in range(40):
        a, b = (s.ctl.axis(2) for s in systems)
        assert (a.command_position, a.command_velocity) == (b.command_position, b.command_velocity)
        for s in systems:
            s.cycle()
    assert systems[0].ctl.axis(2).command_velocity == 100.0
