"""Jogs from rest on many axes: one ``Controller.start`` per axis against one
``Controller.start_jogs`` call (as ``kernel_scale.py``'s ``accel`` commands them).

The set-up is ``kernel_scale.py``'s ``accel``: N/2 virtual masters at rest, N/2 servo
slaves geared to them (real ratio 0.5 on the command position), a 1 ms group; the
command is MAJ at 100 mm/s, 1,000 mm/s² on every master. Printed per size, the CPU time
of the stepping thread (median of ``--repeats``) of the command and of the command
cycle (the command and the first step after it), for each way, and whether the two
commanded the same position, velocity and acceleration on every axis after every one
of the 100 steps that follow (exit status 1 if not).

    python bench/start_batch.py [--sizes 256 1024] [--repeats 5]
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import kernel_scale as ks
from motion_server.kernel import Controller, JogProcess, Limits, ProcessKind

STEPS = 100


def one_by_one(ctl: Controller) -> None:
    """MAJ at 100 mm/s on every master, one ``Controller.start`` per axis."""
    for ax in ctl.axes[: len(ctl.axes) // 2]:
        ctl.start(
            ax,
            lambda v, a: JogProcess(ks.PERIOD, ks.SPEED, Limits(ks.SPEED, ks.RATE, ks.RATE), v, a),
            replace=(ProcessKind.JOG,),
        )


def batch(ctl: Controller) -> None:
    """The same jogs in one call."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_jogs(masters, [ks.SPEED] * len(masters), Limits(ks.SPEED, ks.RATE, ks.RATE, 0.0))


def run(n: int, command: Callable[[Controller], None]) -> tuple[float, float, bytes]:
    """(command s, command cycle s, digest of the commands after every step)."""
    ctl = ks.controller(n, True)
    ks.gear(ctl, False)
    ctl.run(150)
    gc.collect()
    gc.freeze()
    c0 = time.thread_time()
    command(ctl)
    c1 = time.thread_time()
    ctl.step()
    c2 = time.thread_time()
    trace = hashlib.blake2b()
    for _ in range(STEPS):
        for arr in (ctl.cmd_pos, ctl.cmd_vel, ctl.cmd_acc):
            trace.update(arr.tobytes())
        ctl.step()
    gc.unfreeze()
    return c1 - c0, c2 - c0, trace.digest()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 1024])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'axes':>5} {'way':>10} {'command us':>10} {'cmd cycle us':>12}")
    failed = False
    for n in args.sizes:
        digests = set()
        for name, command in (("start", one_by_one), ("start_jogs", batch)):
            runs = [run(n, command) for _ in range(args.repeats)]
            digests.update(r[2] for r in runs)
            cmd = statistics.median(r[0] for r in runs)
            cycle = statistics.median(r[1] for r in runs)
            print(f"{n:>5} {name:>10} {cmd * 1e6:>10.0f} {cycle * 1e6:>12.0f}")
        same = len(digests) == 1
        failed |= not same
        print(f"{'':>5} commands identical after every step: {same}")
    print(f"load average {os.getloadavg()[0]:.2f}")
    if failed:
        raise SystemExit("start and start_jogs differ")


if __name__ == "__main__":
    main()
