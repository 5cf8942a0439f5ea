"""The budget of client writes per cycle (``scan/writes.py``), under the manual clock with a
deliberately tiny budget: what does not fit waits for the next cycle, in arrival order;
channels and clients take turns; a heartbeat and the programmed stop never wait for a
backlog; the same writes give the same trace.

The batches are put in the scan's queue directly (as the front-ends' packets are) and the
clock is stepped the way a client steps it, with a ``Clock.Step`` batch that arrives
first: the batches behind it go into its cycles."""

from __future__ import annotations

import socket
from collections import deque

import pytest

from motion_server import config
from motion_server.frontends.link import IN_FLIGHT_PER_CLIENT, ScanLink
from motion_server.image import wire
from motion_server.image.buffer import Meta
from motion_server.safety.client import ClientInfo
from motion_server.scan import Scan
from motion_server.scan.channel import MODBUS, OPCUA, Channel
from motion_server.scan.writes import AXES_PER_UNIT, ITEMS_PER_UNIT, default_budget

SITE = """
[site]
name = "write_budget"

[controller]
clock = "manual"
status_log_interval = 0.0
{budget}

[modbus]
enabled = false

[opcua]
enabled = false

[[groups]]
name = "Group1"
coarse_update_period_ms = 1.0
axes = ["Axis1", "Axis2"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[[axes]]
name = "Axis2"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[instructions]
every_type = false

[[instructions.instances]]
name = "MAJ_1"
type = "MAJ"
operands = {{ Axis = 1, Speed = 10.0, AccelRate = 1000.0, DecelRate = 1000.0 }}

[[instructions.instances]]
name = "MAM_1"
type = "MAM"
operands = {{ Axis = 2, Position = 5.0, Speed = 10.0, AccelRate = 1000.0, DecelRate = 1000.0 }}

[[instructions.instances]]
name = "MGS_1"
type = "MGS"

[[watchdogs]]
name = "HMI1"
timeout = 0.01
group = "Group1"
"""

A = ClientInfo("modbus", "10.0.0.1", 50001, 1)
B = ClientInfo("modbus", "10.0.0.2", 50002, 2)
C = ClientInfo("opcua", "10.0.0.3", 50003, 3)


class FakeChannel(Channel):
    """A channel without a socket: the scan's acknowledgements are kept."""

    def __init__(self, number: int) -> None:
        self.number = number
        self.name = f"channel {number}"
        self.assembler = wire.BatchAssembler()
        self.outbox = deque()
        self.closed = False
        self.welcomed = True
        self.peer_pid = 0
        self.acks: list[wire.Ack] = []

    def receive(self) -> list[bytes]:
        return []

    def send(self, packet: bytes) -> None:
        self.acks.append(wire.decode_ack(packet))

    def flush(self) -> None:
        return None


