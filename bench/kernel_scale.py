"""Kernel step cost for 32, 256 and 1024 axes with half of them geared.

Each case: N/2 virtual masters jogging at constant speed and N/2 servo slaves geared to
them with MAG (real ratio, command reference, clutch disabled), every slave's drive
simulated; one group at a 1 ms coarse update period. The benchmark steps the bare kernel
(``Controller.step``) and prints, per step, the CPU time of the stepping thread (the cost
on one core, which other processes on a shared machine do not inflate) and the wall
time, and the CPU share of the 1 ms period against the target: 256 axes under 25 %.

Each size runs twice in the same process, side by side: with the fast lanes (the
default: steady jogs and locked gears stepped as arrays, ``kernel/lanes.py``) and with
every axis composed in Python (``Controller(lanes=False)``, the reference); the ratio is
the lanes' gain.

    python bench/kernel_scale.py [--cycles 2000]
"""

from __future__ import annotations

import argparse
import statistics
import time

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig

PERIOD = 0.001
TARGET_SHARE = 0.25


def build(n_axes: int, lanes: bool = True) -> MotionSystem:
    half = n_axes // 2
    axes = [
        AxisConfig(k + 1, f"M{k + 1}", AxisType.VIRTUAL, max_velocity=1000.0,
                   max_acceleration=1e5, max_deceleration=1e5)
        for k in range(half)
    ] + [
        AxisConfig(half + k + 1, f"S{k + 1}", AxisType.SERVO, max_velocity=1000.0,
                   max_acceleration=1e5, max_deceleration=1e5, following_error_limit=50.0)
        for k in range(half)
    ]  # fmt: skip
    group = GroupConfig(1, "G", tuple(a.number for a in axes), PERIOD)
    ctl = Controller(axes, [group], lanes=lanes)
    system = MotionSystem(ctl)
    mso = system.add("MSO", "MSO")
    maj = system.add("MAJ", "MAJ", {"Speed": 100.0, "AccelRate": 1e5, "DecelRate": 1e5})
    mag = system.add("MAG", "MAG", {"Ratio": 0.5, "MasterReference": 1, "Clutch": 1})

    def fire(inst: object, **operands: float) -> None:
        inst.inputs.update(operands)  # type: ignore[attr-defined]
        inst.inputs["Execute"] = True  # type: ignore[attr-defined]
        system.cycle()
        inst.inputs["Execute"] = False  # type: ignore[attr-defined]
        system.cycle()

    for a in axes:
        fire(mso, Axis=a.number)
    for k in range(half):
        fire(maj, Axis=k + 1)
        fire(mag, SlaveAxis=half + k + 1, MasterAxis=k + 1)
    # run until every jog is at speed, so the measured steps are steady state
    system.cycle(50)
    assert all(ctl.axis(half + k + 1).active() for k in range(half)), "gearing not active"
    return system


def measure(n_axes: int, cycles: int, lanes: bool) -> tuple[float, float, float]:
    """(mean CPU, p99 CPU, mean wall) seconds per step."""
    ctl = build(n_axes, lanes).ctl
    cpu, wall = [], []
    for _ in range(cycles):
        t0, c0 = time.perf_counter(), time.thread_time()
        ctl.step()
        cpu.append(time.thread_time() - c0)
        wall.append(time.perf_counter() - t0)
    cpu.sort()
    return statistics.fmean(cpu), cpu[int(0.99 * (len(cpu) - 1))], statistics.fmean(wall)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--cycles", type=int, default=2000)
    args = ap.parse_args()
    print(
        f"{'axes':>6} {'geared':>7} {'lanes':>6} {'cpu mean us':>12} {'cpu p99 us':>11} "
        f"{'wall mean us':>13} {'cpu share of 1 ms':>18}"
    )
    for n in (32, 256, 1024):
        means = {}
        for lanes in (False, True):
            mean, p99, wall = measure(n, args.cycles, lanes)
            means[lanes] = mean
            share = mean / PERIOD
            mark = ""
            if n == 256 and lanes:
                mark = "  target < 25 %: " + ("met" if share < TARGET_SHARE else "MISSED")
            print(
                f"{n:>6} {n // 2:>7} {'on' if lanes else 'off':>6} {mean * 1e6:>12.1f} "
                f"{p99 * 1e6:>11.1f} {wall * 1e6:>13.1f} {share:>17.1%}{mark}"
            )
        print(f"{'':>6} lanes cut the step to {means[True] / means[False]:.2f} of the reference")


if __name__ == "__main__":
    main()
