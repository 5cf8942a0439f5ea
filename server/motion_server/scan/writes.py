"""The write queue: judged client batches waiting for the cycle that applies them, and
the budget each cycle has for them.

A cycle applies queued batches before it runs, but only as many as its **budget** allows,
so that a flood of writes can neither make a cycle late nor keep the scan behind its
schedule. The budget is a count, not a time (a time would make the same writes give a
different trace under the manual and fast clocks). What is counted is what a batch costs
the scan, in units of about 25 µs measured on the reference machine (256 axes in one group,
``bench/write_abuse.py``; see ``docs/architecture.md``):

- every batch: 1 (applying it, waking the instances it writes, publishing what changed),
  plus 1 for every :data:`ITEMS_PER_UNIT` items;
- every instruction trigger it writes to 1 (``Execute``, ``Enable``), which makes the next
  cycle execute the instruction: 1 more, plus 1 for every :data:`AXES_PER_UNIT` axes the
  instruction commands (an axis operand is one axis; a group operand the largest group of
  the map): an MGS on a group of 256 axes costs 34, an MAJ 2, a write of an operand 1.

A cycle's credit is refilled to the budget before it applies its batches. A batch is taken
when its cost fits the credit left; a batch that costs more than a whole budget is taken
when the credit is full, alone, and the excess is a debt the next cycles pay back (they
take nothing until the credit is positive again). What is not taken waits for the next
cycle.

Order and share. When everything waiting fits, batches are taken in arrival order, as
they always were. When it does not, the channels (front-ends) take turns, and inside a
channel its clients (connections) do: a client whose batch does not fit is done for this
cycle, and the first such client has the first turn of the next one, so a batch larger
than the budget goes in the next cycle whose credit is full (not never). One client's
batches are always taken in the order they arrived, whatever the others do.

A turn is worth one unit (deficit round robin): a client that took a batch of ``c`` units
owes ``c - 1`` turns, and lets its turns pass until it paid them, while the others take
theirs. A round in which nobody takes anything pays debts only when nobody is waiting for
credit (else a cycle would pay them all at once while the others wait). So a connection
cannot take more than its share of the budget by sending costly batches: a client
toggling a group stop (34 units on 256 axes) gets one through per 34 turns, while one
writing operands gets one a turn. Batches of one unit each are taken one a turn, as
before. What a client owes is forgotten in a cycle where everything waiting
fits (nobody waited for it).

Stops come before the queue. When not everything waiting fits, a batch that sets the
trigger of a stop instruction (:data:`STOPS`: MGS, MGSD, MAS, MASD, MC_Stop, MC_Halt) and
is the next of its client's batches is taken right after the watchdog writes, ahead of
every other client's, when its client owes nothing and the credit allows it as it allows
any batch (it fits what is left, or the credit is full and it goes alone): a stop is not
behind another client's backlog. It is behind the budget's debt (at most the few cycles
that pay back the last command larger than the budget, 5 after an MGS on 256 axes at
1 ms): a stop executes a command on every axis it stops, and taking stops whatever the
debt let four clients toggling MGS put one into almost every cycle, and letting them in
as soon as the credit was positive into every fourth cycle instead of every fifth, with
more late cycles in ``bench/write_abuse.py``. Its cost is charged as usual and, as it took
no turn, the client owes ``cost`` turns; one such stop is taken a cycle: a client that
toggles stops as fast as it can gets them through at its share, like any other batch. A
stop behind its own client's earlier batches waits for them (their order is the
client's), and those are few: a front-end lets a client have only a few batches
unacknowledged.

Watchdog writes come first. A batch that writes only watchdog tags (``<name>.Heartbeat``,
``<name>.Reset``: the Safety folder) is taken before every other batch of every cycle,
outside the budget: a heartbeat is never behind a queue, not even its own client's. It is
cheap (no instruction runs for it), and a front-end lets a client have only a few batches
unacknowledged (:mod:`motion_server.frontends.link`), so their number is bounded too.

Acknowledged order. The image's meta word ``APPLIED`` of a channel tells the front-end up
to which sequence number its batches are in the image (it then stops laying its own
values over the snapshot). Batches of one channel may now be taken out of order (a
heartbeat, another client's turn), so the word holds the highest sequence number below
which every batch of the channel was applied (:meth:`WriteQueue.settle`).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

from ..image import wire
from ..image.layout import ImageLayout
from ..instructions.registry import instruction_type
from ..instructions.schema import Kind
from ..kernel import Controller
from ..tagmap import Folder
from .channel import Channel

#: budget units per millisecond of the base period (the default of ``write_budget``):
#: about 20 % of a period's time on the reference machine, headroom for a loaded one
BUDGET_PER_MS = 8
#: batch items per extra unit
ITEMS_PER_UNIT = 16
#: axes an instruction commands per extra unit of its execution
AXES_PER_UNIT = 8
#: instruction types whose trigger stops motion: a batch that sets one goes before the queue
STOPS = frozenset({"MGS", "MGSD", "MAS", "MASD", "MC_Stop", "MC_Halt"})


def default_budget(period: float) -> int:
    """The budget of a cycle of ``period`` seconds when the site map sets none."""
    return max(1, round(BUDGET_PER_MS * period * 1000.0))


class BatchCosts:
    """What each batch of a map costs, and whether it is a watchdog write (computed once
    from the map: the same writes always cost the same)."""

    def __init__(self, layout: ImageLayout, ctl: Controller) -> None:
        largest_group = max((len(g.axes) for g in ctl.groups), default=0)
        #: slot of an instruction trigger -> what executing the instruction costs
        self.triggers: dict[int, int] = {}
        #: slots of the triggers of the stop instructions (:data:`STOPS`)
        stops: set[int] = set()
        watchdog: set[int] = set()
        for slot, tag in enumerate(layout.tags):
            if tag.folder == Folder.SAFETY:
                watchdog.add(slot)
            elif tag.instruction:
                cls = instruction_type(tag.instruction)
                if tag.field != cls.TRIGGER:
                    continue
                axes = 0
                for op in cls.OPERANDS:
                    if op.kind == Kind.AXIS:
                        axes += 1
                    elif op.kind == Kind.GROUP:
                        axes += largest_group
                self.triggers[slot] = 1 + axes // AXES_PER_UNIT
                if tag.instruction in STOPS:
                    stops.add(slot)
        self.watchdog = frozenset(watchdog)
        self.stops = frozenset(stops)

    def of(self, items: list[tuple[int, float]]) -> tuple[int, bool]:
        """(cost, watchdog write) of a batch's items."""
        cost = 1 + len(items) // ITEMS_PER_UNIT
        triggers = self.triggers
        watchdog = bool(items)
        for slot, value in items:
            if value and slot in triggers:
                cost += triggers[slot]
            if watchdog and slot not in self.watchdog:
                watchdog = False
        return cost, watchdog

    def stops_motion(self, items: list[tuple[int, float]]) -> bool:
        """Whether a batch sets the trigger of a stop instruction."""
        stops = self.stops
        return any(value and slot in stops for slot, value in items)


