"""Power a servo with MSO, jog it with MAJ, stop it with MAS (Logix, Axis2 'Slave').

Trapezoidal jog at v = 100 mm/s with a = 1000 mm/s²: up to speed after v/a = 0.1 s,
having covered v²/(2a) = 5 mm; MAS with d = 1000 mm/s² stops it within v²/(2d) = 5 mm.
The actual position trails the command through the simulated drive and catches up at rest.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "Slave.CommandPosition",
    "Slave.ActualPosition",
    "Slave.CommandVelocity",
    "Slave.ActualVelocity",
    "MAJ_1.IP",
]
V, A, D = 100.0, 1000.0, 1000.0
#: jog dynamics in units/s and units/s² (operands keep their values between triggers)
TIME_UNITS = dict(SpeedUnits=0, AccelUnits=0, DecelUnits=0)


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("MSO_1", Axis=2)
    sc.check("Slave AxisState (2 = Servo Control)", int(await sc.read("Slave.AxisState")), 2, 0)
    start = float(await sc.read("Slave.CommandPosition"))
    jog = await sc.trigger(
        "MAJ_1",
        Axis=2,
        Direction="FORWARD",
        Speed=V,
        AccelRate=A,
        DecelRate=D,
        Profile=0,
        **TIME_UNITS,
    )
    await sc.run(0.3 - jog.cycles * 0.002)  # 0.3 s of jog in all
    moved = float(await sc.read("Slave.CommandPosition")) - start
    sc.check("jog travel after 0.3 s [mm]: v²/2a + v·(0.3 - v/a)", moved, 5.0 + V * 0.2)
    sc.check("jog speed [mm/s]", float(await sc.read("Slave.CommandVelocity")), V)
    at_stop = float(await sc.read("Slave.CommandPosition"))
    await sc.trigger("MAS_1", Axis=2, StopType="ALL", ChangeDecel="YES", DecelRate=D)
    await sc.run(0.3)
    rest = float(await sc.read("Slave.CommandPosition"))
    sc.check("stopping distance [mm]: v²/2d", rest - at_stop, V * V / (2 * D))
    sc.check("command velocity at rest [mm/s]", float(await sc.read("Slave.CommandVelocity")), 0.0)
    sc.check(
        "actual caught up at rest [mm] (within 1 count)",
        float(await sc.read("Slave.ActualPosition")),
        rest,
        1e-3,
    )


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
