"""What instances that only wait cost a cycle: 256 axes, one instance per axis.

An instance whose motion runs, or whose PLCopen outputs are held by a high Execute, has
nothing to do until its process ends or an operand is written. This script measures the
CPU time of ``MotionSystem.cycle`` (instances and kernel, nothing published) per cycle
on a controller of 256 axes (128 virtual, 128 servo, one group at 1 ms), one instance
per axis with its trigger held high, in four scenes:

- ``maj``: MAJ jogging every axis at 100 mm/s (in process, IP);
- ``move``: MC_MoveAbsolute to 1,000 mm at 100 mm/s on every axis (Busy);
- ``done``: MC_MoveRelative of 5 mm on every axis, done (Done held by Execute);
- ``velocity``: MC_MoveVelocity at 100 mm/s on every axis (InVelocity);
- ``gear``: the 128 virtual axes jogging at 100 mm/s (kernel jogs, no instance), an
  MC_GearIn (ratio 1:2) on each servo axis to its master (InGear);
- ``idle``: the same axes, no instance triggered (the floor).

Median over ``--cycles`` cycles after the scene is set up. Run it with
``PYTHONPATH=<checkout>/server`` to compare versions side by side.

    python bench/waiting_instances.py [--cycles 300] [--scenes maj move done velocity gear idle]
"""

from __future__ import annotations

import argparse
import gc
import os
import statistics
import time
from typing import Any

from motion_server.instructions import MotionSystem
from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig, Limits

AXES = 256
RATE = 1000.0
#: scene -> (instance type, operands of the instance on axis k, cycles to set it up)
SCENES: dict[str, tuple[str | None, dict[str, Any], int]] = {
    "maj": ("MAJ", {"Speed": 100.0, "AccelRate": RATE, "DecelRate": RATE}, 200),
    "move": ("MC_MoveAbsolute", {"Position": 1000.0, "Velocity": 100.0,
                                 "Acceleration": RATE, "Deceleration": RATE}, 200),
    "done": ("MC_MoveRelative", {"Distance": 5.0, "Velocity": 100.0,
                                 "Acceleration": RATE, "Deceleration": RATE}, 200),
    "velocity": ("MC_MoveVelocity", {"Velocity": 100.0, "Acceleration": RATE,
                                     "Deceleration": RATE}, 200),
    "gear": ("MC_GearIn", {"RatioNumerator": 1.0, "RatioDenominator": 2.0,
                           "Acceleration": RATE, "Deceleration": RATE}, 400),
    "idle": (None, {}, 10),
}  # fmt: skip


def controller() -> Controller:
    half = AXES // 2
    axes = [
        AxisConfig(k + 1, f"A{k + 1}", AxisType.VIRTUAL if k < half else AxisType.SERVO,
                   max_velocity=1000.0, max_acceleration=RATE, max_deceleration=RATE,
                   following_error_limit=50.0)
        for k in range(AXES)
    ]  # fmt: skip
    ctl = Controller(axes, [GroupConfig(1, "G", tuple(a.number for a in axes), 0.001)])
    for ax in ctl.axes:
        ctl.servo_on(ax)
    return ctl


def measure(scene: str, cycles: int) -> tuple[float, int]:
    """Median CPU µs per cycle, and how many instances the system still calls."""
    kind, operands, setup = SCENES[scene]
    ctl = controller()
    system = MotionSystem(ctl)
    half = AXES // 2
    if kind == "MC_GearIn":
        ctl.start_jogs(ctl.axes[:half], [100.0] * half, Limits(100.0, RATE, RATE))
        for k in range(1, half + 1):
            inst = system.add(kind, f"I{k}", {})
            inst.inputs.update({"Slave": half + k, "Master": k, **operands})
            inst.inputs[inst.TRIGGER] = True
    elif kind is not None:
        for k in range(1, AXES + 1):
            inst = system.add(kind, f"I{k}", {})
            inst.inputs.update({"Axis": k, **operands})
            inst.inputs[inst.TRIGGER] = True
    system.cycle(setup)
    gc.collect()
    gc.freeze()
    spent = []
    for _ in range(cycles):
        t0 = time.thread_time()
        system.cycle()
        spent.append(time.thread_time() - t0)
    gc.unfreeze()
    return statistics.median(spent) * 1e6, len(system.awake())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=300)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'scene':>9} {'cycle us':>9} {'share of 1 ms':>13} {'called':>7}")
    for scene in args.scenes:
        us, called = measure(scene, args.cycles)
        print(f"{scene:>9} {us:>9.1f} {us / 10:>12.1f}% {called:>7}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
