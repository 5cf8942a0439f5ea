"""Reads of tag values over OPC UA come from the scan's image, one snapshot per request.

A site of six hand wheels (feedback-only axes, 100 counts/mm): the ActualPosition of each
is the FeedbackInput written before the cycle, so writing the same value to all six
before a cycle gives six equal positions in that cycle's snapshot, and a Read that showed
nodes of two cycles would show two different positions. Manual clock: cycles run only
when the test asks. The periodic publishing pass runs once at start and not again within
the test (0.01 Hz); the tests run passes themselves.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import pytest_asyncio
from asyncua import Client, ua

from motion_server import config
from motion_server.runtime import Runtime
from tests.opcua_support import running

pytestmark = pytest.mark.asyncio(loop_scope="module")

WHEELS = [f"Wheel{k}" for k in range(1, 7)]

SITE = """
[site]
name = "opcua_reads"
namespace_uri = "urn:motion-server:opcua-reads"

[controller]
clock = "manual"
status_log_interval = 0.0

[modbus]
enabled = false

[opcua]
port = 0
data_dir = "{data_dir}"
allow_anonymous = true
anonymous_role = "operator"
allow_none_endpoint = true
publish_rate_hz = 0.01
chunk_size = 1

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = [{axes}]

{wheels}
[instructions]
every_type = false
"""


def site(data_dir: Path) -> config.SiteMap:
    wheels = "".join(
        f'[[axes]]\nname = "{w}"\ntype = "feedback_only"\nconversion_constant = 100.0\n\n'
        for w in WHEELS
    )
    axes = ", ".join(f'"{w}"' for w in WHEELS)
    text = SITE.format(data_dir=data_dir, axes=axes, wheels=wheels)
    return config.parse(text, "opcua-reads.toml")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    async with running(site(tmp_path_factory.mktemp("opcua-reads"))) as runtime:
        yield runtime


@pytest_asyncio.fixture(loop_scope="module")
async def client(rt: Runtime) -> AsyncIterator[Client]:
    assert rt.opcua is not None
    c = Client(rt.opcua.endpoint, timeout=10)
    await c.connect()
    try:
        yield c
    finally:
        await c.disconnect()


def node_ids(rt: Runtime, field: str) -> list[ua.NodeId]:
    assert rt.opcua is not None
    ns = rt.opcua.namespace_index
    return [ua.NodeId(f"Axes.{w}.{field}", ns) for w in WHEELS]


async def turn(rt: Runtime, counts: int) -> None:
    """Every hand wheel to ``counts`` / 100 mm, then one cycle."""
    rt.image.write_many([(f"{w}.FeedbackInput", counts / 100.0) for w in WHEELS])
    rt.request_cycles(1)
    await rt.settle()


async def test_a_read_shows_the_newest_cycle_without_a_publishing_pass(
    rt: Runtime, client: Client
) -> None:
    fe = rt.opcua
    assert fe is not None
    passes = fe.passes
    cycle = client.get_node(ua.NodeId("Clock.Cycle", fe.namespace_index))
    rt.request_cycles(5)
    await rt.settle()
    assert await cycle.read_value() == rt.ctl.tick
    await turn(rt, 250)
    values = await client.read_values([client.get_node(n) for n in node_ids(rt, "ActualPosition")])
    assert values == [2.5] * len(WHEELS)
    assert await cycle.read_value() == rt.ctl.tick
    assert fe.passes == passes  # no pass published any of it


async def test_every_value_of_a_read_comes_from_one_snapshot(
    rt: Runtime, client: Client, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The front-end reads the scan's image, which the scan (another process) may
    publish anew at any moment: here every look at the image sees a newer snapshot, in
    which every slot holds the number of looks so far. One Read still shows one."""
    fe = rt.opcua
    assert fe is not None
    size = rt.layout.size
    looks = 0

    def newer() -> np.ndarray:
        nonlocal looks
        looks += 1
        return np.full(size, float(looks))

    monkeypatch.setattr(fe.image, "values", newer)
    nodes = [client.get_node(n) for n in node_ids(rt, "ActualPosition")]
    first = await client.read_values(nodes)
    second = await client.read_values(nodes)
    monkeypatch.undo()
    assert len(set(first)) == 1, first
    assert len(set(second)) == 1, second
    assert second[0] > first[0]  # each Read took the newest snapshot


class Count:
    def __init__(self) -> None:
        self.n = 0

    def datachange_notification(self, node: Any, val: Any, data: Any) -> None:
        self.n += 1


async def test_a_read_during_a_publishing_pass_never_sees_two_cycles(
    rt: Runtime, client: Client
) -> None:
    """Cycles run while publishing passes notify a subscription of every position, one
    notification at a time (``chunk_size = 1``: the pass yields after each), and a client
    reads the six positions back to back: every Read shows six equal positions."""
    fe = rt.opcua
    assert fe is not None
    count = Count()
    sub = await client.create_subscription(0, count)
    positions = [client.get_node(n) for n in node_ids(rt, "ActualPosition")]
    await sub.subscribe_data_change(positions, queuesize=1)
    iserver = fe.server.iserver if fe.server is not None else None
    assert iserver is not None
    service = iserver.attribute_service
    answer = service.read
    during_pass: list[bool] = []

    def read(params: ua.ReadParameters) -> list[ua.DataValue]:
        during_pass.append(fe._lock.locked())
        return answer(params)

    service.read = read
    done = asyncio.Event()
    reads: list[list[float]] = []

    async def drive() -> None:
        for counts in range(1, 200):
            await turn(rt, counts)
            await asyncio.sleep(0)
        done.set()

    async def publish() -> None:
        while not done.is_set():
            await fe.publish()
            await asyncio.sleep(0)

    async def read_back() -> None:
        while not done.is_set():
            reads.append(await client.read_values(positions))

    try:
        await asyncio.wait_for(asyncio.gather(drive(), publish(), read_back()), 60.0)
    finally:
        service.read = answer
        await sub.delete()
    mixed = [r for r in reads if len(set(r)) != 1]
    assert not mixed, mixed[:5]
    assert any(during_pass), "no Read was answered while a pass was notifying"
    assert len({r[0] for r in reads}) > 1  # the reads saw the cycles go by
    assert count.n > len(WHEELS)  # the passes notified the subscription
