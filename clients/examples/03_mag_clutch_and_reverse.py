"""MAG with the clutch onto a moving master, then Direction = reverse, clutched again.

The master jogs at 100 mm/s. MAG at ratio 0.5 with the clutch enabled ramps the slave
from rest to 0.5 · 100 = 50 mm/s at AccelRate 500 mm/s² (0.1 s) and locks. MAG with
Direction 2 (reverse) ramps it from +50 to -50 mm/s at the same rate (0.2 s) and locks
in the opposite direction: the winding-machine case of the seed.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Master.CommandVelocity",
    "Slave.CommandVelocity",
    "Master.CommandPosition",
    "Slave.CommandPosition",
    "MAG_1.IP",
]
RATE = 500.0

#: jog dynamics in units/s and units/s² (operands keep their values between triggers)
TIME_UNITS = dict(SpeedUnits=0, AccelUnits=0, DecelUnits=0)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("MSO_1", Axis=1)
    await sc.trigger("MSO_1", Axis=2)
    await sc.trigger("Jog_Master", Speed=100.0, AccelRate=10000.0, DecelRate=10000.0, **TIME_UNITS)
    await sc.run(0.1)
    clutch = dict(
        MasterReference="COMMAND", RatioFormat="REAL", Clutch="ENABLED", AccelUnits="UNITS_PER_SEC2"
    )
    await sc.trigger(
        "MAG_1", SlaveAxis=2, MasterAxis=1, Direction="SAME", Ratio=0.5, AccelRate=RATE, **clutch
    )
    await sc.run(0.05 - 0.002)  # 25 cycles into the 50-cycle ramp
    sc.check(
        "clutch ramp half way [mm/s]: 500 · 0.05",
        float(await sc.read("Slave.CommandVelocity")),
        25.0,
        RATE * 0.002,
    )
    await sc.run(0.25)
    sc.check("locked: 0.5 · 100 [mm/s]", float(await sc.read("Slave.CommandVelocity")), 50.0)
    await sc.trigger(
        "MAG_1", SlaveAxis=2, MasterAxis=1, Direction="REVERSE", Ratio=0.5, AccelRate=RATE, **clutch
    )
    await sc.run(0.1 - 0.002)  # 50 cycles into the 100-cycle reversal
    sc.check(
        "reversal half way [mm/s]: 50 - 500 · 0.1",
        float(await sc.read("Slave.CommandVelocity")),
        0.0,
        RATE * 0.002,
    )
    await sc.run(0.3)
    sc.check("locked reversed [mm/s]", float(await sc.read("Slave.CommandVelocity")), -50.0)
    sc.check("MAG IP stays set", int(await sc.read("MAG_1.IP")), 1, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
