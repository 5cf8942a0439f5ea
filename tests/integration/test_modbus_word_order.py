"""A REAL written in the wrong word order (issue 24): 10.0 sent as CDAB to a big-endian
(ABCD) map arrives as 2.3e-41, a subnormal REAL. A controller takes such a value, so the
server does too, but it warns once per tag, naming the tag and the word order.

IEEE 754 binary32: 10.0 is 0x41200000; its words swapped, 0x00004120, is the subnormal
0x4120 × 2^-149 = 16672 × 2^-149 ≈ 2.336e-41 (below the smallest normal REAL, 2^-126 ≈
1.18e-38).
"""

from __future__ import annotations

import asyncio
import logging
import math

import pytest
from pymodbus.client import AsyncModbusTcpClient

from tests.integration.test_modbus import start
from tests.modbus_support import modbus_site

SWAPPED_TEN = [0x0000, 0x4120]  # 10.0 in CDAB
SUBNORMAL = 0x4120 * 2.0**-149


def warnings_about(caplog: pytest.LogCaptureFixture, name: str) -> list[str]:
    return [
        r.getMessage()
        for r in caplog.records
        if r.levelno == logging.WARNING and "subnormal" in r.getMessage() and name in r.getMessage()
    ]


async def test_a_subnormal_real_is_accepted_and_warned_of_once_per_tag(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.WARNING)
    rt, task, port = await start(modbus_site(word_order="big"))
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0)
    await client.connect()
    try:
        speed = rt.tagmap.tag("MAJ_1.Speed")
        accel = rt.tagmap.tag("MAJ_1.AccelRate")
        for _ in range(3):
            rr = await client.write_registers(speed.address, SWAPPED_TEN, device_id=1)
            assert not rr.isError()  # not refused: a real controller takes it too
        assert math.isclose(float(rt.image.read("MAJ_1.Speed")), SUBNORMAL, rel_tol=1e-6)
        said = warnings_about(caplog, "MAJ_1.Speed")
        assert len(said) == 1, said
        assert "big, ABCD" in said[0] and "word order" in said[0]
        # another tag warns on its own; a normal REAL (10.0 in the right order) does not
        rr = await client.write_registers(accel.address, SWAPPED_TEN, device_id=1)
        assert not rr.isError()
        assert len(warnings_about(caplog, "MAJ_1.AccelRate")) == 1
        rr = await client.write_registers(speed.address, [0x4120, 0x0000], device_id=1)
        assert not rr.isError() and rt.image.read("MAJ_1.Speed") == 10.0
        assert len(warnings_about(caplog, "subnormal")) == 2
    finally:
        client.close()
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)
