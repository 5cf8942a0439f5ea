"""MC_CamIn with MC_CamOut: a flying shear cuts a moving line, one cut per 500 mm.

The line (virtual, mm) runs at 1000 mm/s. The shear's carriage (servo, mm) follows it on
a periodic cam table the example writes through the tags and selects with
MC_CamTableSelect (MasterAbsolute: one period per 500 mm of line; SlaveAbsolute FALSE:
the carriage starts where it stands). Per period of line travel:

    point  line [mm]  shear [mm]  segment to the next
      0        0          0       cubic: acceleration from rest
      1      100         50       linear: synchronous (slope 1), the cut
      2      250        200       cubic: the return
      3      500          0

MC_CamTableSelect gives the spline slope 0 at both ends; inside, a cubic segment takes its
linear neighbour's slope. So the first segment goes from (0, 0) with slope 0 to (100, 50)
with slope 1: the cubic 0 + 0·u + c·u² + d·u³ with c = (3·(50/100) − 2·0 − 1)/100 =
0.005 and d = (0 + 1 − 2·(50/100))/100² = 0, the parabola 0.005·u²: constant
acceleration (0.01 /mm, 10 000 mm/s² at 1000 mm/s) up to the line's speed. From 100 to
250 mm the shear runs at the line's speed (the cut), then returns from 200 mm to 0 with
slope 1 at 250 and 0 at 500, and the next period starts from rest at its first point.

MC_CamIn couples just after the line passed a period's start (by less than a cycle's
2 mm, where the table is nearly flat: the carriage starts on the cam without a jump, at
a few mm/s) and is InSync at once; EndOfProfile pulses for one cycle each time the line
completes a period (so the trace samples every cycle). In the synchronous section
MC_CamOut disengages the shear: it keeps the line's speed (ContinuousMotion), and MC_Stop
brings it to rest within v²/(2d) = 1000²/(2·50 000) = 10 mm.
"""

from __future__ import annotations

import math
import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Line.CommandPosition",
    "Shear.CommandPosition",
    "Line.CommandVelocity",
    "Shear.CommandVelocity",
    "Shear.PLCopenState",
    "CamIn_Shear.InSync",
    "CamIn_Shear.EndOfProfile",
]
#: (line mm, shear mm, segment type 0 linear / 1 cubic): the table above
POINTS = [(0.0, 0.0, 1), (100.0, 50.0, 0), (250.0, 200.0, 1), (500.0, 0.0, 0)]
PERIOD = 500.0  # mm of line per cut
SPEED = 1000.0  # line, mm/s
DT = 0.002  # s per cycle (the bench's Group1)


async def line_position(sc: Scenario) -> float:
    return float(await sc.read("Line.CommandPosition"))


async def run_to_phase(sc: Scenario, phase: float) -> None:
    """Run until the line (at its speed) has just passed ``phase`` of a period (by less
    than a cycle's travel): an instruction triggered next sees the line there."""
    p = await line_position(sc)
    ahead = (phase - p) % PERIOD
    cycles = math.ceil(ahead / (SPEED * DT))
    await sc.run(cycles * DT)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_Line", Enable=True)
    await sc.trigger("Power_Shear", Enable=True)
    # the table through its tags, then the selection: a profile snapshot, its CamTableID
    for k, (master, slave, segment) in enumerate(POINTS):
        await sc.write(f"ShearCam.Master[{k}]", master)
        await sc.write(f"ShearCam.Slave[{k}]", slave)
        await sc.write(f"ShearCam.SegmentType[{k}]", segment)
    await sc.write("ShearCam.Length", len(POINTS))
    await sc.trigger("Select_Shear", Periodic=True, MasterAbsolute=True, SlaveAbsolute=False)
    table_id = int(await sc.read("Select_Shear.CamTableID"))
    sc.check("profile calculated: Status 2", int(await sc.read("ShearCam.ProfileStatus")), 2, 0)
    await sc.trigger(
        "Velocity_Line", Velocity=SPEED, Acceleration=20000.0, Deceleration=20000.0, Jerk=0.0
    )
    await run_to_phase(sc, 0.0)
    await sc.trigger(
        "CamIn_Shear",
        CamTableID=table_id,
        MasterOffset=0.0,
        SlaveOffset=0.0,
        MasterScaling=1.0,
        SlaveScaling=1.0,
        StartMode="RELATIVE",
        MasterValueSource="SET_VALUE",
        BufferMode="ABORTING",
    )
    sc.check("InSync at once", int(await sc.read("CamIn_Shear.InSync")), 1, 0)
    sc.check("SynchronizedMotion (8)", int(await sc.read("Shear.PLCopenState")), 8, 0)
    sc.check("profile in use: Status 3", int(await sc.read("ShearCam.ProfileStatus")), 3, 0)
    first = len(sc.trace)
    start = await line_position(sc)
    await sc.run(1.1)
    end = await line_position(sc)
    pulses = sum(int(v) for v in sc.trace.column("CamIn_Shear.EndOfProfile")[first:])
    sc.check(
        "one EndOfProfile per 500 mm of line",
        pulses,
        math.floor(end / PERIOD) - math.floor(start / PERIOD),
        0,
    )
    # the cut: in the synchronous section (100..250 mm) the shear runs at the line's speed
    await run_to_phase(sc, 175.0)
    await sc.run(DT)
    sc.check("in the cut: shear speed [mm/s]", float(await sc.read("Shear.CommandVelocity")), SPEED)
    await sc.trigger("CamOut_Shear")
    sc.check("MC_CamIn aborted", int(await sc.read("CamIn_Shear.CommandAborted")), 1, 0)
    await sc.run(0.1)
    sc.check(
        "after MC_CamOut the speed is kept [mm/s]",
        float(await sc.read("Shear.CommandVelocity")),
        SPEED,
    )
    sc.check("ContinuousMotion (7)", int(await sc.read("Shear.PLCopenState")), 7, 0)
    at_stop = float(await sc.read("Shear.CommandPosition"))
    await sc.trigger("Stop_Shear", Deceleration=50000.0, Jerk=0.0)
    await sc.run(0.05)
    sc.check(
        "MC_Stop distance [mm]: 1000² / (2 · 50 000)",
        float(await sc.read("Shear.CommandPosition")) - at_stop,
        10.0,
    )
    sc.check("at rest [mm/s]", float(await sc.read("Shear.CommandVelocity")), 0.0)
    sc.check("StandStill (2)", int(await sc.read("Shear.PLCopenState")), 2, 0)
    sc.check("profile free again: Status 2", int(await sc.read("ShearCam.ProfileStatus")), 2, 0)
    await sc.trigger("Velocity_Line", Velocity=0.0, Acceleration=20000.0, Deceleration=20000.0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv, every=1)


if __name__ == "__main__":
    sys.exit(main())
