"""The lanes of one motion group, their order, and the axes left to compose in Python.

Order, masters before slaves: time-driven lanes (jogs, profiles, stop ramps, S-curve
ramps) read no other axis and step first; followers on an actual position read feedback,
which composition never changes, and step next; followers on a command position read their
master's command of this cycle, so they step by level: level 0 when the master is in a time lane,
in an actual-position lane, in another group or has no motion; level k + 1 when the master
is a command follower at level k. A follower whose master is composed in Python leaves its
lane (it is composed in Python after its master). Axes a lane moves out in a step are
composed in Python at that point, before any later level reads them.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import chain, repeat
from operator import attrgetter

import numpy as np

from ..axis import Axis
from ..cams import CamProcess
from ..enums import MasterReference
from ..gearing import GearProcess
from ..group import MotionGroup
from ..processes import JogProcess, MoveProcess, Process, StopRamp
from ..state import AxisArrays
from ..trapezoid import TrapezoidProfile
from .base import Compose, Lane, LevelledLane
from .cams import CamLane
from .gears import CatchUpLane, FractionLane, GearLane, gear_source
from .levels import FollowerLevels
from .ramps import CruiseLane, ProfileLane, StopLane
from .scurve import SCurveLane

#: processes released per step after a rebuild dropped many (:meth:`GroupLanes.step`)
RELEASE_CHUNK = 32


_OWN_PROCESSES = attrgetter("_processes")
_STOP_ROWS = attrgetter("stop_rows")


def _offer_again(axes: Sequence[Axis]) -> None:
    """Mark every process of ``axes`` to be offered to the lanes again. Their process
    lists are read in a C-level pass (a group of 256 axes, most at rest, costs no Python
    step per axis without a process); an axis whose ramp is still a stop row, whose list
    only reading ``processes`` makes, is read the long way."""
    if list(map(_STOP_ROWS, axes)).count(None) != len(axes):  # (rows have a length)
        for ax in axes:
            for p in ax.processes:
                p.offer_pending = True
        return
    for p in chain.from_iterable(map(_OWN_PROCESSES, axes)):
        p.offer_pending = True


class GroupLanes(FollowerLevels):
    """The lanes of one motion group, and the axes it still composes in Python (their
    command followers' levels: :class:`.levels.FollowerLevels`)."""

    # what :meth:`_python_order` keeps (class defaults: lanes restored from older state)
    _order: list[Axis] | None = None
    _order_idx: np.ndarray = np.zeros(0, dtype=np.intp)
    _n_axes = 0  # axis indices are below this
    _release: list[list[Process]] = []  # noqa: RUF012 (replaced per instance, see __init__)
    #: only the time-driven lanes' membership changed since the last rebuild (see
    #: :attr:`.base.Lane.RELEVELS`); a class default for lanes restored from older state
    joined = False
    #: followers handed from one lane to another since the last rebuild (see
    #: :meth:`_offer_locked`), and their levels by ``id`` of the process (class defaults
    #: for lanes restored from older state)
    handed = False
    _handed: dict[int, int] = {}  # noqa: RUF012 (replaced per instance, see __init__)
    #: followers admitted to a follower lane since the last rebuild (``Lane.admit``),
    #: with nothing else marking the lanes ``dirty``: the rebuild levels only them
    #: (:meth:`_hand_over`); a class default for lanes restored from older state
    followed = False

    def __init__(self, group: MotionGroup) -> None:
        self.group = group
        self.cruise = CruiseLane(self)
        self.profiles = ProfileLane(self)
        self.stops = StopLane(self)
        self.scurves = SCurveLane(self)
        self.followers: dict[MasterReference, tuple[LevelledLane, ...]] = {
            src: (
                GearLane(self, src),
                FractionLane(self, src),
                CatchUpLane(self, src),
                CamLane(self, src),
            )
            for src in (MasterReference.COMMAND, MasterReference.ACTUAL)
        }
        self.all: tuple[Lane, ...] = (
            self.cruise,
            self.profiles,
            self.stops,
            self.scurves,
            *self.followers[MasterReference.ACTUAL],
            *self.followers[MasterReference.COMMAND],
        )
        #: number of levels of command followers
        self.depth = 0
        #: (lane, level) of every non-empty follower level, in stepping order
        self.schedule: list[tuple[LevelledLane, int]] = []
        #: the group's axes in composition order, without those in a lane
        self.python_order: list[Axis] = list(group.order)
        self.dirty = False
        self.joined = False
        self.handed = False
        self._handed = {}
        self.followed = False
        self._ordered = {}
        #: processes that left the lanes, freed a chunk per step (:meth:`_defer_release`)
        self._release: list[list[Process]] = []

    def __len__(self) -> int:
        return sum(len(lane) for lane in self.all)

    def offer(self, ax: Axis, p: Process) -> None:
        """``p`` is the only, active process of ``ax`` and nothing is buffered: admit it
        to the lane of its state, if there is one."""
        kind = type(p)
        if kind is JogProcess:
            prof = p.profile  # type: ignore[attr-defined]
            if prof.finished:  # CruiseLane.accepts
                self.cruise.admit(p, ax)
            elif isinstance(prof, TrapezoidProfile):
                # ProfileLane.accepts: planned (built, or requested: a jog just commanded)
                if prof.request is not None or prof._plan is not None:
                    self.profiles.admit(p, ax)
            elif SCurveLane.accepts(p):
                self.scurves.admit(p, ax)
        elif kind is MoveProcess:
            if ProfileLane.accepts(p):
                self.profiles.admit(p, ax)
            elif SCurveLane.accepts(p):
                self.scurves.admit(p, ax)
        elif kind is StopRamp:
            if StopLane.accepts(p):
                self.stops.admit(p, ax)
            elif SCurveLane.accepts(p):
                self.scurves.admit(p, ax)
        elif kind is GearProcess:
            self._offer_follower(p, ax)
        elif kind is CamProcess:
            self._offer_cam(p, ax)

    def _offer_cam(self, p: Process, ax: Axis) -> None:
        assert isinstance(p, CamProcess)
        if p.index is None or not CamLane.accepts(p):
            return
        if p.source == MasterReference.COMMAND and not self._master_settled(p.index):
            return  # its master is composed in Python: so must it be
        for follower in self.followers[p.source]:
            if isinstance(follower, CamLane):
                follower.admit(p, ax)
                return

    def _offer_follower(self, p: Process, ax: Axis) -> None:
        assert isinstance(p, GearProcess)
        if p.single is not None:
            source = gear_source(p)
            if source == MasterReference.COMMAND and not self._master_settled(p.single.index):
                return  # its master is composed in Python: so must it be (see rebuild)
            for follower in self.followers[source]:
                if follower.accepts(p):
                    follower.admit(p, ax)
                    return

    def _gear_lane(self, source: MasterReference) -> GearLane:
        for follower in self.followers[source]:
            if isinstance(follower, GearLane):
                return follower
        raise AssertionError("every source has a lane of locked gears")

    def _offer_locked(
        self, reached: Sequence[tuple[Process, Axis]], gears: GearLane, level: int
    ) -> None:
        """:meth:`_offer_follower` of the real-ratio gears the catch-up lane of ``gears``'s
        source locked at ``level`` (one master, locked, not a fraction:
        ``GearLane.accepts``), in row order, without asking each which lane it belongs
        to. Each keeps its level in the lane of locked gears (the same master, read the
        same way), which the next rebuild takes without levelling the followers again
        (:meth:`_hand_over`); a gear whose master is no longer settled stays out, and
        the followers are levelled again."""
        taken: Sequence[tuple[Process, Axis]] = reached
        if gears.source == MasterReference.COMMAND:
            settled = self._master_settled
            taken = [(p, ax) for p, ax in reached if settled(p.single.index)]  # type: ignore[attr-defined]
            if len(taken) != len(reached):
                self.dirty = True
        gears.hand_in_all(taken)
        self._handed.update(dict.fromkeys([id(p) for p, _ in taken], level))

    def _master_settled(self, index: int) -> bool:
        """The master at ``index`` is composed before any follower steps: in another group,
        without motion, or in a lane (its level is decided at the rebuild)."""
        master = self.group.by_index.get(index)
        if master is None:
            return True
        # (the property's call saved: no stop row here unless its ramp is to be made)
        procs = master._processes if master.stop_rows is None else master.processes
        if not procs and master.buffered is None:
            return True
        return len(procs) == 1 and procs[0].lane is not None

    def rebuild(self, s: AxisArrays, axes: Sequence[Axis]) -> None:
        """Apply the changes of membership; order the command followers by level (when
        only the time-driven lanes gained members or ended some themselves, ``joined``
        without ``dirty``: :meth:`_rejoin`, the followers as they are)."""
        if not self.dirty:
            if self.handed or self.followed:
                self._hand_over(s, axes)
            else:
                self._rejoin(s)
            if not self.dirty:
                return
        if self._emptied():
            return
        dropped = [lane.members for lane in self.all if lane.changed and lane.members]
        for lane in self.all:
            lane.rebuild()
        self._defer_release(dropped)
        self.cruise.place(s)
        for lane in self.followers[MasterReference.ACTUAL]:
            lane.order([0] * len(lane.members))
        self._order_command_followers(axes)
        self.schedule = self._schedule()
        self.python_order = self._python_order()
        # membership changed: a follower's master may have joined a lane
        _offer_again(self.python_order)
        self.dirty = False  # evictions while levelling set it: they are rebuilt above
        self._rebuilt()

    def _emptied(self) -> bool:
        """The rebuild when no lane holds or takes a member and none changed since it was
        last rebuilt (the lanes a group stop emptied, ``stop_plan.clear_emptied``): what
        the full rebuild leaves, without its passes over lanes that have nothing to
        order. The follower lanes are ordered empty, nothing is scheduled, and the
        axes left to Python are those without a stop row (none, when the rows stop the
        whole group). False, with nothing done, when a lane is not that empty."""
        for lane in self.all:
            if lane.members or lane._joining or lane.changed:
                return False
        self.stops.rebuild()  # (its rows compacted: those whose ramp left are dropped)
        ordered = self._ordered
        if ordered is None:
            ordered = self._ordered = {}
        for lane in self.followers[MasterReference.ACTUAL]:
            lane.order([])
        for lane in self.followers[MasterReference.COMMAND]:
            last = ordered.get(lane)
            if last is None or last[0] is not lane.members or last[1]:
                lane.order([])
                ordered[lane] = (lane.members, [])
        self.depth = 0
        self.schedule = []
        rows = self.stops.rows
        if len(rows) == 1 and len(rows[0].axes) == len(self.group.order):
            # (a stop's rows are on distinct axes of the group: here, on all of them)
            self.python_order = []
        else:
            self.python_order = self._python_order()
            _offer_again(self.python_order)
        self.dirty = False
        self._rebuilt()
        return True

    def _rebuilt(self) -> None:
        """What every rebuild leaves: nothing joined, handed over or followed since."""
        self.joined = False
        self.handed = False
        self.followed = False
        self._handed = {}

    def _hand_over(self, s: AxisArrays, axes: Sequence[Axis]) -> None:
        """The rebuild after followers passed from one lane to another at the same level
        (gears the catch-up lane locked, now in the lane of locked gears: the same
        master, read the same way) or were admitted to a follower lane (``followed``),
        besides what :meth:`_rejoin` handles. The followers already in a lane keep
        their levels: what sets a level (the master's lane, its level, its motion) is
        unchanged unless the lanes were marked ``dirty``, or a follower admitted now
        is on an axis that one of them reads (that axis was at rest, level 0 for its
        followers, and is now a follower). So each command follower lane is ordered by
        the levels its members had, the levels recorded for those handed in and, for
        those admitted, the level :meth:`_order_command_followers` would give them,
        worked out from their masters alone (:meth:`_level_of`) instead of levelling
        every follower again. When a level is not known (a lane restored from older
        state, a master composed in Python, an axis read by a follower already in a
        lane), ``dirty`` is set: the full rebuild follows."""
        cmd = self.followers[MasterReference.COMMAND]
        before: dict[LevelledLane, list[int]] = {}
        read: list[np.ndarray] = []
        for lane in cmd:
            if lane.changed:
                n = len(lane.members)
                if len(lane.member_levels) != n or len(lane.midx) != n or lane.midx_stale:
                    self.dirty = True
                    return
                before[lane] = lane.member_levels
            if len(lane.midx):
                read.append(lane.midx)
        changed = [x for x in self.all if x.changed]
        self._defer_release([x.members for x in changed if x.members])
        for x in changed:
            x.rebuild()
        # the axes that joined a lane: appended after the members kept (taken before the
        # follower lanes are ordered by level, which moves them)
        joined = set(map(id, chain.from_iterable(lane.axes[len(lane._kept) :] for lane in changed)))
        handed = self._handed
        levels_of: dict[LevelledLane, list[int]] = {}
        admitted: list[tuple[LevelledLane, list[int]]] = []  # (lane, rows) admitted
        for lane, old in before.items():
            kept = lane._kept
            levels = [old[k] for k in kept]
            n = len(lane.members)
            if not handed:
                rows = list(range(len(levels), n))
                levels += [-1] * len(rows)  # worked out from their masters
            else:
                # (the levels recorded for those handed in, read in a C-level pass)
                start = len(levels)
                found = list(map(handed.get, map(id, lane.members[start:]), repeat(-1)))
                rows = (
                    [start + j for j, level in enumerate(found) if level < 0] if -1 in found else []
                )
                levels += found
            if rows:
                admitted.append((lane, rows))
            levels_of[lane] = levels
        self.cruise.place(s)
        for lane in self.followers[MasterReference.ACTUAL]:
            if lane in changed:
                lane.order([0] * len(lane.members))  # (the others are as they were)
        if admitted:
            self._admitted = (levels_of, admitted, read)
            self._order_command_followers(axes)
            if self.dirty:
                return
        else:
            self._order_levelled(levels_of)
        self.schedule = self._schedule()
        if self.joined:
            self.python_order = self._python_order()
        else:
            # only followers joined or passed between follower lanes: the axes left to
            # Python are those that were, without the axes that joined a lane (no axis
            # left one for Python: that marks the lanes dirty)
            if joined:
                self.python_order = [ax for ax in self.python_order if id(ax) not in joined]
        _offer_again(self.python_order)
        self._rebuilt()

    def _rejoin(self, s: AxisArrays) -> None:
        """The rebuild after changes that leave the command followers' levels as they
        are (:attr:`.base.Lane.RELEVELS`): jogs, moves and stop ramps admitted to the
        time-driven lanes (an axis that starts from rest: its followers read it at level
        0 before and after), jogs handed from the profile lane to the cruise lane, ramps
        that came to rest in the stop lane. The time-driven lanes take their new members
        and drop those that left; the follower lanes, their order and the schedule stay
        as they are. (128 jogs starting at 256 axes: the followers' levels were about
        0.15 ms of the step that starts them.)"""
        lanes = (self.cruise, self.profiles, self.stops, self.scurves)
        dropped = [lane.members for lane in lanes if lane.changed and lane.members]
        for lane in lanes:
            lane.rebuild()
        self._defer_release(dropped)
        self.cruise.place(s)
        self.python_order = self._python_order()
        # a follower composed in Python may now read a master in a lane
        _offer_again(self.python_order)
        self.joined = False

    def _schedule(self) -> list[tuple[LevelledLane, int]]:
        """(lane, level) of every non-empty follower level, in stepping order."""
        schedule = [(lane, 0) for lane in self.followers[MasterReference.ACTUAL] if lane.members]
        cmd = self.followers[MasterReference.COMMAND]
        for level in range(self.depth):
            for lane in cmd:
                if level < len(lane.levels) and lane.levels[level].stop > lane.levels[level].start:
                    schedule.append((lane, level))
        return schedule

    def _defer_release(self, dropped: list[list[Process]]) -> None:
        """Keep the processes that left the lanes alive a little longer: the members a
        group stop evicts (256 jogs and gears, their profiles and limits) would
        otherwise all be freed in this rebuild, in the cycle that must stop the machine
        on time, for about half a microsecond each. They are released RELEASE_CHUNK at
        a time, one chunk per step from the next one on (:meth:`step`), if nothing else
        holds them."""
        if not any(len(members) > RELEASE_CHUNK for members in dropped):
            return  # few: freed here, as they always were
        self._release = [
            *self._release,
            *(m[k : k + RELEASE_CHUNK] for m in dropped for k in range(0, len(m), RELEASE_CHUNK)),
            [],  # popped first (the list is popped from its end): nothing freed this step
        ]

    def __getstate__(self) -> dict[str, object]:
        state = dict(self.__dict__)
        state["_release"] = []  # references kept only to free them later
        if state.get("handed"):
            # levels kept by identity, which a copy does not keep: levelled again
            state["handed"] = False
            state["_handed"] = {}
            state["dirty"] = True
        return state

    def _python_order(self) -> list[Axis]:
        """The group's axes in composition order without those in a lane: marked in
        an array by the lanes' indices (a group stop puts every axis in the stop lane:
        nothing is left to compose, and nothing is looked up axis by axis)."""
        order = self.group.order
        if order is not self._order:
            self._order = order
            self._order_idx = np.array([ax.index for ax in order], dtype=np.intp)
            self._n_axes = int(self._order_idx.max()) + 1 if order else 0
        laned = np.zeros(self._n_axes, dtype=bool)
        for lane in self.all:
            if lane.axes:
                laned[lane.idx] = True
        for rows in self.stops.rows:
            laned[rows.idx] = True
        left = np.flatnonzero(~laned[self._order_idx])
        if left.size == len(order):
            return list(order)
        return list(map(order.__getitem__, left.tolist()))

    def step(self, s: AxisArrays, dt: float, compose: Compose) -> None:
        if self._release:
            self._release.pop()  # (see _defer_release)
        if self.cruise.members:
            self.cruise.step(s)
        if self.profiles.members:
            # (jogs at speed are handed to the cruise lane by the profile lane's step)
            self.profiles.step(s, compose)
        if self.stops.members or self.stops.rows:
            self.stops.step(s, dt, compose)
        if self.scurves.members:
            self.scurves.step(s, compose)
        for lane, level in self.schedule:
            lane.step(s, level, dt, compose)
            if type(lane) is CatchUpLane and lane.reached:
                # gears locked in the lane: offered as Motion.offer would, in row order;
                # the lane of locked gears takes their columns if it took them all
                gears = self._gear_lane(lane.source)
                self._offer_locked(lane.reached, gears, lane.reached_level)
                columns = lane.locked_columns
                if columns is not None:
                    gears.take_batch(lane.reached, columns, lane.locked_masters)
                lane.reached = ()
                lane.locked_columns = None
                lane.locked_masters = None
