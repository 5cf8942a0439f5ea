"""MC_Home and MC_SetPosition on a rotary axis (RotSlave, 360° rollover).

RotSlave homes as its site map says (MOTION-RM003 "switch then marker", bidirectional
forward): at 90°/s to the home switch, a cam on [100°, 120°] of the raw feedback that
repeats every turn, so it is met from any start within one turn; it backs off at 10°/s
until the cam clears at 100°, goes on to the next marker below (markers every 30° from
5°: 95°), where the axis reads MC_Home's Position, 45°, and returns there. Nothing on
the machine moved: the cam now reads [100 - 95 + 45, 120 - 95 + 45] = [50°, 70°].
MC_SetPosition Relative -15° shifts the coordinates once more, with no motion: the cam
reads [35°, 55°], which the HomeSwitch tag confirms at 40° (on) and 20° (off).
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "RotSlave.CommandPosition",
    "RotSlave.CommandVelocity",
    "RotSlave.HomeSwitch",
    "RotSlave.PLCopenState",
    "Home_RotSlave.Done",
]
HOMED = 1 << 7  # MotionStatus bit 7


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_RotSlave", Enable=True)
    # Execute held high, as a program holds it: Done stays up until Execute falls
    await sc.write("Home_RotSlave.Position", 45.0)
    await sc.write("Home_RotSlave.HomingMode", 0)  # DEFAULT: the configured sequence
    await sc.write("Home_RotSlave.Execute", True)
    await sc.run(0.1)
    sc.check("state Homing (5)", int(await sc.read("RotSlave.PLCopenState")), 5, 0)
    # at most one turn at 90°/s (4 s), 5° back at 10°/s and the way back: 6 s is ample
    await sc.run(6.0)
    sc.check("MC_Home Done", int(await sc.read("Home_RotSlave.Done")), 1, 0)
    await sc.write("Home_RotSlave.Execute", False)
    sc.check("at the home position [deg]", float(await sc.read("RotSlave.CommandPosition")), 45.0)
    sc.check("Homed bit", int(await sc.read("RotSlave.MotionStatus")) & HOMED, HOMED, 0)
    sc.check("state StandStill (2)", int(await sc.read("RotSlave.PLCopenState")), 2, 0)
    await sc.run(0.5)  # the drive settles
    before = float(await sc.read("RotSlave.ActualPosition"))
    await sc.trigger("SetPosition_RotSlave", Position=-15.0, Relative=True)
    sc.check(
        "MC_SetPosition: the actual position moved by [deg]",
        float(await sc.read("RotSlave.ActualPosition")) - before,
        -15.0,
    )
    sc.check("no motion [deg/s]", float(await sc.read("RotSlave.CommandVelocity")), 0.0)
    dyn = dict(Velocity=90.0, Acceleration=3600.0, Deceleration=3600.0, Jerk=0.0)
    await sc.trigger("Move_RotSlave", Position=40.0, Direction=2, **dyn)
    await sc.run(0.5)
    sc.check("HomeSwitch on at 40° (cam [35, 55])", int(await sc.read("RotSlave.HomeSwitch")), 1, 0)
    await sc.trigger("Move_RotSlave", Position=20.0, Direction=2, **dyn)
    await sc.run(0.5)
    sc.check("HomeSwitch off at 20°", int(await sc.read("RotSlave.HomeSwitch")), 0, 0)
    sc.check("at [deg]", float(await sc.read("RotSlave.CommandPosition")), 20.0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
