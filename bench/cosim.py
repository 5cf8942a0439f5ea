"""Co-simulation: FMU steps per second against the same stepping over Modbus.

One co-simulation step is one base period (one cycle) the master asks for, then the
positions it reads back: what a master coupling the controller to a plant does every
communication step. Two scenes, as in ``fast_clock.py``:

- ``demo``: the demo map with Axis1 (virtual) jogging at 100 mm/s and Axis2 (servo)
  geared to it (MAG, ratio 0.5); 4 positions read per step;
- ``64-axes``: 32 virtual masters jogging, 32 servo slaves geared to them, one group at
  2 ms; 64 positions read per step.

Each scene two ways, side by side:

- ``fmu``: the FMI 2.0 FMU of the map (``motion-server fmu``), loaded by fmpy's
  ``FMU2Slave`` in this process: ``fmi2DoStep`` of one period, then ``fmi2GetReal`` of
  the axes' ``ActualPosition``;
- ``modbus``: the map served by ``motion-server run --clock manual`` (Modbus only): a
  ``Clock.Step`` of one cycle (answered once it ran), then one read of the same positions.

The motion is set up the same way in both (MSO on every axis, MAJ on every master, MAG
on every slave, then 100 cycles to reach speed) and the positions of the last step are
compared. Target: the FMU at least 3x the steps per second of Modbus (no network in the
loop). The load average is printed before and after (the machine is shared).

    python bench/cosim.py [--fmu-steps 3000] [--modbus-steps 600] [--scenes demo 64-axes]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from fast_clock import PAIRS, jog_and_gear, pairs_map
from motion_server.fmi.build import build_fmu
from motion_server.testing import MotionServer

TARGET = 3.0
PERIOD = 0.002  # both maps' coarse update period
SCENES = {
    "demo": ([1], [2]),
    "64-axes": (list(range(1, PAIRS + 1)), list(range(PAIRS + 1, 2 * PAIRS + 1))),
}


class FmuClient:
    """The FMU through fmpy, with the trigger handshake of ``MotionClient.trigger``."""

    def __init__(self, fmu: Path, unpack: Path) -> None:
        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        extract(str(fmu), str(unpack))
        self.slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=str(unpack),
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName="bench",
        )
        self.slave.instantiate()
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()
        self.time = 0.0

    def set(self, values: dict[str, Any]) -> None:
        for name, value in values.items():
            vr = [self.vr[name]]
            kind = self.types[name]
            if kind == "Boolean":
                self.slave.setBoolean(vr, [bool(value)])
            elif kind == "Real":
                self.slave.setReal(vr, [float(value)])
            else:
                self.slave.setInteger(vr, [int(value)])

    def step(self, cycles: int = 1) -> None:
        for _ in range(cycles):
            self.slave.doStep(self.time, PERIOD)
            self.time += PERIOD

    def trigger(self, instance: str, **operands: Any) -> None:
        self.set({f"{instance}.{k}": v for k, v in operands.items()})
        self.set({f"{instance}.Execute": True})
        self.step(2)
        self.set({f"{instance}.Execute": False})
        self.step(1)

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()


def fmu_setup(c: FmuClient, masters: list[int], slaves: list[int]) -> None:
    """``fast_clock.jog_and_gear`` through the FMU's inputs."""
    for axis in masters + slaves:
        c.trigger("MSO_1", Axis=axis)
    for axis in masters:
        c.trigger("MAJ_1", Axis=axis, Speed=100.0, AccelRate=10000.0, DecelRate=10000.0)
    for slave, master in zip(slaves, masters, strict=True):
        c.trigger("MAG_1", SlaveAxis=slave, MasterAxis=master, Ratio=0.5, MasterReference=0,
                  Clutch=1)  # fmt: skip
    c.step(100)


def run_fmu(fmu: Path, unpack: Path, scene: str, steps: int) -> tuple[float, list[float]]:
    masters, slaves = SCENES[scene]
    c = FmuClient(fmu, unpack)
    try:
        fmu_setup(c, masters, slaves)
        names = [n for n in c.vr if n.endswith(".ActualPosition")]
        vrs = [c.vr[n] for n in names]
        t0 = time.perf_counter()
        for _ in range(steps):
            c.slave.doStep(c.time, PERIOD)
            c.time += PERIOD
            positions = c.slave.getReal(vrs)
        rate = steps / (time.perf_counter() - t0)
        return rate, list(positions)
    finally:
        c.close()


async def modbus_steps(server: MotionServer, scene: str, steps: int) -> tuple[float, list[float]]:
    masters, slaves = SCENES[scene]
    async with server.client(timeout=60.0) as mc:
        await jog_and_gear(mc, masters, slaves)
        names = [t.name for t in mc.map if t.name.endswith(".ActualPosition")]
        t0 = time.perf_counter()
        for _ in range(steps):
            await mc.step(1)
            values = await mc.read_many(names)
        rate = steps / (time.perf_counter() - t0)
        return rate, [float(values[n]) for n in names]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu-steps", type=int, default=3000)
    ap.add_argument("--modbus-steps", type=int, default=600)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    args = ap.parse_args()
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'scene':<9} {'fmu steps/s':>12} {'modbus steps/s':>15} {'ratio':>7} {'target':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "pairs.toml").write_text(pairs_map())
        for scene in args.scenes:
            site = root / "pairs.toml" if scene == "64-axes" else None
            fmu = build_fmu(site, root / f"{scene.replace('-', '_')}.fmu", 2)
            fmu_rate, fmu_end = run_fmu(fmu, root / f"{scene}-unpacked", scene, args.fmu_steps)
            shutil.rmtree(root / f"{scene}-unpacked", ignore_errors=True)
            server = MotionServer.start(root / scene, site, clock="manual", opcua=False)
            try:
                mb_rate, _ = asyncio.run(modbus_steps(server, scene, args.modbus_steps))
            finally:
                server.stop()
            moving = sum(1 for p in fmu_end if p != 0.0)
            ratio = fmu_rate / mb_rate
            print(
                f"{scene:<9} {fmu_rate:12.0f} {mb_rate:15.0f} {ratio:6.1f}x {TARGET:6.0f}x"
                f"   ({moving} of {len(fmu_end)} positions off 0 at the end)"
            )
    print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
