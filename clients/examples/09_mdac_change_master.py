"""MDAC: a master-driven slave changes its master, as the seed's sequence prescribes.

Master A (Axis1) jogs at 100 mm/s, master B (Axis3) at 80 mm/s. MDAC assigns the slave
(Axis2) to A; a master-driven MAJ (speed 0.5 mm per master mm, ramps 0.05 per master mm)
makes it track A at 0.5 · 100 = 50 mm/s. A second MDAC to B only makes the change
pending (DN and IP, not AC): the slave still tracks A. The next motion instruction
(MAJ, 1.0 per master mm) performs it: the slave tracks B at 1.0 · 80 = 80 mm/s, the old
MDAC leaves IP and the new one becomes active.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Master.CommandVelocity",
    "Master2.CommandVelocity",
    "Slave.CommandVelocity",
    "Slave.CommandPosition",
    "MDAC_1.AC",
    "MDAC_2.AC",
    "MAJ_2.TrackingMaster",
]
MASTER_UNITS = dict(SpeedUnits=4, AccelRate=0.05, AccelUnits=4, DecelRate=0.05, DecelUnits=4)

#: jog dynamics in units/s and units/s² (operands keep their values between triggers)
TIME_UNITS = dict(SpeedUnits=0, AccelUnits=0, DecelUnits=0)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    for n in (1, 2, 3):
        await sc.trigger("MSO_1", Axis=n)
    await sc.trigger("Jog_Master", Speed=100.0, AccelRate=10000.0, DecelRate=10000.0, **TIME_UNITS)
    await sc.trigger("Jog_Master2", Speed=80.0, AccelRate=10000.0, DecelRate=10000.0, **TIME_UNITS)
    await sc.run(0.05)
    mdac = dict(SlaveAxis=2, MotionType="ALL", MasterReference="COMMAND")
    await sc.trigger("MDAC_1", MasterAxis=1, **mdac)
    await sc.trigger("MAJ_1", Axis=2, Direction="FORWARD", Speed=0.5, **MASTER_UNITS)
    await sc.run(0.3)
    sc.check("tracking A: 0.5 · 100 [mm/s]", float(await sc.read("Slave.CommandVelocity")), 50.0)
    await sc.trigger("MDAC_2", MasterAxis=3, **mdac)
    sc.check("MDAC_2 pending: IP", int(await sc.read("MDAC_2.IP")), 1, 0)
    sc.check("MDAC_2 pending: not AC", int(await sc.read("MDAC_2.AC")), 0, 0)
    await sc.run(0.1)
    sc.check("still tracking A [mm/s]", float(await sc.read("Slave.CommandVelocity")), 50.0)
    await sc.trigger("MAJ_2", Axis=2, Direction="FORWARD", Speed=1.0, **MASTER_UNITS)
    sc.check("MDAC_2 active", int(await sc.read("MDAC_2.AC")), 1, 0)
    sc.check("MDAC_1 left IP", int(await sc.read("MDAC_1.IP")), 0, 0)
    await sc.run(0.3)
    sc.check("tracking B: 1.0 · 80 [mm/s]", float(await sc.read("Slave.CommandVelocity")), 80.0)
    sc.check("TrackingMaster", int(await sc.read("MAJ_2.TrackingMaster")), 1, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
