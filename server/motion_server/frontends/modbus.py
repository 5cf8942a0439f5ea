"""Modbus TCP front-end: holding registers over a :class:`~motion_server.tagmap.TagImage`.

Built on the pymodbus 3.16 ``SimDevice``/``SimData`` API: every register block of the tag
map becomes a ``SimData`` range (the read-only parts marked ``readonly``), and one async
``action`` hook translates each request into tag-image reads and writes. Status registers
are filled on read from the image (nothing is pushed per cycle), so a read always shows
the last completed cycle.

Served: FC3 (read), FC6 and FC16 (write), FC22 (mask write) and FC23 (read/write).
Exceptions:

- 01 another function code (coils, discrete inputs, input registers);
- 02 a register outside the map, or a write that touches a read-only register;
- 03 a value the tag cannot hold (a SINT beyond -128..127, an unknown ``Clock.Mode``, a
  non-finite hand-wheel input), or a malformed count (pymodbus);
- 11 (gateway target failed to respond) a unit id other than the site's; with
  ``unit_id = 0`` every unit id is answered.

A write that covers only part of a 32/64-bit value changes those words: operands are
latched on the trigger's edge, so a client may write the two halves separately. A write
to ``Clock.Step`` is answered once the cycles it asked for have run (manual clock).
Known upstream limits: several requests pipelined in one TCP segment get only the first
answered.
"""

from __future__ import annotations

import logging
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from ..tagmap import AddressError, BadValueError, ReadOnlyError, TagImage, TagMap

log = logging.getLogger("motion_server.modbus")

#: function codes the front-end answers (the others get exception 01)
SERVED_FUNCTION_CODES = frozenset({3, 6, 16, 22, 23})
#: the highest register + 1
ADDRESS_SPACE = 65536


def sim_data(tagmap: TagMap) -> list[SimData]:
    """One ``SimData`` range per part of every block: read-only status, writable
    command region, read-only tail. Addresses outside every block stay invalid."""
    out: list[SimData] = []
    for b in tagmap.blocks:
        parts = (
            (b.base, b.command_start, True),
            (b.command_start, b.command_end, False),
            (b.command_end, b.end, True),
        )
        for start, end, readonly in parts:
            if end > start:
                out.append(
                    SimData(
                        address=start,
                        count=end - start,
                        values=0,
                        datatype=DataType.REGISTERS,
                        readonly=readonly,
                    )
                )
    return out


class ModbusFrontend:
    """A Modbus TCP server for one tag image. ``await start()`` binds (port 0 picks an
    ephemeral port, see :attr:`port`); ``await stop()`` closes it."""

    def __init__(
        self,
        image: TagImage,
        host: str = "127.0.0.1",
        port: int = 5020,
        unit_id: int | None = None,
    ) -> None:
        self.image = image
        self.host = host
        self.requested_port = port
        self.unit_id = image.map.unit_id if unit_id is None else unit_id
        self.server: ModbusTcpServer | None = None
        self.requests = 0
        self.exceptions = 0

    def devices(self) -> list[SimDevice]:
        devices = [
            SimDevice(id=self.unit_id, simdata=sim_data(self.image.map), action=self._action)
        ]
        if self.unit_id != 0:
            # pymodbus falls back to device 0 for unknown unit ids: answer them with 0x0B
            catch_all = SimData(0, count=ADDRESS_SPACE, values=0, datatype=DataType.REGISTERS)
            devices.append(SimDevice(id=0, simdata=[catch_all], action=self._unknown_unit))
        return devices

    async def start(self) -> None:
        self.server = ModbusTcpServer(self.devices(), address=(self.host, self.requested_port))
        await self.server.serve_forever(background=True)
        log.info("Modbus TCP on %s:%d, unit id %d", self.host, self.port, self.unit_id)

    async def stop(self) -> None:
        if self.server is not None:
            await self.server.shutdown()
            self.server = None

    @property
    def port(self) -> int:
        """The bound TCP port (after :meth:`start`)."""
        if self.server is None or self.server.transport is None:
            raise RuntimeError("the Modbus server is not listening")
        sockets: Any = getattr(self.server.transport, "sockets", ())
        port: int = sockets[0].getsockname()[1]
        return port

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        """pymodbus calls this after its own range and read-only checks passed."""
        self.requests += 1
        if function_code not in SERVED_FUNCTION_CODES:
            self.exceptions += 1
            return ExcCodes.ILLEGAL_FUNCTION
        image = self.image
        try:
            if set_values is None:
                offset = address - start_address
                registers[offset : offset + count] = image.read_registers(address, count, False)
            else:
                if image.write_registers(address, [int(v) for v in set_values], check=False):
                    await image.settle()  # a Clock.Step: answer once its cycles ran
            return None
        except (AddressError, ReadOnlyError) as exc:
            log.debug("FC%d %d+%d: %s", function_code, address, count, exc)
            code = ExcCodes.ILLEGAL_ADDRESS
        except BadValueError as exc:
            log.info("FC%d %d+%d refused: %s", function_code, address, count, exc)
            code = ExcCodes.ILLEGAL_VALUE
        except Exception:  # never let one request take the server down
            log.exception("FC%d %d+%d failed", function_code, address, count)
            code = ExcCodes.DEVICE_FAILURE
        self.exceptions += 1
        return code

    async def _unknown_unit(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        self.exceptions += 1
        return ExcCodes.GATEWAY_NO_RESPONSE
