"""The first step after a command, alone: thread CPU time of the one ``Controller.step``
that takes a batch of starts or stops into the lanes, the best and the median of
``--repeats`` set-ups (each a fresh controller, set up and run 150 steps as
``kernel_scale.py`` does, the heap frozen before the command).

Cases: ``kernel_scale.py``'s (``accel``, ``clutch``, ``cam``, ``s-curve``, ``stop`` ...:
every master or slave of the group commanded at once) and two where few join many:

- ``few-gears``: masters jogging, all slaves but eight locked to them (``steady``); MAG
  with the clutch on the last eight slaves;
- ``few-cams``: the same, the last eight slaves taking a cam instead (``cam``'s MAPC).

The lanes' bookkeeping in the first step should cost in proportion to what changed:
in the ``few-`` cases, eight followers, not the whole group. Run it from another
checkout with ``PYTHONPATH=<checkout>/server`` to compare versions side by side.

    python bench/first_step.py [--sizes 256 1024] [--cases accel few-gears ...]
        [--repeats 9]
"""

from __future__ import annotations

import argparse
import gc
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import kernel_scale as ks
from motion_server.kernel import Controller, ProcessKind
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterReference, RateRamp

#: slaves left out of the set-up's gearing, commanded in the measured scan
FEW = 8


def few_gears_setup(ctl: Controller) -> None:
    ks.jog(ctl)
    half = len(ctl.axes) // 2
    for k in range(half - FEW):
        _gear(ctl, k, clutch=False)


def few_gears(ctl: Controller) -> None:
    half = len(ctl.axes) // 2
    for k in range(half - FEW, half):
        _gear(ctl, k, clutch=True)


def _gear(ctl: Controller, k: int, clutch: bool) -> None:
    half = len(ctl.axes) // 2
    slave = ctl.axes[half + k]
    term = GearTerm(k + 1, MasterReference.COMMAND, *ks.RATIO)

    def make(v: float, a: float) -> GearProcess:
        ramp = RateRamp(ks.RATE) if clutch else None
        return GearProcess(ctl, slave, (term,), ramp, v, a)

    ctl.start(slave, make, replace=(ProcessKind.GEAR,))


def few_cams(ctl: Controller) -> None:
    """``kernel_scale.cam``'s MAPC on the last ``FEW`` slaves only, one by one."""
    half = len(ctl.axes) // 2
    profile = ks.cam_profile()
    for k in range(half - FEW, half):
        ks.start_cam(ctl, k, profile)


CASES: dict[str, tuple[Callable[[Controller], None], Callable[[Controller], None]]] = {
    **{name: (setup, command) for name, (setup, command, _) in ks.CASES.items()},
    "few-gears": (few_gears_setup, few_gears),
    "few-cams": (few_gears_setup, few_cams),
}


def first_step(case: str, n_axes: int) -> float:
    setup, command = CASES[case]
    ctl = ks.controller(n_axes, True)
    setup(ctl)
    ctl.run(150)
    gc.collect()
    gc.freeze()
    command(ctl)
    c0 = time.thread_time()
    ctl.step()
    cpu = time.thread_time() - c0
    gc.unfreeze()
    return cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", type=int, default=[256])
    ap.add_argument("--cases", nargs="+", default=["accel", "clutch", "cam", "s-curve", "stop"])
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args()
    for n in args.sizes:
        for case in args.cases:
            runs = sorted(first_step(case, n) for _ in range(args.repeats))
            print(
                f"{case:>10} {n:5d} axes  first step best {runs[0] * 1e6:7.0f} us"
                f"  median {statistics.median(runs) * 1e6:7.0f} us"
            )


if __name__ == "__main__":
    main()
