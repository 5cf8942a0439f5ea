"""MAPC Continuous: a rotary knife cuts a conveyor's web, one knife turn per product.

The conveyor (virtual, mm) jogs at 400 mm/s; the knife (servo, 360° rollover) follows it
on a cam table the example writes through the tags, then computes with MCCP. The blade
tip travels 360 mm per turn, so 1°/s of knife is 1 mm/s at the blade: at a slope of
1°/mm the blade runs at the conveyor's speed. One product is 480 mm, one knife turn:

    point  conveyor [mm]  knife [°]  segment to the next
      0          0            0      linear: the cut, synchronous (slope 1)
      1         60           60      cubic
      2        240          180      cubic
      3        420          300      linear: synchronous again, into the next cut
      4        480          360

Between the synchronous sections the knife must cover 240° in 360 mm of conveyor (slope
2/3): MCCP's spline through points 1-3 takes the linear neighbours' slope (1) at 60 and
420 mm, and at 240 mm the slope m solving 180·1 + 2·(180 + 180)·m + 180·1 =
3·(180·2/3 + 180·2/3), m = 1/2: the knife slows to half the conveyor's speed between
cuts. MAPC is incremental and Continuous: each pass adds 360°, the knife turns once per
product. Stopping the conveyor (MAS) stops the knife on its cam; MAS Position Cam ends it.
"""

from __future__ import annotations

import itertools
import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Conveyor.CommandPosition",
    "Knife.CommandPosition",
    "Conveyor.CommandVelocity",
    "Knife.CommandVelocity",
    "Knife.MotionStatus",
    "MAPC_Knife.SEGMENT",
]
#: (conveyor mm, knife °, segment type 0 linear / 1 cubic): the table above
POINTS = [(0.0, 0.0, 0), (60.0, 60.0, 1), (240.0, 180.0, 1), (420.0, 300.0, 0), (480.0, 360.0, 0)]
PRODUCT = 480.0  # mm of conveyor per knife turn
SPEED = 400.0  # conveyor, mm/s
POSITION_CAM, POSITION_CAM_LOCK = 1 << 8, 1 << 13  # MotionStatus bits


def hermite(p0: float, p1: float, m0: float, m1: float, h: float, t: float) -> float:
    """The cubic from (0, p0) slope m0 to (h, p1) slope m1 at t = u / h."""
    return (
        (2 * t**3 - 3 * t**2 + 1) * p0
        + (t**3 - 2 * t**2 + t) * h * m0
        + (-2 * t**3 + 3 * t**2) * p1
        + (t**3 - t**2) * h * m1
    )


def knife_angle(c: float) -> float:
    """The knife's travel [°] after ``c`` mm of conveyor since the lock (unwound): the
    table's segments, worked by hand (module docstring), plus 360° per product."""
    k, x = divmod(c, PRODUCT)
    if x <= 60.0:
        f = x
    elif x <= 240.0:
        f = hermite(60.0, 180.0, 1.0, 0.5, 180.0, (x - 60.0) / 180.0)
    elif x <= 420.0:
        f = hermite(180.0, 300.0, 0.5, 1.0, 180.0, (x - 240.0) / 180.0)
    else:
        f = 300.0 + (x - 420.0)
    return 360.0 * k + f


