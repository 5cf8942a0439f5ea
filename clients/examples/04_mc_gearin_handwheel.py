"""MC_GearIn on a hand wheel: the servo follows the wheel 1:1 on its actual position.

The seed's FB test: RatioNumerator 1, RatioDenominator 1, MasterValueSource 1 (actual
value); enable the servo with MC_Power, execute MC_GearIn, "turn the hand wheel, and the
servo axis will follow the hand wheel at a 1:1 ratio". The wheel (Axis4, feedback only)
is turned by writing HandWheel.FeedbackInput: forward 20 mm at 100 mm/s, back 15 mm at
50 mm/s. At every sample the slave's command displacement equals the wheel's.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "HandWheel.ActualPosition",
    "PSlave.CommandPosition",
    "PSlave.ActualPosition",
    "HandWheel.ActualVelocity",
    "PSlave.CommandVelocity",
    "GearIn_1.InGear",
]


async def turn(sc: Scenario, start: float, distance: float, speed: float) -> float:
    """Turn the wheel by ``distance`` at ``speed``: one reading every 5 cycles (10 ms)."""
    steps = round(abs(distance) / (speed * 0.01))
    for i in range(1, steps + 1):
        await sc.write("HandWheel.FeedbackInput", start + distance * i / steps)
        await sc.run(0.01)
    return start + distance


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_PSlave", Enable=True)
    wheel0 = float(await sc.read("HandWheel.ActualPosition"))
    await sc.write("HandWheel.FeedbackInput", wheel0)
    await sc.trigger(
        "GearIn_1",
        Master=4,
        Slave=6,
        RatioNumerator=1.0,
        RatioDenominator=1.0,
        MasterValueSource="ACTUAL_VALUE",
        Acceleration=1000.0,
        Deceleration=1000.0,
        Jerk=0.0,
    )
    slave0 = float(await sc.read("PSlave.CommandPosition"))
    wheel = await turn(sc, wheel0, 20.0, 100.0)
    moved = float(await sc.read("PSlave.CommandPosition")) - slave0
    sc.check("slave displacement after +20 mm of wheel [mm]", moved, 20.0)
    wheel = await turn(sc, wheel, -15.0, 50.0)
    await sc.run(0.2)
    moved = float(await sc.read("PSlave.CommandPosition")) - slave0
    sc.check("slave displacement after -15 mm more [mm]", moved, 5.0)
    sc.check(
        "slave actual at rest follows within 1 count [mm]",
        float(await sc.read("PSlave.ActualPosition")) - slave0,
        5.0,
        1e-3,
    )
    sc.check("InGear while the wheel is still", int(await sc.read("GearIn_1.InGear")), 1, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