class Bench:
    """A scan of the site map above, its channels, and what each cycle saw."""

    def __init__(self, budget: int | None) -> None:
        line = "" if budget is None else f"write_budget = {budget}"
        self.scan = Scan(config.parse(SITE.format(budget=line), "write-budget.toml"))
        self.scan.start(0.0)
        for ax in self.scan.ctl.axes:  # servo on (not through writes: they are counted)
            self.scan.ctl.servo_on(ax)
        self.channels = {n: FakeChannel(n) for n in (MODBUS, OPCUA)}
        for ch in self.channels.values():
            self.scan.attach(ch)
        self.slot = {t.name: i for i, t in enumerate(self.scan.layout.tags)}
        self.seq = dict.fromkeys(self.channels, 0)
        #: per cycle, before it ran: the values of the watched tags
        self.trace: list[tuple[float, ...]] = []
        self.watched = ["MAJ_1.Speed", "MAM_1.Speed", "MAJ_1.DecelRate"]
        self.applied_before_cycle: list[int] = []
        run = self.scan._run_cycle

        def recorded() -> None:
            getter = self.scan.image.getter
            self.trace.append(tuple(float(getter(n)()) for n in self.watched))
            self.applied_before_cycle.append(self.scan.writes_applied)
            run()

        self.scan._run_cycle = recorded  # type: ignore[method-assign]

    def put(self, client: ClientInfo, *items: tuple[str, float], channel: int = MODBUS) -> int:
        self.seq[channel] += 1
        seq = self.seq[channel]
        batch = wire.Batch(seq, client, [(self.slot[n], float(v)) for n, v in items])
        self.scan.deliver(self.channels[channel], batch)
        return seq

    def step(self, cycles: int, client: ClientInfo = C) -> int:
        """Queue a Clock.Step of ``cycles`` (a rising edge: 0, then 1, in one batch)."""
        return self.put(
            client,
            ("Clock.StepCycles", cycles),
            ("Clock.Step", 0),
            ("Clock.Step", 1),
            channel=OPCUA,
        )

    def run(self) -> None:
        """Serve the scan until the cycles asked for ran (what is still queued then is
        applied by the next pass: time stands still)."""
        scan = self.scan
        scan.service(0.0)
        while scan._pending_cycles:
            scan.service(0.0)

    def column(self, name: str) -> list[float]:
        i = self.watched.index(name)
        return [row[i] for row in self.trace]


def test_batches_that_do_not_fit_wait_for_the_next_cycle_in_arrival_order() -> None:
    """Budget 4, ten batches of one operand each (1 unit each): four a cycle."""
    b = Bench(budget=4)
    b.step(3)
    for k in range(1, 11):
        b.put(A, ("MAJ_1.Speed", 100.0 + k))
    b.run()
    assert b.column("MAJ_1.Speed") == [104.0, 108.0, 110.0]
    assert b.scan.writes.deferred_cycles == 2
    assert len(b.scan.writes) == 0
    acks = b.channels[MODBUS].acks
    assert [a.seq for a in acks] == list(range(1, 11))
    assert all(a.result == wire.Result.APPLIED for a in acks)
    # applied before cycle 1, 2, 3: the step, then 4 a cycle
    assert [a.tick for a in acks] == [0] * 4 + [1] * 4 + [2] * 2


def test_a_clock_step_is_acknowledged_once_its_cycles_ran() -> None:
    b = Bench(budget=2)
    seq = b.step(5)
    for k in range(1, 9):
        b.put(A, ("MAJ_1.Speed", float(k)))
    b.run()
    (ack,) = [a for a in b.channels[OPCUA].acks if a.seq == seq]
    assert ack.result == wire.Result.APPLIED
    assert ack.tick == 5
    assert b.column("MAJ_1.Speed") == [2.0, 4.0, 6.0, 8.0, 8.0]


def test_clients_and_channels_take_turns_when_the_budget_is_spent() -> None:
    """Budget 6: Modbus has clients A and B with six batches each, OPC UA client C six:
    the channels alternate, and inside Modbus A and B do; each client in its own order."""
    b = Bench(budget=6)
    b.step(3)
    for k in range(1, 7):
        b.put(A, ("MAJ_1.Speed", float(k)))
    for k in range(1, 7):
        b.put(B, ("MAM_1.Speed", float(k)))
    for k in range(1, 7):
        b.put(C, ("MAJ_1.DecelRate", 1000.0 + k), channel=OPCUA)
    b.run()
    # turns: Modbus A, OPC UA C, Modbus B, C, A, C | B, C, A, C, B, C | the rest fits
    assert b.column("MAJ_1.Speed") == [2.0, 3.0, 6.0]
    assert b.column("MAM_1.Speed") == [1.0, 3.0, 6.0]
    assert b.column("MAJ_1.DecelRate") == [1003.0, 1006.0, 1006.0]
    by_seq = {a.seq: a.tick for a in b.channels[MODBUS].acks}
    a_ticks = [by_seq[s] for s in range(1, 7)]
    assert a_ticks == sorted(a_ticks)  # A's batches in A's order


