"""What a snapshot costs: the scan's memory under a steady write load, and the time a
save and a restore take (and how many 2 ms cycles that is) after a long history, on the
demo map and on a generated map of 256 axes.

Runs in one process on the scan's own code (:class:`motion_server.runtime.Runtime`, the
manual clock): ``--writes`` client writes, one per cycle, for the memory (VmRSS and the
Python heap); then ``--history`` cycles with a client write every 10 cycles, a save and a
restore, timed. A restore in the scan's process reads and checks the file off the cycle;
the figure here is the whole of it (read, verify, unpickle, swap in), so it bounds what
the cycle sees.

    python bench/snapshot_cost.py [--writes 20000] [--history 30000]
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import time
import tracemalloc
from pathlib import Path

from motion_server import config
from motion_server.runtime import Runtime


def rss_kib() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def big_site(axes: int) -> str:
    lines = ["[site]\nname = 'big'\n[controller]\nclock = 'manual'\nstatus_log_interval = 0.0\n"]
    lines.append("[instructions]\nevery_type = true\n[modbus]\nport = 0\naxis_base = 4000\n")
    for i in range(axes):
        lines.append(
            f'[[axes]]\nname = "Axis{i + 1}"\ntype = "virtual"\nmax_velocity = 500.0\n'
            "max_acceleration = 5000.0\nmax_deceleration = 5000.0\n"
        )
    names = ", ".join(f'"Axis{i + 1}"' for i in range(axes))
    lines.append(f'[[groups]]\nname = "Group1"\naxes = [{names}]\n')
    return "\n".join(lines)


def runtime(kind: str, data: Path) -> Runtime:
    if kind == "demo":
        site = config.load(None)
    else:
        path = data / "big.toml"
        path.write_text(big_site(256))
        site = config.load(path, environ={})
    ctl = site.controller.model_copy(update={"clock": "manual", "status_log_interval": 0.0})
    return Runtime(site.model_copy(update={"controller": ctl, "data_dir": str(data)}))


def start_motion(rt: Runtime) -> None:
    """Enable and jog every axis that can move (client writes, as an HMI makes them)."""
    for ax in rt.ctl.axes:
        if ax.type.name == "FEEDBACK_ONLY":
            continue
        rt.image.write_many([("MSO_1.Axis", ax.number), ("MSO_1.Execute", True)])
        rt.cycle(1)
        rt.image.write("MSO_1.Execute", False)
        rt.image.write_many(
            [("MAJ_1.Axis", ax.number), ("MAJ_1.Speed", 10.0), ("MAJ_1.AccelRate", 100.0),
             ("MAJ_1.DecelRate", 100.0), ("MAJ_1.Execute", True)]
        )  # fmt: skip
        rt.cycle(1)
        rt.image.write("MAJ_1.Execute", False)


def memory(kind: str, writes: int) -> str:
    with tempfile.TemporaryDirectory() as d:
        rt = runtime(kind, Path(d))
        start_motion(rt)
        rt.cycle(100)
        gc.collect()
        tracemalloc.start()
        heap0, _ = tracemalloc.get_traced_memory()
        rss0 = rss_kib()
        for n in range(writes):
            rt.image.write("MAJ_1.Speed", float(n % 7))
            rt.cycle(1)
        gc.collect()
        heap1, _ = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        rss1 = rss_kib()
    return (
        f"{kind}: {writes} writes: Python heap +{(heap1 - heap0) / 1024:.0f} KiB, "
        f"RSS +{rss1 - rss0} KiB"
    )


def restore(kind: str, history: int) -> str:
    with tempfile.TemporaryDirectory() as d:
        rt = runtime(kind, Path(d))
        start_motion(rt)
        for n in range(history // 10):
            rt.image.write("MAJ_1.Speed", float(n % 7 + 1))
            rt.cycle(10)
        t0 = time.perf_counter()
        path = rt.scan.save_snapshot("1")
        saved = time.perf_counter() - t0
        size = path.stat().st_size
        rt.cycle(10)
        t0 = time.perf_counter()
        rt.scan.restore_snapshot("1")
        restored = time.perf_counter() - t0
        period = rt.period
        swap = ""
        if hasattr(rt.scan, "_prepare"):  # the state design: only the swap is in the cycle
            from motion_server.scan import snapshots

            rt.cycle(10)
            ready = rt.scan._prepare(snapshots.load(rt.site, rt.layout, "1"))
            t0 = time.perf_counter()
            rt.scan._swap(ready, t0)
            swap = f"; in the cycle: {(time.perf_counter() - t0) * 1000:.2f} ms"
    return (
        f"{kind}: after {history} cycles: file {size / 1024:.0f} KiB, save {saved * 1000:.1f} "
        f"ms, restore {restored * 1000:.1f} ms = {restored / period:.0f} cycles of "
        f"{period * 1000:.0f} ms{swap}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--writes", type=int, default=20000)
    parser.add_argument("--history", type=int, default=30000)
    args = parser.parse_args()
    for kind in ("demo", "256 axes"):
        print(memory(kind, args.writes), flush=True)
        print(restore(kind, args.history), flush=True)


if __name__ == "__main__":
    main()
