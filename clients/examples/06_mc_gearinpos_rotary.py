"""MC_GearInPos, the seed's rotary example: 360° rollover, master at 0°, slave at 45°.

Ratio 1:1, MasterStartDistance 90°, sync positions master 0° and slave 90°. The master's
next sync occurrence beyond its start is 360° (it starts at 0, within the start distance
of the sync at 0), so the lock-on begins when the master passes 270° (StartSync): the
slave leaves 45° and arrives at 90° at the master's speed just as the master reaches 360°
(= 0°): InSync. From then on the slave runs at the master's speed, 90° ahead of the
master's actual position as sampled at the start of each cycle.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "RotMaster.CommandPosition",
    "RotSlave.CommandPosition",
    "RotMaster.CommandVelocity",
    "RotSlave.CommandVelocity",
    "GearInPos_1.StartSync",
    "GearInPos_1.InSync",
]
SPEED = 180.0  # master, degrees per second: 2 s per turn


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_RotMaster", Enable=True)
    await sc.trigger("Power_RotSlave", Enable=True)
    dyn = dict(Velocity=1000.0, Acceleration=10000.0, Deceleration=10000.0, Jerk=0.0)
    await sc.trigger("Move_RotMaster", Position=0.0, Direction=2, **dyn)
    await sc.trigger("Move_RotSlave", Position=45.0, Direction=2, **dyn)
    await sc.run(0.2)
    sc.check("master starts at [deg]", float(await sc.read("RotMaster.CommandPosition")), 0.0)
    sc.check("slave starts at [deg]", float(await sc.read("RotSlave.CommandPosition")), 45.0)
    await sc.trigger(
        "GearInPos_1",
        until=("Busy",),
        Master=8,
        Slave=9,
        RatioNumerator=1,
        RatioDenominator=1,
        MasterSyncPosition=0.0,
        SlaveSyncPosition=90.0,
        MasterStartDistance=90.0,
        SyncMode="NORMAL",
        BufferMode="BUFFERED",
    )
    sc.check(
        "remaining master distance to the sync [deg]",
        float(await sc.read("GearInPos_1.RemainingMasterDistance")),
        360.0,
    )
    await sc.trigger(
        "Velocity_RotMaster", Velocity=SPEED, Acceleration=100000.0, Deceleration=100000.0
    )
    await sc.run(1.4)  # the master reaches about 252°: still waiting
    sc.check("slave waits at [deg]", float(await sc.read("RotSlave.CommandPosition")), 45.0)
    sc.check("no StartSync yet", int(await sc.read("GearInPos_1.StartSync")), 0, 0)
    await sc.run(0.8)  # past 360°: locked on
    sc.check("InSync", int(await sc.read("GearInPos_1.InSync")), 1, 0)
    master = float(await sc.read("RotMaster.CommandPosition"))
    slave = float(await sc.read("RotSlave.CommandPosition"))
    # MasterActualPosition is sampled at the start of the cycle: the master's previous
    # position, SPEED · dt = 0.36° behind its command position of this cycle
    sc.check(
        "slave = (master actual at cycle start + 90) mod 360 [deg]",
        slave,
        (master - SPEED * 0.002 + 90.0) % 360.0,
        1e-6,
    )
    sc.check(
        "slave speed = master speed [deg/s]",
        float(await sc.read("RotSlave.CommandVelocity")),
        SPEED,
    )


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
