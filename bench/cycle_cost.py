"""Where a cycle of the demo map goes: CPU time per cycle, in one process, no sockets.

``fast_clock.py`` measures what users see (simulated seconds per wall second over
Modbus). This script takes the scan apart in-process (``Scan`` on the embedded demo map,
the manual clock, nothing served) to show where that time goes, for two scenes of
``fast_clock.py``:

- ``idle``: nothing enabled, nothing moving;
- ``moving``: Axis1 (virtual) jogging at 100 mm/s, Axis2 (servo) geared to it by MAG
  (ratio 0.5, actual position of the master).

For each scene, CPU time (``time.process_time``) per cycle, the best of ``--rounds``
windows of ``--seconds`` each:

- ``fast clock``: ``Scan.service`` with the fast clock (cycles back to back, the image
  published about every millisecond): what the scan process spends per cycle;
- ``cycle``: one cycle of the scan (watchdogs, instances, kernel) without publishing;
- ``kernel``: ``Controller.step`` alone;
- ``publish``: filling and publishing the image once after 25 cycles, per publish.

``--scenes idle-256 moving-256``: the same on ``worst_cycle.py``'s map (256 virtual axes in
one group at 1 ms, 259 instances, a watchdog), idle (nothing enabled) and with every axis
jogging at 20 mm/s; in real time at 1 ms every cycle is published, so there ``cycle`` +
``publish`` is what a cycle costs the scan.

The × real time column is the period (2 ms, 1 ms for the 256-axis map) over the CPU
time. Run it from another checkout with ``PYTHONPATH=<checkout>/server`` to compare
versions side by side.

    python bench/cycle_cost.py [--seconds 1] [--rounds 5] [--scenes idle moving ...]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import worst_cycle
from motion_server import config
from motion_server.config import load
from motion_server.scan import Scan
from motion_server.tagmap import ClockMode

PUBLISH_EVERY = 25
SCENES = ["idle", "moving", "idle-256", "moving-256"]


def build(scene: str) -> Scan:
    """The scan of ``scene``'s map, with the manual clock, set up for it."""
    if scene.endswith("-256"):
        return build_256(scene)
    scan = Scan(load(None, {}), fresh=True)
    system = scan.system

    def trigger(name: str, **operands: object) -> None:
        inst = system[name]
        inst.inputs.update(operands)
        for level, cycles in ((False, 1), (True, 3), (False, 1)):
            inst.inputs[inst.TRIGGER] = level
            scan.cycle(cycles)
        if inst.outputs.get("ER"):
            raise SystemExit(f"{name}: ERR {inst.outputs.get('ERR')}")

    if scene == "moving":
        trigger("MSO_1", Axis=1)
        trigger("MSO_1", Axis=2)
        trigger("MAJ_1", Axis=1, Speed=100.0, AccelRate=10000.0, DecelRate=10000.0)
        trigger("MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5, MasterReference=0, Clutch=1)
        scan.cycle(100)
    return scan


def build_256(scene: str) -> Scan:
    """``worst_cycle.py``'s map (256 virtual axes at 1 ms, 259 instances, a watchdog), with
    the manual clock; ``moving-256``: every axis enabled and jogging at 20 mm/s."""
    text = worst_cycle.site_text().replace('clock = "realtime"', 'clock = "manual"')
    scan = Scan(config.parse(text, "worst_cycle.toml"), fresh=True)
    if scene == "moving-256":
        system = scan.system
        for name in ("MSO_ALL", "MAJ_ALL"):
            inst = system[name]
            for axis in range(1, worst_cycle.AXES + 1):
                inst.inputs["Axis"] = axis
                for level in (True, False):
                    inst.inputs[inst.TRIGGER] = level
                    scan.cycle(1)
                if inst.outputs.get("ER"):
                    raise SystemExit(f"{name} on axis {axis}: ERR {inst.outputs.get('ERR')}")
        scan.cycle(100)
    return scan


def batch(scan: Scan) -> Any:
    """The kernel's batch of steps (numpy's error state set once) where it has one."""
    enter = getattr(scan.ctl, "batch", None)
    return enter() if enter is not None else contextlib.nullcontext()


def best(run: Callable[[], int], seconds: float, rounds: int) -> float:
    """Least CPU seconds per unit over ``rounds`` windows; ``run`` returns its units."""
    out = float("inf")
    for _ in range(rounds):
        units = 0
        t0 = time.process_time()
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            units += run()
        out = min(out, (time.process_time() - t0) / units)
    return out


def measure(scene: str, seconds: float, rounds: int) -> dict[str, float]:
    scan = build(scene)
    ctl = scan.ctl
    scan.start(time.monotonic())
    scan.set_mode(ClockMode.FAST)

    def fast() -> int:
        tick = ctl.tick
        scan.service(time.monotonic())
        return ctl.tick - tick

    def cycles() -> int:
        with batch(scan):
            for _ in range(100):
                scan._run_cycle()
        return 100

    def steps() -> int:
        with batch(scan):
            for _ in range(100):
                ctl.step()
        return 100

    def publishes() -> int:
        with batch(scan):
            for _ in range(PUBLISH_EVERY):
                scan._run_cycle()
        t0 = time.process_time()
        scan._publish()
        publish_cpu.append(time.process_time() - t0)
        return 1

    publish_cpu: list[float] = []
    out = {
        "fast clock": best(fast, seconds, rounds),
        "cycle": best(cycles, seconds, rounds),
        "kernel": best(steps, seconds, rounds),
    }
    best(publishes, seconds, 1)
    publish_cpu.sort()
    out["publish"] = publish_cpu[len(publish_cpu) // 2]  # the median: one call is timed
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=1.0, help="length of one window")
    ap.add_argument("--rounds", type=int, default=5, help="windows; the best is kept")
    ap.add_argument("--scenes", nargs="+", default=["idle", "moving"], choices=SCENES)
    args = ap.parse_args()
    print("load average before: " + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    print(f"{'scene':10s} {'part':11s} {'us/cycle':>9s} {'x real time':>12s}")
    for scene in args.scenes:
        period = 0.001 if scene.endswith("-256") else 0.002
        figures = measure(scene, args.seconds, args.rounds)
        for part, cpu in figures.items():
            us = cpu * 1e6
            if part == "publish":
                print(f"{scene:10s} {part:11s} {us:9.1f}   (per publish)")
            else:
                print(f"{scene:10s} {part:11s} {us:9.1f} {period / cpu:11.1f}x")
    print("load average after:  " + " ".join(f"{x:.2f}" for x in os.getloadavg()))


if __name__ == "__main__":
    main()