def test_a_heartbeat_is_not_delayed_by_a_backlog_nor_counted_in_the_budget() -> None:
    """Budget 2: A's twenty batches take ten cycles; B's heartbeat, behind them, is
    applied before the first cycle, and A's own heartbeat before A's backlog too."""
    b = Bench(budget=2)
    b.step(1)
    for k in range(1, 21):
        b.put(A, ("MAJ_1.Speed", float(k)))
    b.put(B, ("HMI1.Heartbeat", 7))
    b.put(A, ("HMI1.Heartbeat", 8))
    b.run()
    assert b.column("MAJ_1.Speed") == [2.0]  # the budget: A's backlog waits
    wd = b.scan.watchdogs["HMI1"]
    assert wd.heartbeat == 8  # both beats applied before cycle 1 (stamped with it)
    assert wd.beats["*"] == (0, 8)
    # the Modbus APPLIED word stops before the first of A's batches still waiting: the
    # front-end keeps laying those values over the image
    assert int(b.scan.meta[Meta.APPLIED + MODBUS]) == 2


def test_the_watchdog_trips_on_time_behind_a_backlog() -> None:
    """The heartbeat stops; a client keeps the queue full: the watchdog still trips in the
    cycle that starts its timeout (10 cycles of 1 ms) after the cycle that took the beat."""
    b = Bench(budget=2)
    b.put(B, ("HMI1.Heartbeat", 1))
    b.run()  # applied while time stands still: stamped with cycle 0
    wd = b.scan.watchdogs["HMI1"]
    b.step(10)
    for k in range(1, 60):
        b.put(A, ("MAJ_1.Speed", float(k)))
    b.run()
    assert wd.trips == 0  # cycles 0 to 9: the beat is 9 cycles old at most
    assert len(b.scan.writes) == 59 - 2 * 10
    b.step(1)
    b.run()
    assert wd.trips == 1  # the cycle that starts 10 cycles after the beat


