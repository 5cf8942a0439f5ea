"""The test bench over OPC UA. Communication faults: the answers to one client dropped
(its timeout fires, it connects again and recovers, another client is not affected), and
the answers to every client delayed for a given time, then on time again
(``frontends/comm_faults.py``, ``frontends/opcua_wire.py``; tags ``Clock.CommFault``,
``CommDelay``, ``CommDuration``, ``CommClientPort``, written by an admin). And a snapshot
the scan refuses: a Bad status.

The HMI reads ``Clock.Cycle`` with a 0.5 s timeout, as a panel does; the delay is 1.5 s so
that a busy machine does not blur a delayed answer and one on time.
"""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest
from asyncua import Client, ua

from motion_server.runtime import Runtime
from tests.integration.test_opcua_roles import roles_site, write
from tests.opcua_support import running, secure_client

HMI_TIMEOUT = 0.5
DELAY = 1.5


def local_port(client: Client) -> int:
    """The TCP port the client connects from."""
    protocol = client.uaclient.protocol
    assert protocol is not None and protocol.transport is not None
    return int(protocol.transport.get_extra_info("sockname")[1])


async def read_cycle(rt: Runtime, client: Client) -> int:
    assert rt.opcua is not None
    node = client.get_node(
        ua.NodeId(rt.tagmap.tag("Clock.Cycle").node_id, rt.opcua.namespace_index)
    )
    return int(await node.read_value())


async def set_fault(rt: Runtime, admin: Client, **tags: int) -> None:
    for name, value in tags.items():
        if name != "CommFault":
            assert await write(rt, admin, f"Clock.{name}", value) == 0, name
    assert await write(rt, admin, "Clock.CommFault", tags.get("CommFault", 0)) == 0


async def test_dropped_answers_time_out_one_client_until_it_connects_again(
    tmp_path: Path,
) -> None:
    async with running(roles_site(tmp_path)) as rt:
        admin = await secure_client(rt, tmp_path, "admin")
        hmi = await secure_client(rt, tmp_path, "viewer")
        await admin.connect()
        await hmi.connect()
        again: Client | None = None
        try:
            await asyncio.wait_for(read_cycle(rt, hmi), HMI_TIMEOUT * 10)
            await set_fault(
                rt, admin, CommFault=2, CommDelay=0, CommDuration=0, CommClientPort=local_port(hmi)
            )
            with pytest.raises(TimeoutError):
                await asyncio.wait_for(read_cycle(rt, hmi), HMI_TIMEOUT)
            # another client is answered; the HMI connects again (from another port)
            await read_cycle(rt, admin)
            again = await secure_client(rt, tmp_path, "viewer")
            await again.connect()
            assert local_port(again) != local_port(hmi)
            await asyncio.wait_for(read_cycle(rt, again), HMI_TIMEOUT * 10)
            assert rt.opcua is not None
            assert await write(rt, admin, "Clock.CommFault", 0) == 0
        finally:
            hmi.disconnect_socket()  # its answers were dropped: no CloseSession answer
            if again is not None:
                await again.disconnect()
            await admin.disconnect()


async def test_delayed_answers_to_every_client_for_a_given_time(tmp_path: Path) -> None:
    async with running(roles_site(tmp_path)) as rt:
        admin = await secure_client(rt, tmp_path, "admin")
        # a client whose own watchdog (a read every second) does not give up on the
        # server while its answers are late, so that the reads below are the ones timed
        hmi = await secure_client(rt, tmp_path, "viewer")
        hmi._watchdog_intervall = 3600.0  # asyncua 2.1: only a constructor argument
        await admin.connect()
        await hmi.connect()
        try:
            t_on = time.monotonic()
            await set_fault(
                rt,
                admin,
                CommFault=1,
                CommDelay=round(DELAY * 1000),
                CommDuration=4000,
                CommClientPort=0,
            )
            t0 = time.monotonic()
            await read_cycle(rt, hmi)
            late = time.monotonic() - t0
            assert late >= DELAY > HMI_TIMEOUT  # an HMI's 0.5 s timeout would fire
            # the fault ends by itself after its duration
            await asyncio.sleep(max(0.0, t_on + 4.0 + 0.5 - time.monotonic()))
            t0 = time.monotonic()
            await read_cycle(rt, hmi)
            assert time.monotonic() - t0 < DELAY
            assert rt.image.read("Clock.CommFault") == 0
        finally:
            await hmi.disconnect()
            await admin.disconnect()


async def test_a_snapshot_the_scan_refuses_is_a_bad_status(tmp_path: Path) -> None:
    site = roles_site(tmp_path)
    site = site.model_copy(update={"data_dir": str(tmp_path)})  # the snapshots' directory
    async with running(site) as rt:
        admin = await secure_client(rt, tmp_path, "admin")
        await admin.connect()
        try:
            assert await write(rt, admin, "Clock.Snapshot", 7) == 0
            # no snapshot 7 yet: refused, and said so
            bad = await write(rt, admin, "Clock.SnapshotRestore", True)
            assert bad == ua.StatusCodes.BadInvalidState
            assert await write(rt, admin, "Clock.SnapshotSave", True) == 0
            assert await write(rt, admin, "Clock.SnapshotRestore", True) == 0
        finally:
            await admin.disconnect()
