"""MC_GearOut: the slave leaves the gear and keeps its velocity until MC_Stop.

The seed's FB test: the master moves at constant speed (MC_MoveVelocity, 100 mm/s), the
slave gears in at 2:1 and runs at 200 mm/s (InGear); after MC_GearOut it "will maintain
the speed before disengagement" in continuous motion (PLCopen state 7) until MC_Stop
(deceleration 2000 mm/s²) stops it within v²/(2d) = 200²/4000 = 10 mm.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "PMaster.CommandPosition",
    "PSlave.CommandPosition",
    "PMaster.CommandVelocity",
    "PSlave.CommandVelocity",
    "PSlave.PLCopenState",
]


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_PMaster", Enable=True)
    await sc.trigger("Power_PSlave", Enable=True)
    await sc.trigger("Velocity_PMaster", Velocity=100.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.trigger(
        "GearIn_1",
        Master=5,
        Slave=6,
        RatioNumerator=2.0,
        RatioDenominator=1.0,
        MasterValueSource="SET_VALUE",
        Acceleration=4000.0,
        Deceleration=4000.0,
        Jerk=0.0,
    )
    await sc.run(0.1)
    sc.check("geared: 2 · 100 [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 200.0)
    sc.check("state SynchronizedMotion (8)", int(await sc.read("PSlave.PLCopenState")), 8, 0)
    await sc.trigger("GearOut_1", Slave=6)
    await sc.run(0.3)
    sc.check(
        "after GearOut the velocity is kept [mm/s]",
        float(await sc.read("PSlave.CommandVelocity")),
        200.0,
    )
    sc.check("state ContinuousMotion (7)", int(await sc.read("PSlave.PLCopenState")), 7, 0)
    # the master slows down: the slave, no longer geared, does not
    await sc.trigger("Velocity_PMaster", Velocity=20.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.run(0.1)
    sc.check(
        "master slowed, slave still [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 200.0
    )
    at_stop = float(await sc.read("PSlave.CommandPosition"))
    await sc.trigger("Stop_PSlave", Deceleration=2000.0, Jerk=0.0)
    await sc.run(0.1)
    sc.check(
        "MC_Stop distance [mm]: 200² / (2 · 2000)",
        float(await sc.read("PSlave.CommandPosition")) - at_stop,
        10.0,
    )
    sc.check("at rest [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 0.0)
    sc.check("state StandStill (2)", int(await sc.read("PSlave.PLCopenState")), 2, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
