"""MC_MoveSuperimposed on a geared slave, MC_Halt, then MC_MoveAdditive.

The master runs at 100 mm/s and PSlave follows it 1:1 (MC_GearIn). MC_MoveSuperimposed
(10 mm at 50 mm/s, 1000 mm/s²) rides on the gear as an incremental MAM does on a geared
Logix slave: the slave runs at 100 + 50 mm/s for a while and ends 10 mm ahead of the
master, still in gear (SynchronizedMotion). A second superimposed move is cut short by
MC_Halt, which stops the gear and the superimposed move together. Then MC_MoveAbsolute
heads for 100 mm and MC_MoveAdditive (+25 mm) takes over mid-way: the slave ends on
100 + 25 = 125 mm, the last commanded target plus the distance.
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
    "Super_PSlave.CoveredDistance",
]


async def offset(sc: Scenario) -> float:
    """Slave minus master position: constant while geared 1:1 alone."""
    slave = float(await sc.read("PSlave.CommandPosition"))
    return slave - float(await sc.read("PMaster.CommandPosition"))


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_PMaster", Enable=True)
    await sc.trigger("Power_PSlave", Enable=True)
    await sc.trigger("Velocity_PMaster", Velocity=100.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.trigger(
        "GearIn_1",
        Master=5,
        Slave=6,
        RatioNumerator=1.0,
        RatioDenominator=1.0,
        MasterValueSource="SET_VALUE",
        Acceleration=4000.0,
        Deceleration=4000.0,
        Jerk=0.0,
    )
    await sc.run(0.2)
    sc.check("geared 1:1 [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 100.0)
    before = await offset(sc)
    dynamics = {"Acceleration": 1000.0, "Deceleration": 1000.0, "Jerk": 0.0}
    await sc.trigger("Super_PSlave", until=("Busy",), Distance=10.0, VelocityDiff=50.0, **dynamics)
    # 10 mm at 50 mm/s: 0.05 s up (1.25 mm), 0.15 s at 50 mm/s, 0.05 s down
    await sc.run(0.1)
    sc.check("gear + superimposed [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 150.0)
    sc.check("still SynchronizedMotion (8)", int(await sc.read("PSlave.PLCopenState")), 8, 0)
    await sc.run(0.3)
    sc.check("slave 10 mm ahead of the master [mm]", await offset(sc) - before, 10.0)
    sc.check("CoveredDistance [mm]", float(await sc.read("Super_PSlave.CoveredDistance")), 10.0)
    sc.check("back to the gear [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 100.0)
    # a second one, backwards, halted while it runs: gear and superimposed stop together
    await sc.trigger("Super_PSlave", until=("Busy",), Distance=-10.0, VelocityDiff=50.0, **dynamics)
    await sc.run(0.1)
    sc.check("gear - superimposed [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 50.0)
    await sc.trigger("Halt_PSlave", Deceleration=2000.0, Jerk=0.0)
    await sc.run(0.1)  # 50 mm/s to rest at 2000 mm/s²: 0.025 s
    sc.check("halted [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 0.0)
    sc.check("StandStill (2)", int(await sc.read("PSlave.PLCopenState")), 2, 0)
    sc.check("the master goes on [mm/s]", float(await sc.read("PMaster.CommandVelocity")), 100.0)
    # MC_MoveAdditive takes over a running MC_MoveAbsolute: target + distance
    moves = {"Velocity": 200.0, "Acceleration": 2000.0, "Deceleration": 2000.0, "Jerk": 0.0}
    await sc.trigger("Move_PSlave", until=("Busy",), Position=100.0, **moves)
    await sc.run(0.05)
    # 1 + 25 cycles of 2 ms at 2000 mm/s²: 0.052 s into the ramp
    speed = float(await sc.read("PSlave.CommandVelocity"))
    sc.check("MC_MoveAbsolute accelerating [mm/s]", speed, 2000.0 * 0.052, 1e-6)
    await sc.trigger("Additive_PSlave", Distance=25.0, **moves)
    await sc.run(0.1)
    sc.check("on the last target + 25 [mm]", float(await sc.read("PSlave.CommandPosition")), 125.0)
    sc.check("at rest [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 0.0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
