"""MC_CombineAxes: the slave follows the sum, then the difference, of two masters.

The seed's FB test: all four ratios 1/1, both masters on their set values (command
positions). Master 1 runs at 100 mm/s, master 2 at 30 mm/s (MC_MoveVelocity).
CombineMode 0 (add): slave velocity 100 + 30 = 130 mm/s. MC_Stop ends the combination
(MC_GearOut must not); CombineMode 1 (subtract): 100 - 30 = 70 mm/s. While in sync every
slave increment is the masters' increments added (or subtracted).
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "PMaster.CommandPosition",
    "PMaster2.CommandPosition",
    "PSlave.CommandPosition",
    "PMaster.CommandVelocity",
    "PMaster2.CommandVelocity",
    "PSlave.CommandVelocity",
    "Combine_1.InSync",
]
COMBINE = dict(
    Master1=5,
    Master2=7,
    Slave=6,
    GearRatioNumeratorM1=1.0,
    GearRatioDenominatorM1=1.0,
    GearRatioNumeratorM2=1.0,
    GearRatioDenominatorM2=1.0,
    MasterValueSourceM1="SET_VALUE",
    MasterValueSourceM2="SET_VALUE",
    Acceleration=5000.0,
    Deceleration=5000.0,
    Jerk=0.0,
)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    for power in ("Power_PMaster", "Power_PMaster2", "Power_PSlave"):
        await sc.trigger(power, Enable=True)
    await sc.trigger("Combine_1", CombineMode="ADD", **COMBINE)
    await sc.trigger("Velocity_PMaster", Velocity=100.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.trigger("Velocity_PMaster2", Velocity=30.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.run(0.2)
    sc.check("add: 100 + 30 [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 130.0)
    await sc.trigger("Stop_PSlave", Deceleration=5000.0, Jerk=0.0)
    await sc.run(0.01)  # MC_Stop holds the axis in Stopping until its Execute has fallen
    await sc.trigger("Combine_1", CombineMode="SUBTRACT", **COMBINE)
    await sc.run(0.3)
    sc.check("subtract: 100 - 30 [mm/s]", float(await sc.read("PSlave.CommandVelocity")), 70.0)
    sc.check("InSync", int(await sc.read("Combine_1.InSync")), 1, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
