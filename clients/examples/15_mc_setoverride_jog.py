"""MC_SetOverride on a jog of PSlave (Axis6, a servo): the factors act on the running
motion.

MC_MoveVelocity runs PSlave at 100 mm/s (1000 mm/s²). VelFactor 0.5 brings it down to
50 mm/s in 50/1000 = 0.05 s; VelFactor 0 brings it to rest in another 0.05 s without
changing its state (still ContinuousMotion, the jog still Busy); VelFactor 1 with
AccFactor 0.5 brings it back to 100 mm/s at 500 mm/s², in 0.2 s. Enable low ends the
override; MC_Halt stops the axis.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "PSlave.CommandVelocity",
    "PSlave.PLCopenState",
    "Override_PSlave.VelFactor",
    "Override_PSlave.AccFactor",
    "Override_PSlave.Enabled",
]


async def velocity(sc: Scenario) -> float:
    return float(await sc.read("PSlave.CommandVelocity"))


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_PSlave", Enable=True)
    await sc.trigger("Velocity_PSlave", Velocity=100.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.run(0.2)
    sc.check("jog [mm/s]", await velocity(sc), 100.0)
    await sc.trigger("Override_PSlave", VelFactor=0.5, AccFactor=1.0, JerkFactor=1.0)
    await sc.run(0.1)
    sc.check("VelFactor 0.5 [mm/s]", await velocity(sc), 50.0)
    await sc.write("Override_PSlave.VelFactor", 0.0)
    await sc.run(0.1)
    sc.check("VelFactor 0: at rest [mm/s]", await velocity(sc), 0.0)
    sc.check("still ContinuousMotion", int(await sc.read("PSlave.PLCopenState")), 7, 0)
    sc.check("the jog still Busy", int(await sc.read("Velocity_PSlave.Busy")), 1, 0)
    await sc.write("Override_PSlave.AccFactor", 0.5)
    await sc.write("Override_PSlave.VelFactor", 1.0)
    await sc.run(0.1)
    sc.check("half way up at 500 mm/s² [mm/s]", await velocity(sc), 50.0, 1.0 + 1e-9)
    await sc.run(0.2)
    sc.check("100 mm/s again [mm/s]", await velocity(sc), 100.0)
    await sc.write("Override_PSlave.Enable", False)
    await sc.trigger("Halt_PSlave", Deceleration=1000.0)
    await sc.run(0.05)
    sc.check("halted [mm/s]", await velocity(sc), 0.0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
