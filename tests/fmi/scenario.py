"""One scenario run three ways: a gear-in, then a group stop, on the demo map.

Axis1 (virtual master) is enabled by MC_Power_1 and Axis2 (servo) switched on by MSO_1;
Axis1 jogs at 100 mm/s, MAG_1 gears Axis2 to it at 0.5, and MGS_1 stops the group with
each axis's programmed stop. The same writes at the same cycles go to the FMU (through a
master) and to a served controller (over Modbus with the manual clock); the traces must
be equal bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

PERIOD = 0.002  # the demo map's coarse update period
CYCLES = 200

#: operands, set before the first cycle (FMU: start values; Modbus: one write)
OPERANDS: dict[str, Any] = {
    "MC_Power_1.Axis": 1,
    "MC_Power_1.EnablePositive": True,
    "MC_Power_1.EnableNegative": True,
    "MSO_1.Axis": 2,
    "MAJ_1.Axis": 1,
    "MAJ_1.Direction": 0,
    "MAJ_1.Speed": 100.0,
    "MAJ_1.SpeedUnits": 0,
    "MAJ_1.AccelRate": 2000.0,
    "MAJ_1.AccelUnits": 0,
    "MAJ_1.DecelRate": 2000.0,
    "MAJ_1.DecelUnits": 0,
    "MAJ_1.Profile": 0,
    "MAG_1.SlaveAxis": 2,
    "MAG_1.MasterAxis": 1,
    "MAG_1.Direction": 0,
    "MAG_1.Ratio": 0.5,
    "MAG_1.RatioFormat": 0,
    "MAG_1.MasterReference": 1,
    "MAG_1.Clutch": 1,
    "MGS_1.Group": 1,
    "MGS_1.StopMode": 0,
}

#: (cycles run before the write, trigger): each goes true before that cycle
TRIGGERS: list[tuple[int, str]] = [
    (1, "MC_Power_1.Enable"),
    (2, "MSO_1.Execute"),
    (10, "MAJ_1.Execute"),
    (30, "MAG_1.Execute"),
    (120, "MGS_1.Execute"),
]

#: what is compared (after every cycle)
RECORD = [
    "Axis1.CommandPosition",
    "Axis1.ActualPosition",
    "Axis2.CommandPosition",
    "Axis2.ActualPosition",
    "Axis2.ActualVelocity",
    "MAG_1.IP",
    "MGS_1.IP",
    "MGS_1.PC",
    "Clock.Cycle",
]


def fmpy_input() -> np.ndarray:
    """The triggers as an fmpy input signal: each rises at the communication point where
    it is set (fmpy steps to every time an input changes: a time off the grid would be a
    step of part of a period)."""
    names = [name for _, name in TRIGGERS]
    dtype = [("time", float)] + [(n, bool) for n in names]
    rows = [tuple([0.0] + [False] * len(names))]
    for cycle, _ in TRIGGERS:
        row = [cycle * PERIOD] + [c <= cycle for c, _ in TRIGGERS]
        rows.append(tuple(row))
    return np.array(rows, dtype=dtype)


def trace_of(rows: list[dict[str, Any]]) -> dict[str, list[Any]]:
    return {name: [row[name] for row in rows] for name in RECORD}