def test_an_instruction_costs_by_the_axes_it_commands() -> None:
    b = Bench(budget=None)
    costs = b.scan.writes.costs
    slot = b.slot
    assert costs.of([(slot["MAJ_1.Speed"], 5.0)]) == (1, False)
    assert costs.of([(slot["MAJ_1.Execute"], 1.0)]) == (2, False)
    assert costs.of([(slot["MAJ_1.Execute"], 0.0)]) == (1, False)
    # MGS: the group's two axes
    assert costs.of([(slot["MGS_1.Execute"], 1.0)]) == (2 + 2 // AXES_PER_UNIT, False)
    many = [(slot["MAJ_1.Speed"], 5.0)] * (3 * ITEMS_PER_UNIT)
    assert costs.of(many) == (4, False)
    assert costs.of([(slot["HMI1.Heartbeat"], 3.0), (slot["HMI1.Reset"], 0.0)]) == (1, True)
    assert costs.of([(slot["HMI1.Heartbeat"], 3.0), (slot["MAJ_1.Speed"], 5.0)]) == (1, False)
    # the default: 8 units per millisecond of the period
    assert b.scan.writes.budget == default_budget(0.001) == 8
    assert default_budget(0.002) == 16


def test_a_batch_larger_than_the_budget_goes_alone_and_the_next_cycles_pay_for_it() -> None:
    """Budget 1: an MAJ's rising edge costs 2. It is taken when the credit is full, alone;
    the debt it leaves takes the next cycle's credit; then one unit a cycle again."""
    b = Bench(budget=1)
    b.step(5)
    b.put(A, ("MAJ_1.Execute", 1))
    b.put(A, ("MAJ_1.Speed", 50.0))
    b.put(A, ("MAJ_1.Speed", 60.0))
    b.run()
    assert b.column("MAJ_1.Speed") == [10.0, 10.0, 50.0, 60.0, 60.0]
    maj = b.scan.system["MAJ_1"]
    assert maj.outputs["IP"]


def test_the_programmed_stop_does_not_wait_for_a_backlog() -> None:
    """A stop requested with 40 batches waiting (budget 2): its first cycle runs after two
    of them; by the end every one was applied (the retained state has them)."""
    b = Bench(budget=2)
    b.put(C, ("MAJ_1.Execute", 1), channel=OPCUA)
    b.step(5)
    b.run()
    assert b.scan.ctl.axes[0].command_velocity > 0.0
    for k in range(1, 41):
        b.put(A, ("MAM_1.Speed", float(k)))
    before = b.scan.writes_applied
    ran = len(b.applied_before_cycle)
    b.scan.request_stop()
    while not b.scan.finished:
        b.scan.service(0.0)
    stop_cycles = b.applied_before_cycle[ran:]
    assert stop_cycles[0] - before == 2
    assert b.scan.writes_applied - before == 40
    assert float(b.scan.image.getter("MAM_1.Speed")()) == 40.0


def scenario(b: Bench) -> list[tuple[float, ...]]:
    """A mix of commands from three clients, behind a step of 40 cycles."""
    b.step(40)
    for k in range(12):
        b.put(A, ("MAJ_1.Speed", 20.0 + k), ("MAJ_1.Execute", k % 2))
        b.put(B, ("MAM_1.Position", 3.0 * k), ("MAM_1.Execute", (k + 1) % 2))
        b.put(C, ("MGS_1.Execute", int(k == 9)), channel=OPCUA)
        b.put(B, ("HMI1.Heartbeat", k))
    b.run()
    b.scan.service(0.0)  # time stands still: what still waits is applied at once
    ctl = b.scan.ctl
    positions = tuple(float(ax.command_position) for ax in ctl.axes)
    return [*b.trace, positions]


def test_the_same_writes_give_the_same_trace() -> None:
    first = scenario(Bench(budget=3))
    second = scenario(Bench(budget=3))
    assert first == second
    assert len(first) == 41


@pytest.mark.parametrize("budget", [1, 3])
def test_every_batch_is_applied_exactly_once_in_its_clients_order(budget: int) -> None:
    b = Bench(budget=budget)
    scenario(b)
    for ch in b.channels.values():
        seqs = [a.seq for a in ch.acks]
        assert len(seqs) == len(set(seqs))
    modbus = sorted(a.seq for a in b.channels[MODBUS].acks)
    assert modbus == list(range(1, b.seq[MODBUS] + 1))
    assert len(b.scan.writes) == 0
    assert int(b.scan.meta[Meta.APPLIED + MODBUS]) == b.seq[MODBUS]


def test_a_client_with_too_many_writes_in_flight_waits_for_the_scan() -> None:
    """The front-end's side: past its share of unacknowledged batches, a client's answer
    waits for the scan (flow control), another client's does not."""
    ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    with ours, theirs:
        link = ScanLink(ours, MODBUS, 0)
        tickets = [link.send([(0, 1.0)], A) for _ in range(IN_FLIGHT_PER_CLIENT + 1)]
        assert [t.waits for t in tickets] == [False] * IN_FLIGHT_PER_CLIENT + [True]
        assert not link.send([(0, 1.0)], B).waits
        for t in tickets[:2]:
            link._packet(wire.encode_ack(wire.Ack(t.seq, 1, 0, wire.Result.APPLIED)))
        assert tickets[0].ack is not None
        assert not link.send([(0, 1.0)], A).waits  # 8 in flight again
        assert link.send([(0, 1.0)], A).waits


def test_a_batch_larger_than_the_budget_is_not_starved_by_smaller_ones() -> None:
    """Budget 2; A's batch of 48 items costs 4 (more than a whole budget): the first
    client blocked in a cycle has the first turn of the next, so it goes as soon as a
    cycle's credit is full, however many small batches B (its channel) and C (another
    channel) keep sending in turns around it."""
    b = Bench(budget=2)
    b.step(12)
    b.put(C, ("MAJ_1.DecelRate", 2000.0), channel=OPCUA)
    b.put(A, *[("MAM_1.Speed", 77.0)] * (3 * ITEMS_PER_UNIT))
    for k in range(1, 25):
        b.put(B, ("MAJ_1.Speed", float(k)))
        b.put(C, ("MAJ_1.DecelRate", 1000.0 + k), channel=OPCUA)
    b.run()
    speeds = b.column("MAM_1.Speed")
    assert 77.0 in speeds
    assert speeds.index(77.0) == 1  # blocked in the first cycle, first in the second


def test_a_clock_step_behind_a_backlog_is_acknowledged_once_its_own_cycles_ran() -> None:
    """Budget 2: while a step of 8 runs, A's ten batches and then A's own step of 2 wait
    their turns; the second step is applied before the sixth cycle and adds its 2 cycles
    after the 3 left: 10 in all, and its answer comes with the tenth."""
    b = Bench(budget=2)
    b.step(8)
    for k in range(1, 11):
        b.put(A, ("MAJ_1.Speed", float(k)))
    second = b.put(A, ("Clock.StepCycles", 2), ("Clock.Step", 0), ("Clock.Step", 1))
    b.run()
    assert b.scan.ctl.tick == 10
    (ack,) = [a for a in b.channels[MODBUS].acks if a.seq == second]
    assert (ack.tick, ack.result) == (10, wire.Result.APPLIED)
    assert b.column("MAJ_1.Speed") == [2.0, 4.0, 6.0, 8.0, 10.0] + [10.0] * 5


def test_a_connection_cannot_take_more_than_its_share_with_costly_batches() -> None:
    """Budget 2: A's batches of 48 items cost 4 units each, B's cost 1 (both on Modbus). A
    turn is worth one unit, so A, having taken 4, lets three of B's turns pass: after
    every cycle A has taken at most one batch (4 units) more than B, not four times as
    much as a turn per batch would give it."""
    b = Bench(budget=2)
    b.step(16)
    costly = [("MAM_1.Speed", 77.0)] * (3 * ITEMS_PER_UNIT)
    owner: dict[int, tuple[str, int]] = {}
    for _ in range(6):
        owner[b.put(A, *costly)] = ("A", 4)
    for k in range(1, 25):
        owner[b.put(B, ("MAJ_1.Speed", float(k)))] = ("B", 1)
    b.run()
    by_tick: dict[int, dict[str, int]] = {}
    for ack in b.channels[MODBUS].acks:
        who, units = owner[ack.seq]
        by_tick.setdefault(ack.tick, {"A": 0, "B": 0})[who] += units
    taken = {"A": 0, "B": 0}
    for tick in range(16):
        for who, units in by_tick.get(tick, {}).items():
            taken[who] += units
        assert taken["A"] - taken["B"] <= 4, (tick, taken)
    assert taken["A"] >= 8  # A is not starved either


def test_a_stop_is_not_behind_another_clients_backlog() -> None:
    """Budget 2: B has ten operand writes waiting, then A's MGS (2 units) arrives: it is
    applied before the next cycle, ahead of B's backlog; an operand write of A's behind
    it waits its turn."""
    b = Bench(budget=2)
    b.step(3)
    for k in range(1, 11):
        b.put(B, ("MAJ_1.Speed", float(k)))
    stop = b.put(A, ("MGS_1.Execute", 1))
    after = b.put(A, ("MAM_1.Speed", 99.0))
    b.run()
    ticks = {a.seq: a.tick for a in b.channels[MODBUS].acks}
    assert ticks[stop] == 0
    assert ticks[after] > 0
    assert b.scan.system["MGS_1"].outputs["DN"]


def test_a_client_toggling_stops_gets_only_its_share() -> None:
    """Budget 1: A toggles MGS_1 (a rising edge costs 2 units, a falling one 1) while B
    has twelve operand writes (1 unit each) waiting. A's stop jumps the queue and, having
    taken no turn, A owes 2 turns; then B's turns and A's alternate. Cycle by cycle: A's
    stop (the credit goes to -1), nothing (0), B, A pays and B, A pays and B, A's falling
    edge, A's next stop, nothing, B, B, B, A: in 12 cycles 6 units each."""
    b = Bench(budget=1)
    b.step(12)
    for k in range(1, 13):
        b.put(B, ("MAJ_1.Speed", float(k)))
    stops = [b.put(A, ("MGS_1.Execute", k % 2)) for k in range(1, 9)]
    b.run()
    ticks = {a.seq: a.tick for a in b.channels[MODBUS].acks}
    assert [ticks[s] for s in stops[:4]] == [0, 5, 6, 11]
    assert b.column("MAJ_1.Speed") == [10.0, 10.0, 1, 2, 3, 3, 3, 3, 4, 5, 6, 6]


def test_stops_go_before_the_queue_but_not_before_the_budgets_debt() -> None:
    """Budget 1: two clients' stops (2 units each) wait with B's backlog. The first goes
    before cycle 0 and leaves the credit at -1; the cycle after pays it back (credit 0:
    nothing taken); the second stop goes before cycle 2, still ahead of B's backlog, and
    cycle 3 pays for it: B's first write goes before cycle 4."""
    b = Bench(budget=1)
    b.step(5)
    for k in range(1, 6):
        b.put(B, ("MAJ_1.Speed", float(k)))
    first = b.put(A, ("MGS_1.Execute", 1))
    second = b.put(C, ("MGS_1.Execute", 1), channel=OPCUA)
    b.run()
    modbus = {a.seq: a.tick for a in b.channels[MODBUS].acks}
    opcua = {a.seq: a.tick for a in b.channels[OPCUA].acks}
    assert modbus[first] == 0
    assert opcua[second] == 2
    assert b.column("MAJ_1.Speed") == [10.0, 10.0, 10.0, 10.0, 1.0]


def test_a_stop_larger_than_the_credit_left_waits_for_a_full_credit() -> None:
    """Budget 3: B's batch of 64 items (5 units) leaves the credit at -2. The next cycle's
    credit is 1: A's stop (2 units) does not fit it and the credit is not full, so it
    waits; B, having taken 5 units, owes 4 turns and pays one. The cycle after, with its
    credit full, the stop goes first, as a batch larger than what is left always does;
    then, nobody waiting for credit, the debts are paid and B's first write goes; the next
    cycle three of B's."""
    b = Bench(budget=3)
    b.step(1)
    b.put(B, *[("MAM_1.Speed", 5.0)] * (4 * ITEMS_PER_UNIT))
    b.run()
    b.step(3)
    stop = b.put(A, ("MGS_1.Execute", 1))
    for k in range(1, 7):
        b.put(B, ("MAJ_1.Speed", float(k)))
    b.run()
    ticks = {a.seq: a.tick for a in b.channels[MODBUS].acks}
    assert ticks[stop] == 2
    assert b.column("MAJ_1.Speed")[1:] == [10.0, 1.0, 4.0]


def test_a_client_that_does_not_fit_does_not_take_its_channel_mates_turn() -> None:
    """Budget 2: D's batch of 32 items (3 units) leaves the credit at -1; then A's MAJ edge
    (2 units) and B's operand write (1) arrive on the same channel, A first. The next
    cycle's credit is 1: A does not fit and is set aside for the cycle; B, behind A in
    the turns, fits and goes in that cycle, not one later."""
    d = ClientInfo("modbus", "10.0.0.4", 50004, 4)
    b = Bench(budget=2)
    b.step(1)
    b.put(d, *[("MAJ_1.Speed", 5.0)] * (2 * ITEMS_PER_UNIT))
    b.run()
    b.step(2)
    edge = b.put(A, ("MAJ_1.Execute", 1))
    write = b.put(B, ("MAM_1.Speed", 42.0))
    b.run()
    ticks = {a.seq: a.tick for a in b.channels[MODBUS].acks}
    assert ticks[write] == 1
    assert ticks[edge] == 2