def wrap(angle: float) -> float:
    """An angle difference in (-180, 180]."""
    return angle - 360.0 * round(angle / 360.0)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("MSO_1", Axis=15)
    await sc.trigger("MSO_1", Axis=16)
    # the table through its tags (Modbus: 6 registers per point), then MCCP
    for k, (master, slave, segment) in enumerate(POINTS):
        await sc.write(f"KnifeCam.Master[{k}]", master)
        await sc.write(f"KnifeCam.Slave[{k}]", slave)
        await sc.write(f"KnifeCam.SegmentType[{k}]", segment)
    await sc.write("KnifeCam.Length", len(POINTS))
    await sc.trigger("MCCP_Knife", Length=len(POINTS), StartSlope=0.0, EndSlope=0.0)
    sc.check("profile calculated: Status 2", int(await sc.read("KnifeCam.ProfileStatus")), 2, 0)
    c0 = float(await sc.read("Conveyor.CommandPosition"))
    k0 = float(await sc.read("Knife.CommandPosition"))
    await sc.trigger(
        "MAPC_Knife",
        Direction="SAME",
        ExecutionMode="CONTINUOUS",
        ExecutionSchedule="IMMEDIATE",
        MasterReference="COMMAND",
        SlaveScaling=1.0,
        MasterScaling=1.0,
        CamLockPosition=0.0,
    )
    sc.check(
        "profile in use by 1 cam: Status 3", int(await sc.read("KnifeCam.ProfileStatus")), 3, 0
    )
    status = int(await sc.read("Knife.MotionStatus"))
    sc.check("PositionCamLockStatus (bit 13) at once", (status & POSITION_CAM_LOCK) >> 13, 1, 0)
    await sc.trigger("Jog_Conveyor", Speed=SPEED, AccelRate=4000.0, DecelRate=4000.0)
    await sc.run(2.5)  # two products and a bit: about 980 mm
    c = float(await sc.read("Conveyor.CommandPosition")) - c0
    k = float(await sc.read("Knife.CommandPosition"))
    sc.check("past two products [mm]", min(c, 2 * PRODUCT), 2 * PRODUCT)
    sc.check("knife on the cam [°]", wrap(k - k0 - knife_angle(c)), 0.0, 1e-6)
    # the run's samples: the knife turns once per product, at the conveyor's speed in the cut
    t = sc.trace
    conv = t.column("Conveyor.CommandPosition")
    knife = t.column("Knife.CommandPosition")
    vc, vk = t.column("Conveyor.CommandVelocity"), t.column("Knife.CommandVelocity")
    travel = sum(wrap(b - a) for a, b in itertools.pairwise(knife))  # unwound
    sc.check(
        "knife travel [°] = 2 turns for 2 products + f(rest of the third)",
        travel,
        2 * 360.0 + knife_angle(conv[-1] - c0 - 2 * PRODUCT),
        1e-6,
    )
    in_cut = [
        i for i, p in enumerate(conv) if (p - c0) % PRODUCT <= 60.0 or (p - c0) % PRODUCT >= 420.0
    ]
    sc.check(
        "in the cut, knife speed - conveyor speed (largest) [°/s vs mm/s]",
        max(abs(vk[i] - vc[i]) for i in in_cut),
        0.0,
    )
    # stopping the conveyor stops the knife on its cam, still locked
    await sc.trigger("MAS_1", Axis=15, StopType="ALL", ChangeDecel="YES", DecelRate=4000.0)
    await sc.run(0.2)
    c = float(await sc.read("Conveyor.CommandPosition")) - c0
    k = float(await sc.read("Knife.CommandPosition"))
    sc.check("conveyor at rest [mm/s]", float(await sc.read("Conveyor.CommandVelocity")), 0.0)
    sc.check("knife at rest [°/s]", float(await sc.read("Knife.CommandVelocity")), 0.0)
    sc.check("knife still on the cam [°]", wrap(k - k0 - knife_angle(c)), 0.0, 1e-6)
    status = int(await sc.read("Knife.MotionStatus"))
    sc.check("still locked (bit 13)", (status & POSITION_CAM_LOCK) >> 13, 1, 0)
    # MAS Position Cam ends the cam: both bits clear, the profile free (Status 2)
    await sc.trigger("MAS_1", Axis=16, StopType="POSITION_CAM")
    await sc.run(0.02)
    status = int(await sc.read("Knife.MotionStatus"))
    sc.check("cam ended: bits 8 and 13 clear", status & (POSITION_CAM | POSITION_CAM_LOCK), 0, 0)
    sc.check("profile free again: Status 2", int(await sc.read("KnifeCam.ProfileStatus")), 2, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
