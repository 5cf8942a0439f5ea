"""``MotionClient``: read, write and trigger by tag name, and move the clock.

::

    tagmap = ClientMap.load("maps/demo-map.json")
    async with MotionClient.modbus(tagmap, port=5020) as mc:
        await mc.set_manual()
        out = await mc.trigger("MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5)
        print(out)                       # MAG_1: DN after 1 cycle
        await mc.run_for(0.5)            # 250 cycles of 2 ms, then read
        print(await mc.read("Axis2.CommandPosition"))

The trigger handshake is the one an HMI uses: write the operands, raise the trigger
(``Execute``, or ``Enable`` for MC_Power), wait for the success output (DN for Logix;
Done, InGear, InSync or InVelocity for PLCopen, whichever the block has) or a failure
(ER, Error, CommandAborted), then lower the trigger (not MC_Power's Enable: its falling
edge would switch the drive off).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from .backend import Backend, ClientError, make_backend
from .tagmap import ClientMap, MapTag, Value

#: success outputs, the most specific first (MC_GearInPos has Done and InSync: InSync wins)
SUCCESS = ("InSync", "InGear", "InVelocity", "Done", "DN")
FAILURE = ("ER", "Error", "CommandAborted")
#: a long manual step is cut into requests of this many cycles (each answered when run)
STEP_CHUNK = 5000


class TriggerTimeout(ClientError):
    """The instruction showed neither success nor failure within the timeout."""


@dataclass(frozen=True)
class Outcome:
    """How a triggered instruction ended. ``ok`` when the success output came first."""

    instance: str
    ok: bool
    flag: str  #: the output that ended the wait (DN, ER, InGear, Error, ...)
    code: int  #: ERR / ErrorID
    meaning: str  #: the code's text from the map's error table
    exerr: int | None = None  #: Logix EXERR: the offending operand's index (ERR 13)
    cycles: int = 0  #: cycles waited
    status: dict[str, bool] = field(default_factory=dict)

    def __str__(self) -> str:
        text = f"{self.instance}: {self.flag} after {self.cycles} cycle(s)"
        if not self.ok or self.code:
            text += f", error {self.code}: {self.meaning}"
            if self.exerr is not None and self.code == 13:
                text += f" (EXERR {self.exerr})"
        return text


@dataclass(frozen=True)
class Handshake:
    """The tags of one instance that the trigger handshake uses."""

    trigger: MapTag
    success: tuple[MapTag, ...]
    failure: tuple[MapTag, ...]
    code: MapTag | None
    exerr: MapTag | None

    @property
    def level(self) -> bool:
        """An Enable input stays high after the trigger: MC_Power's falling edge
        disables, the Enable-style read blocks read every cycle while it is high."""
        return self.trigger.field == "Enable"


def handshake(tagmap: ClientMap, instance: str, until: Sequence[str] = ()) -> Handshake:
    tags = {t.field: t for t in tagmap.owned_by(instance)}
    trig = tags.get("Execute") or tags.get("Enable")
    if trig is None:
        raise ClientError(f"{instance} has no Execute or Enable input: not an instruction")
    if until:
        missing = [u for u in until if u not in tags]
        if missing:
            raise ClientError(f"{instance} has no output {', '.join(missing)}")
        success = tuple(tags[u] for u in until)
    elif trig.field == "Enable":
        # MC_Power: Status; MC_SetOverride: Enabled; the Enable-style read blocks
        # (MC_ReadStatus, ...): Valid
        field = next(f for f in ("Status", "Enabled", "Valid") if f in tags)
        success = (tags[field],)
    else:
        success = tuple(tags[s] for s in SUCCESS if s in tags)[:1]
    return Handshake(
        trigger=trig,
        success=success,
        failure=tuple(tags[f] for f in FAILURE if f in tags),
        code=tags.get("ERR") or tags.get("ErrorID"),
        exerr=tags.get("EXERR"),
    )


class MotionClient:
    """Tag-name access to one server through one back-end (``async with`` connects)."""

    def __init__(self, tagmap: ClientMap, backend: Backend) -> None:
        self.map = tagmap
        self.backend = backend
        self._period: float | None = None
        self._step_cycles: int | None = None
        self._modes = tagmap.tag("Clock.Mode").enum
        #: instance -> Clock.Cycle when we lowered its trigger: a new rising edge needs a
        #: scan with the trigger low in between, or the server sees no edge at all
        self._lowered: dict[str, int] = {}

    @classmethod
    def connect(
        cls,
        tagmap: ClientMap,
        protocol: str = "modbus",
        host: str = "127.0.0.1",
        port: int | None = None,
        **options: Any,
    ) -> MotionClient:
        return cls(tagmap, make_backend(protocol, tagmap, host, port, **options))

    @classmethod
    def modbus(cls, tagmap: ClientMap, host: str = "127.0.0.1", port: int | None = None) -> Any:
        return cls.connect(tagmap, "modbus", host, port)

    async def __aenter__(self) -> MotionClient:
        await self.backend.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.backend.close()

    # -- values -----------------------------------------------------------------------------
    async def read(self, name: str) -> Value:
        return (await self.backend.read([self.map.tag(name)]))[0]

    async def read_many(self, names: Sequence[str]) -> dict[str, Value]:
        tags = [self.map.tag(n) for n in names]
        return dict(zip(names, await self.backend.read(tags), strict=True))

    async def write(self, name: str, value: Value | str) -> None:
        tag = self.map.tag(name)
        await self.backend.write(tag, tag.coerce(value))

    async def write_many(self, values: Mapping[str, Value | str]) -> None:
        """Words first, then bits (so a trigger bit never runs ahead of its operands)."""
        tags = [(self.map.tag(n), v) for n, v in values.items()]
        for tag, value in sorted(tags, key=lambda tv: tv[0].type == "BOOL"):
            await self.backend.write(tag, tag.coerce(value))

    # -- clock ------------------------------------------------------------------------------
    async def period(self) -> float:
        """Seconds per cycle (``Clock.Period``)."""
        if self._period is None:
            self._period = float(await self.read("Clock.Period")) / 1000.0
        return self._period

    async def clock_mode(self) -> str:
        mode = int(await self.read("Clock.Mode"))
        return {v: k for k, v in self._modes.items()}.get(mode, str(mode))

    async def set_clock_mode(self, mode: str) -> None:
        await self.write("Clock.Mode", mode.upper())

    async def set_manual(self) -> None:
        await self.set_clock_mode("MANUAL")

    async def cycle(self) -> int:
        return int(await self.read("Clock.Cycle"))

    async def step(self, cycles: int = 1) -> None:
        """Advance ``cycles`` cycles: run them (manual clock) or wait for them (others)."""
        if cycles <= 0:
            return
        if await self.clock_mode() != "MANUAL":
            await self._wait_cycles(cycles)
            return
        while cycles > 0:
            n = min(cycles, STEP_CHUNK)
            if n != self._step_cycles:
                await self.write("Clock.StepCycles", n)
                self._step_cycles = n
            await self.write("Clock.Step", False)
            await self.write("Clock.Step", True)  # answered once the cycles ran
            cycles -= n

    async def run_for(self, seconds: float) -> int:
        """Advance ``seconds`` of simulated time (rounded to whole cycles); the cycle count."""
        cycles = round(seconds / await self.period())
        await self.step(cycles)
        return cycles

    async def _wait_cycles(self, cycles: int) -> None:
        start = await self.cycle()
        pause = max(await self.period() / 2.0, 0.0005)
        while (await self.cycle() - start) % 2**32 < cycles:
            await asyncio.sleep(pause)

    async def _lower(self, instance: str, hs: Handshake) -> None:
        await self.backend.write(hs.trigger, False)
        self._lowered[instance] = await self.cycle()

    # -- instructions -----------------------------------------------------------------------
    async def trigger(
        self,
        instance: str,
        *,
        timeout: float = 5.0,
        until: Sequence[str] = (),
        **operands: Value | str,
    ) -> Outcome:
        """Write ``operands``, raise the trigger, wait for success or failure, lower it.

        ``until`` names other success outputs to wait for (``("PC",)`` for an MGS to
        complete, ``("StartSync",)``). ``timeout`` is in simulated seconds under the manual
        clock, in real seconds otherwise; :class:`TriggerTimeout` names what was seen.
        """
        hs = handshake(self.map, instance, until)
        await self.write_many({f"{instance}.{k}": v for k, v in operands.items()})
        manual = await self.clock_mode() == "MANUAL"
        if await self.backend.read([hs.trigger]) == [True]:
            await self.backend.write(hs.trigger, False)  # a rising edge needs a low scan
            await self.step(1)
        elif instance in self._lowered and await self.cycle() == self._lowered[instance]:
            await self.step(1)  # lowered by our last trigger, not yet scanned low
        self._lowered.pop(instance, None)
        await self.backend.write(hs.trigger, True)
        watched = [*hs.success, *hs.failure]
        extra = [t for t in (hs.code, hs.exerr) if t is not None]
        loop = asyncio.get_running_loop()
        limit = math.ceil(timeout / await self.period()) if manual else 0
        deadline = loop.time() + timeout
        cycles = 0
        # not manual: a cycle may run between our last read and the write; 2 are certain
        await self.step(1 if manual else 2)
        cycles += 1 if manual else 2
        while True:
            values = await self.backend.read([*watched, *extra])
            flags = {t.field: bool(v) for t, v in zip(watched, values, strict=False)}
            hit = next((t.field for t in watched if flags[t.field]), None)
            if hit is not None:
                break
            if (manual and cycles >= limit) or (not manual and loop.time() >= deadline):
                if not hs.level:
                    await self._lower(instance, hs)
                seen = " ".join(f"{k}={int(v)}" for k, v in flags.items())
                clock = "simulated" if manual else "real"
                want = "/".join(t.field for t in hs.success)
                raise TriggerTimeout(
                    f"{instance}: no {want} and no {'/'.join(t.field for t in hs.failure)} "
                    f"within {timeout:g} s ({clock} time, {cycles} cycles); last seen: {seen}"
                )
            await self.step(1)
            cycles += 1
        if not hs.level:
            await self._lower(instance, hs)
        rest = dict(zip([t.field for t in extra], values[len(watched) :], strict=True))
        code = int(rest.get(hs.code.field, 0)) if hs.code is not None else 0
        return Outcome(
            instance=instance,
            ok=hit in {t.field for t in hs.success},
            flag=hit,
            code=code,
            meaning=self.map.error_text(code),
            exerr=int(rest[hs.exerr.field]) if hs.exerr is not None else None,
            cycles=cycles,
            status=flags,
        )
