"""MAH to an encoder marker, then MRP (Logix, Axis2 'Slave').

Slave homes as its site map says (MOTION-RM003 "marker", unidirectional forward): at the
home speed, 20 mm/s, to the next encoder marker (one every 10 mm), which reads
home_position - home_offset = 0 - 5 = -5 mm; the axis runs on at the home speed to the
home position, 0 mm, in the same direction ("by setting a Home Offset greater than the
deceleration distance, unidirectional motion to the Home Position is insured"): PC.
MRP then redefines the position with no motion: Absolute on the actual position (it
reads 100 mm exactly, the command moves with it), then Relative on the command
(+2.5 mm, both move by it).
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Slave.CommandPosition",
    "Slave.ActualPosition",
    "Slave.CommandVelocity",
    "Slave.Marker",
    "MAH_1.IP",
    "MAH_1.PC",
]
HOMED = 1 << 7  # MotionStatus bit 7


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("MSO_1", Axis=2)
    await sc.trigger("MAH_1", Axis=2)  # DN at once, IP while the sequence runs
    # the next marker within 10 mm at 20 mm/s (0.5 s), then 5 mm on (0.25 s)
    await sc.run(1.5)
    sc.check("MAH PC", int(await sc.read("MAH_1.PC")), 1, 0)
    sc.check("at the home position [mm]", float(await sc.read("Slave.CommandPosition")), 0.0)
    sc.check("Homed bit", int(await sc.read("Slave.MotionStatus")) & HOMED, HOMED, 0)
    sc.check("actual at home [mm]", float(await sc.read("Slave.ActualPosition")), 0.0, 1e-6)
    await sc.trigger("MRP_1", Axis=2, Type=0, PositionSelect=0, Position=100.0)
    sc.check("MRP absolute, actual [mm]", float(await sc.read("Slave.ActualPosition")), 100.0)
    sc.check(
        "the command moved with it [mm]", float(await sc.read("Slave.CommandPosition")), 100.0, 1e-6
    )
    await sc.trigger("MRP_1", Axis=2, Type=1, PositionSelect=1, Position=2.5)
    sc.check(
        "MRP relative, command [mm]", float(await sc.read("Slave.CommandPosition")), 102.5, 1e-6
    )
    sc.check("actual [mm]", float(await sc.read("Slave.ActualPosition")), 102.5, 1e-6)
    await sc.run(0.2)
    sc.check("no motion [mm/s]", float(await sc.read("Slave.CommandVelocity")), 0.0)
    sc.check("still Homed", int(await sc.read("Slave.MotionStatus")) & HOMED, HOMED, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
