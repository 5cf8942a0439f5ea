"""The frame of a runnable example: arguments, connection, manual clock, checks, outputs.

An example is an ``async def body(sc: Scenario)`` that triggers instructions, advances
time while recording a trace, and states what it checks with :meth:`Scenario.check`.
:func:`run_example` parses the command line (``--host``, ``--port``, ``--map``, output
folder), switches the server to the manual clock for a reproducible trace (and back
afterwards), writes ``<name>.csv`` and ``<name>.png`` and returns 0 when every check held.
"""

from __future__ import annotations

import argparse
import asyncio
import tempfile
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .client import MotionClient, Outcome
from .plot import plot_trace
from .tagmap import ClientMap, Value
from .trace import Recorder, Trace


class ScenarioError(AssertionError):
    """An instruction of the scenario did not end as the scenario needs."""


@dataclass(frozen=True)
class Check:
    what: str
    actual: float
    expected: float
    tolerance: float

    @property
    def ok(self) -> bool:
        return abs(self.actual - self.expected) <= self.tolerance

    def __str__(self) -> str:
        mark = "ok  " if self.ok else "FAIL"
        expected = f"{self.expected:.9g} ± {self.tolerance:g}"
        return f"  {mark} {self.what}: {self.actual:.9g} (expected {expected})"


class Scenario:
    """What an example body works with: the client, the recorder, and its checks."""

    def __init__(self, name: str, mc: MotionClient, tags: Sequence[str], every: int) -> None:
        self.name = name
        self.mc = mc
        self.rec = Recorder(mc, tags)
        self.every = every
        self.checks: list[Check] = []

    @property
    def trace(self) -> Trace:
        return self.rec.trace

    async def trigger(
        self, instance: str, *, expect_ok: bool = True, **operands: object
    ) -> Outcome:
        """Trigger, print the outcome, sample once; a surprise ends the scenario."""
        out = await self.mc.trigger(instance, **operands)  # type: ignore[arg-type]
        print(f"  {out}")
        if out.ok != expect_ok:
            raise ScenarioError(f"{self.name}: {out}")
        await self.rec.sample()
        return out

    async def clean_start(self, instance: str = "CleanStart") -> None:
        """Bring the axes to rest first (an MGS instance of the site map, waited to PC),
        so an example behaves the same on a fresh server and after other examples."""
        out = await self.mc.trigger(instance, until=("PC",), timeout=10.0)
        if not out.ok:
            raise ScenarioError(f"{self.name}: clean start: {out}")
        await self.rec.sample()

    async def run(self, seconds: float) -> None:
        """Advance simulated time, sampling every ``every`` cycles."""
        await self.rec.run(seconds, every=self.every)

    async def read(self, name: str) -> Value:
        return await self.mc.read(name)

    async def write(self, name: str, value: Value | str) -> None:
        await self.mc.write(name, value)

    def say(self, text: str) -> None:
        print(text)

    def check(self, what: str, actual: float, expected: float, tolerance: float = 1e-9) -> bool:
        c = Check(what, float(actual), float(expected), tolerance)
        self.checks.append(c)
        print(c)
        return c.ok


Body = Callable[[Scenario], Awaitable[None]]


def parser(name: str, doc: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=name, description=doc)
    p.add_argument("out", nargs="?", help="output folder (default: a new temporary folder)")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, help="server port (default: the protocol's)")
    p.add_argument("--protocol", default="modbus")
    p.add_argument("--map", help="JSON map export or site map TOML (default: bench.toml)")
    p.add_argument("--user", help="OPC UA user name")
    p.add_argument("--password", help="OPC UA password")
    p.add_argument("--security", default="Basic256Sha256", help="OPC UA: Basic256Sha256 or None")
    p.add_argument("--cert-dir", help="OPC UA: folder of the client certificate")
    return p


def options(args: argparse.Namespace) -> dict[str, object]:
    """Back-end options from the command line (OPC UA's; Modbus ignores them)."""
    return {
        "user": args.user,
        "password": args.password,
        "security": args.security,
        "cert_dir": args.cert_dir,
    }


async def _run(
    args: argparse.Namespace, name: str, tags: Sequence[str], body: Body, every: int, out: Path
) -> int:
    tagmap = ClientMap.load(args.map)
    mc_ = MotionClient.connect(tagmap, args.protocol, args.host, args.port, **options(args))
    async with mc_ as mc:
        previous = await mc.clock_mode()
        await mc.set_manual()
        sc = Scenario(name, mc, tags, every)
        try:
            await body(sc)
        finally:
            if previous != "MANUAL":
                await mc.set_clock_mode(previous)
    csv_path = sc.trace.write_csv(out / f"{name}.csv")
    png_path = plot_trace(sc.trace, out / f"{name}.png", title=name)
    failed = [c for c in sc.checks if not c.ok]
    print(f"{name}: {len(sc.checks) - len(failed)}/{len(sc.checks)} checks ok")
    print(f"  trace {csv_path}\n  plot  {png_path}")
    return 1 if failed or not sc.checks else 0


def run_example(
    file: str,
    doc: str,
    tags: Sequence[str],
    body: Body,
    argv: Sequence[str] | None = None,
    every: int = 5,
    defaults: dict[str, object] | None = None,
) -> int:
    """Run one example script: ``file`` is its ``__file__`` (its name names the outputs);
    ``defaults`` sets argument defaults (example 10: OPC UA and the bench user)."""
    name = Path(file).stem
    p = parser(name, doc)
    p.set_defaults(**(defaults or {}))
    args = p.parse_args(argv)
    if args.map is None:
        args.map = str(Path(file).with_name("bench.toml"))
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix=f"{name}-"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"{name}: {doc.strip().splitlines()[0]}")
    return asyncio.run(_run(args, name, tags, body, every, out))
