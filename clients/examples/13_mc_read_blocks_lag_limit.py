"""PLCopen status and parameter blocks on PSlave (Axis6, a servo): MC_ReadStatus,
MC_ReadAxisError, MC_ReadActualVelocity, MC_ReadParameter, MC_WriteParameter and
MC_WriteBoolParameter.

The read blocks are Enable-style: triggered once, Enable stays high and they read every
cycle. Parameter 7 (MaxPositionLag) is the following error limit, off (0) on the bench.
PSlave's drive follows its command with bandwidth ω = 2π · 40 rad/s, so at a steady
100 mm/s its following error is 2v/ω = 0.796 mm: with the limit written to 1.2 mm the
move runs (ContinuousMotion); written to 0.5 mm with the monitoring switched off
(parameter 6 EnablePosLagMonitoring FALSE, MC_WriteBoolParameter) it runs on; switched
on again, the axis faults at once (ErrorStop, AxisErrorID 1: bit 0, position error).
The limit goes back to 0, MC_Reset and MC_Power bring the axis back to StandStill.
"""

from __future__ import annotations

import math
import sys

from motion_clients.scenario import Scenario, run_example

TAGS = [
    "PSlave.CommandVelocity",
    "PSlave.ActualVelocity",
    "Status_PSlave.ContinuousMotion",
    "Status_PSlave.ErrorStop",
    "AxisError_PSlave.AxisErrorID",
    "LagLimit_PSlave.Value",
]
READERS = ("Status_PSlave", "AxisError_PSlave", "Velocity_Read_PSlave", "LagLimit_PSlave")


async def body(sc: Scenario) -> None:
    await sc.clean_start()
    await sc.trigger("Power_PSlave", Enable=True)
    for name in READERS:
        await sc.trigger(name)  # waits for Valid; Enable stays high
    sc.check("StandStill", int(await sc.read("Status_PSlave.Standstill")), 1, 0)
    sc.check("no axis error", int(await sc.read("AxisError_PSlave.AxisErrorID")), 0, 0)
    sc.check("MaxPositionLag off [mm]", float(await sc.read("LagLimit_PSlave.Value")), 0.0)
    await sc.trigger("WriteParameter_PSlave", Value=1.2)
    sc.check("MaxPositionLag read back [mm]", float(await sc.read("LagLimit_PSlave.Value")), 1.2)
    await sc.trigger("Velocity_PSlave", Velocity=100.0, Acceleration=1000.0, Deceleration=1000.0)
    await sc.run(0.5)
    sc.check("ContinuousMotion", int(await sc.read("Status_PSlave.ContinuousMotion")), 1, 0)
    sc.check(
        "MC_ReadActualVelocity [mm/s]",
        float(await sc.read("Velocity_Read_PSlave.Velocity")),
        100.0,
        1e-6,
    )
    # the actual position is read in encoder counts (1000 per mm): within one count
    sc.check(
        "following error 2v/ω [mm], under the 1.2 mm limit",
        float(await sc.read("PSlave.CommandPosition"))
        - float(await sc.read("PSlave.ActualPosition")),
        2 * 100.0 / (2 * math.pi * 40.0),
        1e-3,
    )
    await sc.trigger("LagWatch_PSlave", Value=False)  # the monitoring off, the limit kept
    await sc.trigger("WriteParameter_PSlave", Value=0.5)
    await sc.run(0.05)
    sc.check("no ErrorStop, monitoring off", int(await sc.read("Status_PSlave.ErrorStop")), 0, 0)
    await sc.trigger("LagWatch_PSlave", Value=True)
    await sc.run(0.01)
    sc.check("ErrorStop", int(await sc.read("Status_PSlave.ErrorStop")), 1, 0)
    sc.check(
        "AxisErrorID: bit 0, position error",
        int(await sc.read("AxisError_PSlave.AxisErrorID")),
        1,
        0,
    )
    # back to a clean bench: the limit off, the fault reset, the power on again
    await sc.trigger("WriteParameter_PSlave", Value=0.0)
    await sc.trigger("Reset_PSlave")
    await sc.trigger("Power_PSlave", Enable=True)
    await sc.run(0.01)
    sc.check("StandStill again", int(await sc.read("Status_PSlave.Standstill")), 1, 0)
    sc.check("no axis error", int(await sc.read("AxisError_PSlave.AxisErrorID")), 0, 0)
    for name in READERS:
        await sc.write(f"{name}.Enable", False)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
