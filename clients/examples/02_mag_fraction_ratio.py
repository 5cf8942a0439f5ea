"""MAG with a fraction ratio: 1 slave count per 3 master counts, exact forever.

The seed: "the irrational gear ratio of 1/3 can be specified as 1 slave count to 3 master
counts ... with no accumulated positioning errors or round off". Both axes have 1000
counts per mm; the slave's command counts are floor(master counts / 3) at every sample.
"""

from __future__ import annotations

import math
import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Master.CommandPosition",
    "Slave.CommandPosition",
    "Master.CommandVelocity",
    "Slave.CommandVelocity",
]
COUNTS = 1000.0  # counts per mm, both axes

#: jog dynamics in units/s and units/s² (operands keep their values between triggers)
TIME_UNITS = dict(SpeedUnits=0, AccelUnits=0, DecelUnits=0)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("MSO_1", Axis=1)
    await sc.trigger("MSO_1", Axis=2)
    await sc.trigger(
        "MAG_1",
        SlaveAxis=2,
        MasterAxis=1,
        Direction="SAME",
        RatioFormat="FRACTION",
        SlaveCounts=1,
        MasterCounts=3,
        MasterReference="COMMAND",
        Clutch="DISABLED",
    )
    m0 = round(float(await sc.read("Master.CommandPosition")) * COUNTS)
    s0 = round(float(await sc.read("Slave.CommandPosition")) * COUNTS)
    await sc.trigger("Jog_Master", Speed=100.0, AccelRate=1000.0, DecelRate=1000.0, **TIME_UNITS)
    await sc.run(1.0)
    master = round(float(await sc.read("Master.CommandPosition")) * COUNTS) - m0
    slave = round(float(await sc.read("Slave.CommandPosition")) * COUNTS) - s0
    sc.say(f"  master {master} counts, slave {slave} counts")
    sc.check("slave counts = floor(master counts / 3)", slave, math.floor(master / 3), 0)
    sc.check(
        "slave speed = master speed / 3 [mm/s]",
        float(await sc.read("Slave.CommandVelocity")),
        100.0 / 3.0,
        1e-6,
    )


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
