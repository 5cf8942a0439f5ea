"""Back-ends: one interface, one class per protocol, looked up by name in :data:`BACKENDS`.

A back-end reads and writes :class:`~.tagmap.MapTag` values; everything above it (trigger,
clock, trace) is protocol-free, so the same client code runs over Modbus TCP or OPC UA.
"""

from __future__ import annotations

import contextlib
import logging
from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from typing import Any, ClassVar

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ModbusException

from .tagmap import ClientMap, MapTag, Value, decode, encode

#: registers per Modbus read request (the protocol allows 125)
MAX_READ = 125
#: registers between two tags that a single read request may span anyway
MAX_GAP = 8


class ClientError(Exception):
    """The server refused a request or could not be reached."""


class _Held(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def held_logs(*names: str) -> Iterator[list[logging.LogRecord]]:
    """Hold back what the loggers ``names`` (a library's) log meanwhile, and yield the
    records: a failed connection is then told in one line of ours, with its likely cause,
    instead of after the library's own lines (pymodbus' "Failed to connect", asyncua's
    ServiceFault dump)."""
    held = _Held()
    saved = []
    for name in names:
        logger = logging.getLogger(name)
        saved.append((logger, logger.propagate))
        logger.addHandler(held)
        logger.propagate = False
    try:
        yield held.records
    finally:
        for logger, propagate in saved:
            logger.removeHandler(held)
            logger.propagate = propagate


def connection_refused_hint(protocol: str, port: int) -> str:
    """Why a connection is refused, most of the time, in words."""
    return (
        f"connection refused: nothing listens on port {port} (is motion-server running, "
        f"with {protocol} on? At start it logs the address it serves)"
    )


class Backend(ABC):
    """Tag-level access over one protocol. ``async with`` connects and closes."""

    protocol: ClassVar[str]
    default_port: ClassVar[int]

    def __init__(
        self, tagmap: ClientMap, host: str = "127.0.0.1", port: int | None = None, **_: Any
    ) -> None:
        self.map = tagmap
        self.host = host
        self.port = self.default_port if port is None else port

    @abstractmethod
    async def connect(self) -> None: ...

    @abstractmethod
    async def close(self) -> None: ...

    @abstractmethod
    async def read(self, tags: Sequence[MapTag]) -> list[Value]:
        """The values of ``tags``, in order, from one consistent server cycle if possible."""

    @abstractmethod
    async def write(self, tag: MapTag, value: Value) -> None:
        """Write one value; :class:`ClientError` if the server refuses it."""

    async def __aenter__(self) -> Backend:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()


def read_plan(tags: Sequence[MapTag]) -> list[tuple[int, int]]:
    """Register ranges (start, count) covering ``tags`` in as few requests as sensible."""
    spans = sorted({(t.address, t.address + t.count) for t in tags})
    out: list[list[int]] = []
    for start, end in spans:
        if out and start - out[-1][1] <= MAX_GAP and end - out[-1][0] <= MAX_READ:
            out[-1][1] = max(out[-1][1], end)
        else:
            out.append([start, end])
    return [(s, e - s) for s, e in out]


class ModbusBackend(Backend):
    """Holding registers over Modbus TCP (pymodbus). BOOLs are written with a mask write
    (function 22), so the other bits of their register are left alone."""

    protocol = "modbus"
    default_port = 5020

    def __init__(
        self,
        tagmap: ClientMap,
        host: str = "127.0.0.1",
        port: int | None = None,
        timeout: float = 3.0,
        **_: Any,
    ) -> None:
        super().__init__(tagmap, host, port)
        self.unit = tagmap.unit_id
        self.client = AsyncModbusTcpClient(host, port=self.port, timeout=timeout, retries=0)

    async def connect(self) -> None:
        with held_logs("pymodbus") as records:
            connected = await self.client.connect()
        if not connected:
            said = " ".join(r.getMessage() for r in records)
            raise ClientError(
                f"cannot connect to Modbus TCP {self.host}:{self.port}: {self._why(said)}"
            )

    def _why(self, said: str) -> str:
        """The likely cause of a failed connection, from what pymodbus logged."""
        text = said.removeprefix("Failed to connect").strip()
        if "Errno 111" in text or "refused" in text.lower():
            return connection_refused_hint("Modbus TCP", self.port)
        if "Name or service not known" in text or "name resolution" in text:
            return f"unknown host {self.host!r}"
        if not text or "timed out" in text.lower() or "Errno 110" in text:
            timeout = self.client.comm_params.timeout_connect
            return f"no answer within {timeout:g} s (a wrong host, or a firewall)"
        return text

    async def close(self) -> None:
        self.client.close()

    async def _registers(self, start: int, count: int) -> list[int]:
        try:
            rr = await self.client.read_holding_registers(start, count=count, device_id=self.unit)
        except ModbusException as exc:
            raise ClientError(f"read {start}+{count}: {exc}") from None
        if rr.isError():
            raise ClientError(f"read of registers {start}..{start + count - 1} refused: {rr}")
        regs: list[int] = list(rr.registers)
        return regs

    async def read(self, tags: Sequence[MapTag]) -> list[Value]:
        image: dict[int, int] = {}
        for start, count in read_plan(tags):
            for i, reg in enumerate(await self._registers(start, count)):
                image[start + i] = reg
        order = self.map.word_order
        return [decode(t, [image[t.address + i] for i in range(t.count)], order) for t in tags]

    async def write(self, tag: MapTag, value: Value) -> None:
        if not tag.writable:
            raise ClientError(f"{tag.name} is read-only")
        try:
            if tag.type == "BOOL":
                bit = tag.bit or 0
                rr = await self.client.mask_write_register(
                    address=tag.address,
                    and_mask=~(1 << bit) & 0xFFFF,
                    or_mask=int(bool(tag.coerce(value))) << bit,
                    device_id=self.unit,
                )
            else:
                regs = encode(tag, value, self.map.word_order)
                rr = await self.client.write_registers(tag.address, regs, device_id=self.unit)
        except ModbusException as exc:
            raise ClientError(f"write {tag.name}: {exc}") from None
        if rr.isError():
            raise ClientError(f"write {tag.name} = {value!r} refused by the server: {rr}")


#: back-ends by protocol name (``opcua`` is added by :mod:`.opcua` on import)
BACKENDS: dict[str, type[Backend]] = {"modbus": ModbusBackend}


def make_backend(
    protocol: str, tagmap: ClientMap, host: str = "127.0.0.1", port: int | None = None, **opts: Any
) -> Backend:
    if protocol == "opcua" and protocol not in BACKENDS:
        from .opcua import OpcUaBackend

        BACKENDS["opcua"] = OpcUaBackend
    try:
        cls = BACKENDS[protocol]
    except KeyError:
        known = ", ".join(sorted(BACKENDS))
        raise ClientError(f"unknown protocol {protocol!r}; known: {known}") from None
    return cls(tagmap, host, port, **opts)
