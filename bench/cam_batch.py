"""Many position cams started in one scan: one ``Controller.start`` per slave against
:func:`~motion_server.kernel.cam_batch.start_position_cams`.

The set-up and the cams are ``kernel_scale.py``'s ``cam`` case (masters jogging at
100 mm/s, MAPC Continuous Immediate on every slave, one 9-point cubic table); the command
cycle is the command and the first step after it, in CPU time of the stepping thread,
lanes on. Both ways must command the same position, velocity and acceleration after
every step (checked; the script fails when they do not)::

    python bench/cam_batch.py [--sizes 256 1024] [--repeats 5] [--steps 50]
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import kernel_scale as ks
from motion_server.kernel import Controller
from motion_server.kernel.cam_batch import CamStart, start_position_cams
from motion_server.kernel.cams import CamMode
from motion_server.kernel.enums import MasterReference


def one_by_one(ctl: Controller) -> None:
    """The ``cam`` case's cams, one ``Controller.start`` per slave."""
    profile = ks.cam_profile()
    for k in range(len(ctl.axes) // 2):
        ks.start_cam(ctl, k, profile)


def batch(ctl: Controller) -> None:
    """The ``cam`` case's cams, handed over as one batch."""
    half = len(ctl.axes) // 2
    profile = ks.cam_profile()
    start_position_cams(
        ctl,
        [
            CamStart(
                ctl.axes[half + k],
                ctl.axes[k],
                profile,
                CamMode.CONTINUOUS,
                1.0,
                ks.CAM_MASTER_SCALING,
                0.0,
                MasterReference.COMMAND,
            )
            for k in range(half)
        ],
    )


def run(n: int, command: object, steps: int) -> tuple[float, float, bytes]:
    ctl = ks.controller(n, True)
    ks.jog(ctl)
    ctl.run(150)
    gc.collect()
    gc.freeze()
    c0 = time.thread_time()
    command(ctl)  # type: ignore[operator]
    c1 = time.thread_time()
    ctl.step()
    c2 = time.thread_time()
    trace = hashlib.blake2b()
    for k in range(steps):
        if k:
            ctl.step()
        for arr in (ctl.cmd_pos, ctl.cmd_vel, ctl.cmd_acc):
            trace.update(arr.tobytes())
    gc.unfreeze()
    return c1 - c0, c2 - c0, trace.digest()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 1024])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=50)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    for n in args.sizes:
        for name, command in (("one by one", one_by_one), ("batch", batch)):
            runs = [run(n, command, args.steps) for _ in range(args.repeats)]
            cmd = statistics.median(r[0] for r in runs) * 1e6
            cycle = statistics.median(r[1] for r in runs) * 1e6
            print(f"{n:>5} axes {name:>10}: command {cmd:7.0f} us, command cycle {cycle:7.0f} us")
            if name == "one by one":
                reference = runs[0][2]
            elif runs[0][2] != reference:
                raise SystemExit(f"{n} axes: the batch commanded other motion")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
