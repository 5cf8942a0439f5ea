"""Traces: tag values sampled against simulated time, written to and read from CSV.

A :class:`Trace` holds columns ``time`` (``Clock.SimTime``, s), ``cycle`` (``Clock.Cycle``)
and one column per tag. :class:`Recorder` fills one from a live server: under the manual
clock it steps ``every`` cycles between samples, so a trace is exactly reproducible.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .client import MotionClient
from .tagmap import Value

CLOCK_COLUMNS = ("time", "cycle")


@dataclass
class Trace:
    """Rows of samples; ``columns`` names them (``time``, ``cycle``, then the tags)."""

    columns: list[str]
    rows: list[list[float]] = field(default_factory=list)
    units: dict[str, str] = field(default_factory=dict)

    def column(self, name: str) -> list[float]:
        try:
            i = self.columns.index(name)
        except ValueError:
            raise KeyError(f"no column {name!r} in the trace ({', '.join(self.columns)})") from None
        return [row[i] for row in self.rows]

    def __len__(self) -> int:
        return len(self.rows)

    def write_csv(self, path: str | Path) -> Path:
        """The CSV file; a second header line gives the units (empty where none)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="", encoding="utf-8") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(self.columns)
            w.writerow(
                ["# units: s" if c == "time" else self.units.get(c, "") for c in self.columns]
            )
            for row in self.rows:
                w.writerow([_cell(v) for v in row])
        return path

    @classmethod
    def read_csv(cls, path: str | Path) -> Trace:
        with Path(path).open(newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            columns = next(reader)
            units_row = next(reader, [])
            trace = cls(columns)
            if units_row and not units_row[0].startswith("# units"):
                trace.rows.append([float(v) for v in units_row])
            else:
                trace.units = {c: u for c, u in zip(columns, units_row, strict=False) if u}
                trace.units.pop("time", None)
            trace.rows += [[float(v) for v in row] for row in reader if row]
        return trace


def _cell(value: float) -> str:
    return str(int(value)) if float(value).is_integer() and abs(value) < 2**53 else repr(value)


def _number(value: Value) -> float:
    return float(int(value)) if isinstance(value, bool) else float(value)


class Recorder:
    """Samples ``tags`` from a client into a :class:`Trace`."""

    def __init__(self, client: MotionClient, tags: Sequence[str]) -> None:
        self.client = client
        self.tags = list(tags)
        for name in self.tags:
            client.map.tag(name)  # fail early on a wrong name
        self.trace = Trace(
            [*CLOCK_COLUMNS, *self.tags],
            units={t: client.map.tag(t).units for t in self.tags if client.map.tag(t).units},
        )

    async def sample(self) -> list[float]:
        names = ["Clock.SimTime", "Clock.Cycle", *self.tags]
        values = await self.client.backend.read([self.client.map.tag(n) for n in names])
        row = [_number(v) for v in values]
        self.trace.rows.append(row)
        return row

    async def run(self, seconds: float, every: int = 5) -> Trace:
        """Advance ``seconds`` of simulated time, sampling every ``every`` cycles."""
        cycles = round(seconds / await self.client.period())
        while cycles > 0:
            n = min(every, cycles)
            await self.client.step(n)
            await self.sample()
            cycles -= n
        return self.trace
