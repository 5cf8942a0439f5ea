"""MGS with Stop Mode 'programmed': each axis of the group stops by its own configured mode.

Group StopBench holds five servo axes, one per programmed stop mode of the seed (fast
stop, fast disable, hard disable, fast shutdown, hard shutdown), each jogging at
V = 100 mm/s; maximum deceleration D = 2000 mm/s², coast deceleration C = 500 mm/s².
- fast stop / fast disable / fast shutdown: a trapezoidal ramp at D, at rest after
  V/D = 50 ms (25 cycles) and V²/(2D) = 2.5 mm; then Servo Control (2), Axis Ready (0),
  Axis Shutdown (4) respectively;
- hard disable / hard shutdown: the drive goes off at once and the axis coasts at C: at
  rest within V/C = 0.2 s; Axis Ready (0) and Axis Shutdown (4).
MGS sets DN when initiated, IP until every axis is at rest, then PC.
"""

from __future__ import annotations

import sys

from motion_clients.scenario import Scenario, run_example

AXES = {
    10: "FastStop",
    11: "FastDisable",
    12: "HardDisable",
    13: "FastShutdown",
    14: "HardShutdown",
}
FINAL_STATE = {10: 2, 11: 0, 12: 0, 13: 4, 14: 4}
TAGS = [
    *(f"{name}.CommandPosition" for name in AXES.values()),
    *(f"{name}.ActualVelocity" for name in AXES.values()),
    *(f"{name}.AxisState" for name in AXES.values()),
    "MGS_1.IP",
    "MGS_1.PC",
]
V, D = 100.0, 2000.0


async def body(sc: Scenario) -> None:
    # a shut-down axis from an earlier run needs MGSR first (Axis Ready), then MSO
    await sc.trigger("MGSR_1", Group=2)
    for n in AXES:
        await sc.trigger("MSO_1", Axis=n)
    for n in AXES:
        await sc.trigger(
            f"Jog{n}", Speed=V, AccelRate=1000.0, DecelRate=1000.0, Profile=0, SpeedUnits=0
        )
    await sc.run(0.3)  # up to speed after 0.1 s, then the drives settle
    start = {n: float(await sc.read(f"{AXES[n]}.CommandPosition")) for n in AXES}
    await sc.trigger("MGS_1", Group=2, StopMode="PROGRAMMED")
    sc.check("IP after initiation", int(await sc.read("MGS_1.IP")), 1, 0)
    await sc.run(0.3)
    for n in (10, 11, 13):
        moved = float(await sc.read(f"{AXES[n]}.CommandPosition")) - start[n]
        # once a drive is off its command follows the actual position (to within a count)
        tol = 1e-9 if FINAL_STATE[n] == 2 else 1e-3
        sc.check(f"{AXES[n]}: ramp distance V²/2D [mm]", moved, V * V / (2 * D), tol)
    for n, name in AXES.items():
        sc.check(f"{name}: AxisState", int(await sc.read(f"{name}.AxisState")), FINAL_STATE[n], 0)
        sc.check(f"{name}: at rest [mm/s]", float(await sc.read(f"{name}.ActualVelocity")), 0.0)
    sc.check("PC once all stopped", int(await sc.read("MGS_1.PC")), 1, 0)
    sc.check("IP cleared", int(await sc.read("MGS_1.IP")), 0, 0)


def main(argv: list[str] | None = None) -> int:
    return run_example(__file__, __doc__ or "", TAGS, body, argv)


if __name__ == "__main__":
    sys.exit(main())