@dataclass(eq=False)
class Queued:
    """One batch in the queue."""

    channel: Channel
    batch: wire.Batch
    cost: int
    watchdog: bool
    #: sets the trigger of a stop instruction (taken before the queue)
    stop: bool = False
    #: taken by a cycle (or at once); then applied by the scan
    taken: bool = False
    #: applied, or refused: done with
    settled: bool = False
    #: when the scan received it (``Scan.clock`` seconds; None: not noted): a
    #: heartbeat's arrival, by which a watchdog times out with the wall clock
    arrived: float | None = None

    @property
    def client(self) -> str:
        return self.batch.client.key


@dataclass
class _ChannelQueue:
    """One channel's batches: all of them in arrival order (for its APPLIED word), and
    the ordinary ones per client, with the clients in turn order."""

    arrived: deque[Queued] = field(default_factory=deque)
    clients: dict[str, deque[Queued]] = field(default_factory=dict)
    turns: deque[str] = field(default_factory=deque)
    #: the sequence number of the last batch received
    last_seq: int = 0
    #: turns a client owes for the units it took beyond one a turn (absent: none)
    owed: dict[str, int] = field(default_factory=dict)


class WriteQueue:
    """The batches waiting, and the budget of the cycles that take them (see the module)."""

    def __init__(self, budget: int, costs: BatchCosts) -> None:
        if budget < 1:
            raise ValueError(f"a write budget of {budget}: it must be at least 1")
        self.budget = budget
        self.costs = costs
        #: what the next cycle may still take (negative: a debt)
        self.credit = budget
        #: cycles that left a batch waiting (the budget was spent)
        self.deferred_cycles = 0
        self._arrived: deque[Queued] = deque()
        self._watchdog: deque[Queued] = deque()
        self._channels: dict[int, _ChannelQueue] = {}
        #: channels with ordinary batches waiting, in turn order
        self._turns: deque[int] = deque()
        self._waiting = 0
        self._ordinary_cost = 0
        #: stop batches waiting
        self._stops = 0

    def __len__(self) -> int:
        """Batches waiting (not taken yet)."""
        return self._waiting

    def put(self, ch: Channel, batch: wire.Batch) -> Queued:
        """Queue a batch that arrived on ``ch``."""
        cost, watchdog = self.costs.of(batch.items)
        stop = not watchdog and self.costs.stops_motion(batch.items)
        q = Queued(ch, batch, cost, watchdog, stop)
        cq = self._channels.get(ch.number)
        if cq is None:
            cq = self._channels[ch.number] = _ChannelQueue()
        cq.arrived.append(q)
        cq.last_seq = batch.seq
        self._arrived.append(q)
        self._waiting += 1
        self._stops += stop
        if watchdog:
            self._watchdog.append(q)
            return q
        key = q.client
        lane = cq.clients.get(key)
        if lane is None:
            lane = cq.clients[key] = deque()
            cq.turns.append(key)
        lane.append(q)
        if ch.number not in self._turns:
            self._turns.append(ch.number)
        self._ordinary_cost += cost
        return q

    def last_received(self, channel: int) -> int | None:
        """The sequence number of the last batch of ``channel`` still waiting to be
        applied (None when every one was): a new front-end on the channel numbers its
        batches after it."""
        cq = self._channels.get(channel)
        if cq is None or not cq.arrived:
            return None
        return cq.last_seq

    # -- taking -----------------------------------------------------------------------------
    def take_first(self) -> Queued | None:
        """The batch that arrived first of those waiting, whatever the budget (time stands
        still: the manual clock between steps)."""
        arrived = self._arrived
        while arrived and arrived[0].taken:
            arrived.popleft()
        if not arrived:
            return None
        q = arrived.popleft()
        if q.watchdog:
            assert self._watchdog[0] is q
            self._watchdog.popleft()
        else:
            self._take_head(q.channel.number, q.client)
        self._taken(q)
        return q

    def take_cycle(self) -> list[Queued]:
        """The batches the next cycle applies, in the order it applies them: the watchdog
        writes, then what the budget allows (see the module)."""
        out: list[Queued] = []
        while self._watchdog:
            q = self._watchdog.popleft()
            self._taken(q)
            out.append(q)
        self.credit = min(self.budget, self.credit + self.budget)
        if self._ordinary_cost <= self.credit:
            for cq in self._channels.values():  # nobody waits for anybody: nobody owes
                if cq.owed:
                    cq.owed.clear()
        elif self._stops and self.credit > 0:
            out.extend(self._stop_taken())
        if self._ordinary_cost and self._ordinary_cost <= self.credit:
            self.credit -= self._ordinary_cost
            for q in self._arrived:
                if not q.taken:
                    self._take_head(q.channel.number, q.client)
                    self._taken(q)
                    out.append(q)
            self._arrived.clear()
            return out
        if self._ordinary_cost:
            out.extend(self._turns_taken())
            if self._ordinary_cost:
                self.deferred_cycles += 1
        while self._arrived and self._arrived[0].taken:
            self._arrived.popleft()
        return out

    def _stop_taken(self) -> list[Queued]:
        """The first stop waiting at the head of its client's batches, whose client owes
        nothing: taken before the queue when the credit allows it (see the module)."""
        for q in self._arrived:
            if not q.stop or q.taken:
                continue
            number, key = q.channel.number, q.client
            cq = self._channels[number]
            if cq.clients[key][0] is not q or cq.owed.get(key, 0):
                continue
            if q.cost > self.credit and self.credit != self.budget:
                return []  # larger than what is left: alone, in a cycle with its credit full
            self.credit -= q.cost
            self._owe(cq, key, q.cost + 1)  # it took no turn of its own
            self._take_head(number, key, rotate=True)
            self._taken(q)
            return [q]
        return []

    def _owe(self, cq: _ChannelQueue, key: str, cost: int) -> None:
        if cost > 1:
            cq.owed[key] = cq.owed.get(key, 0) + cost - 1

    def _turns_taken(self) -> list[Queued]:
        """Channels, and inside them clients, take turns while the credit lasts."""
        out: list[Queued] = []
        blocked: set[tuple[int, str]] = set()
        first_blocked: tuple[int, str] | None = None
        while self.credit > 0:
            progress = took = set_aside = False
            for number in list(self._turns):
                cq = self._channels[number]
                key = next((k for k in cq.turns if (number, k) not in blocked), None)
                if key is None:
                    continue
                owed = cq.owed.get(key, 0)
                if owed:  # the turn pays for units taken before
                    cq.owed[key] = owed - 1
                    self._rotate(number, key)
                    progress = True
                    continue
                head = cq.clients[key][0]
                if head.cost <= self.credit or self.credit == self.budget:
                    self.credit -= head.cost
                    self._owe(cq, key, head.cost)
                    self._take_head(number, key, rotate=True)
                    self._taken(head)
                    out.append(head)
                    progress = took = True
                    if self.credit <= 0:
                        break
                else:
                    blocked.add((number, key))  # done for this cycle
                    progress = set_aside = True  # its channel's next client may fit
                    if first_blocked is None:
                        first_blocked = (number, key)
            if not progress or (not took and not set_aside and blocked):
                # a round where nobody took anything pays no debt while others wait for
                # credit: those would be turns of nobody's, and a client toggling stops
                # would owe nothing after every cycle the budget was spent
                break
        if first_blocked is not None:
            # the first client that did not fit has the first turn of the next cycle, so a
            # batch larger than the budget goes when the credit is full, not never
            number, key = first_blocked
            cq = self._channels[number]
            if key in cq.clients:
                cq.turns.remove(key)
                cq.turns.appendleft(key)
                self._turns.remove(number)
                self._turns.appendleft(number)
        return out

    def _take_head(self, number: int, key: str, rotate: bool = False) -> None:
        """Remove the head of a client's lane; a client (channel) that was served goes to
        the end of the turns (``rotate``), one with nothing left leaves them."""
        cq = self._channels[number]
        lane = cq.clients[key]
        q = lane.popleft()
        self._ordinary_cost -= q.cost
        if not lane:
            del cq.clients[key]
            cq.turns.remove(key)
            if not cq.owed.get(key, 1):
                del cq.owed[key]
        elif rotate:
            cq.turns.remove(key)
            cq.turns.append(key)
        if not cq.turns:
            self._turns.remove(number)
        elif rotate:
            self._turns.remove(number)
            self._turns.append(number)

    def _rotate(self, number: int, key: str) -> None:
        """A client (and its channel) had its turn: to the end of the turns."""
        cq = self._channels[number]
        cq.turns.remove(key)
        cq.turns.append(key)
        self._turns.remove(number)
        self._turns.append(number)

    def _taken(self, q: Queued) -> None:
        q.taken = True
        self._waiting -= 1
        self._stops -= q.stop

    # -- done with --------------------------------------------------------------------------
    def settle(self, q: Queued) -> int | None:
        """``q`` was applied (or refused): the channel's new APPLIED sequence number (every
        batch of the channel up to it is done with), or None when it did not move."""
        q.settled = True
        cq = self._channels[q.channel.number]
        arrived = cq.arrived
        seq = None
        while arrived and arrived[0].settled:
            seq = arrived.popleft().batch.seq
        return seq

    def take_all(self) -> Iterable[Queued]:
        """Every batch waiting, in arrival order (the last words of a stopping scan)."""
        while True:
            q = self.take_first()
            if q is None:
                return
            yield q
