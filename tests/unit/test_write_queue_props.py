"""Properties of the write queue (``scan/writes.py``) for random mixes of batches: costly
ones, stops, watchdog writes, several clients on two channels, arriving between cycles.
Whatever the budget: every batch is taken exactly once, each client's ordinary batches in
their order, watchdog writes before anything else of their cycle, and the channel's
settled sequence number only moves forward."""

from __future__ import annotations

from dataclasses import dataclass

from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.image import wire
from motion_server.safety.client import ClientInfo
from motion_server.scan.writes import WriteQueue

CLIENTS = [ClientInfo("modbus", f"10.0.0.{k}", 50000 + k, k) for k in range(1, 4)]


@dataclass
class FakeChannel:
    number: int


class Costs:
    """A batch's single item carries its cost and kind: (cost, kind); kind 0 ordinary,
    1 a stop, 2 a watchdog write."""

    def of(self, items: list[tuple[int, float]]) -> tuple[int, bool]:
        cost, kind = items[0]
        return int(cost), kind == 2

    def stops_motion(self, items: list[tuple[int, float]]) -> bool:
        return items[0][1] == 1


batch = st.tuples(
    st.integers(0, 2),  # client
    st.integers(1, 2),  # channel
    st.integers(1, 40),  # cost
    st.sampled_from([0, 0, 1, 1, 2]),  # kind
    st.sampled_from([0, 0, 0, 1, 3]),  # cycles before the next batch arrives
)


@settings(max_examples=300, deadline=None)
@given(budget=st.integers(1, 40), arrivals=st.lists(batch, min_size=1, max_size=60))
def test_every_batch_once_in_its_clients_order(
    budget: int, arrivals: list[tuple[int, int, int, int, int]]
) -> None:
    queue = WriteQueue(budget, Costs())  # type: ignore[arg-type]
    channels = {n: FakeChannel(n) for n in (1, 2)}
    seqs = dict.fromkeys(channels, 0)
    sent: dict[tuple[int, str], list[int]] = {}
    taken: list[tuple[int, int]] = []  # (channel, seq)
    settled = dict.fromkeys(channels, 0)

    def cycle() -> None:
        out = queue.take_cycle()
        kinds = [q.batch.items[0][1] for q in out]
        # watchdog writes first
        first_other = next((i for i, k in enumerate(kinds) if k != 2), len(kinds))
        assert all(k != 2 for k in kinds[first_other:])
        for q in out:
            taken.append((q.channel.number, q.batch.seq))
            seq = queue.settle(q)
            if seq is not None:
                assert seq > settled[q.channel.number]
                settled[q.channel.number] = seq

    for client, channel, cost, kind, gap in arrivals:
        seqs[channel] += 1
        info = CLIENTS[client]
        items = [(cost, float(kind))]
        queue.put(channels[channel], wire.Batch(seqs[channel], info, items))  # type: ignore[arg-type]
        if kind != 2:
            sent.setdefault((channel, info.key), []).append(seqs[channel])
        for _ in range(gap):
            cycle()
    total = sum(cost for _, _, cost, _, _ in arrivals)
    for _ in range(total + len(arrivals) + 2):
        if not len(queue):
            break
        cycle()
    assert len(queue) == 0
    assert sorted(taken) == sorted({(c, s) for c, s in taken})  # each once
    assert len(taken) == len(arrivals)
    position = {key: i for i, key in enumerate(taken)}
    for (channel, _), order in sent.items():
        at = [position[(channel, s)] for s in order]
        assert at == sorted(at), "a client's batches out of order"
    assert settled == seqs  # every batch settled: APPLIED reached the last
