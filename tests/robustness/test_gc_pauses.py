"""A full garbage collection must not stall the cycle loop.

A served site holds hundreds of thousands of tracked objects (with OPC UA, asyncua's
address space); a full collection over them stops the loop for hundreds of milliseconds,
past the catch-up bound (50 cycles of 2 ms), and the realtime loop drops cycles. The
runtime freezes its start-up heap while it serves: a collection then scans only what
was allocated since.
"""

from __future__ import annotations

import asyncio
import gc

from motion_server.runtime import Runtime
from tests.modbus_support import modbus_site


async def test_the_start_up_heap_is_frozen_while_serving() -> None:
    gc.collect()
    rt = Runtime(modbus_site())
    task = asyncio.create_task(rt.serve())
    await rt.ready.wait()
    await asyncio.sleep(0)
    frozen = gc.get_freeze_count()
    scanned = len(gc.get_objects())  # what a full collection would scan now
    # the heap at start (the interpreter, pymodbus, the tag map...) is frozen; what a
    # full collection scans is a few percent of it
    assert frozen > 20_000
    assert scanned < frozen / 10
    rt.request_stop()
    await task
    assert gc.get_freeze_count() == 0  # unfrozen when the last runtime stops
