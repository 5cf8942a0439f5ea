"""A fast lane: the processes of one kind and state, with their state as parallel arrays.

A lane steps all its members with a few array operations that repeat, for each member,
the floating-point operations of the member's own ``step`` in the same order, so the
result is bit-identical to stepping the objects one by one. A member that changes state
in a step (finishes, locks, reaches its speed) is *moved out* before the lane computes:
the lane writes its state before the step back into the process object, and the caller
composes the axis in Python, through the process's own code, in the same step.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Callable, Collection, Sequence
from operator import attrgetter, itemgetter
from typing import Any, ClassVar, Protocol, cast

import numpy as np

from ..axis import Axis
from ..enums import AbortReason, MasterReference, ProcessState
from ..processes import Process
from ..state import AxisArrays, Index, compact, compact_list

#: composes one axis in Python now (its process changes state this step)
Compose = Callable[[Axis], None]

_LANE = attrgetter("lane")
_INDEX = attrgetter("index")
_FIRST = itemgetter(0)
_SECOND = itemgetter(1)


class LaneOwner(Protocol):
    """The lanes of a group: a change of membership marks them for a rebuild, ``dirty``
    (the followers levelled again) or ``joined`` (only the time-driven lanes' members
    changed, without an axis leaving for Python: see :attr:`Lane.RELEVELS`) or ``handed``
    (followers passed from one lane to another at the same level, ``Lane.hand_in``) or
    ``followed`` (followers admitted: only they are levelled, if no follower already in
    a lane reads their axes)."""

    dirty: bool
    joined: bool
    handed: bool
    followed: bool


class Lane:
    """Members (process, axis) and their state as arrays named by ``FIELDS``.

    Members that joined since the last :meth:`rebuild` wait in ``_joining``: their
    process objects are current until the lane steps them. While a process is a member
    (``p.lane is self``) its ``position``, ``velocity`` and ``acceleration`` are stale
    until the lane evicts or syncs it; its flags (state, locked, at speed) are current.
    """

    #: names of the per-member arrays, loaded from a member by :meth:`_load`
    FIELDS: ClassVar[tuple[str, ...]] = ()
    #: dtype of a field (float unless named here)
    DTYPES: ClassVar[dict[str, Any]] = {}
    #: fields with one row of this many values per member
    WIDTHS: ClassVar[dict[str, int]] = {}
    #: the fields :meth:`_store_columns` reads (those :meth:`evict_all` lists)
    STORED: ClassVar[tuple[str, ...]] = ()
    #: what a lane keeps of a batch admitted to an empty ``_joining`` (see
    #: :meth:`_batch_columns`); dropped at the rebuild (a class default as well, for
    #: lanes restored from state saved before batches existed)
    _batch: Any = None
    #: an admission to this lane can change the levels of the command followers (a
    #: follower lane joins them: the owner is marked ``followed``, and its rebuild
    #: levels the new members alone when no member already in a lane reads their axes,
    #: ``GroupLanes._hand_over``). False for the time-driven lanes: an axis admitted to
    #: one was without motion, in another time-driven lane or composed in Python, and
    #: in each case the followers that read it keep their level (0, or out of the
    #: lanes already), so the group's lanes are rebuilt without levelling them again
    #: (``GroupLanes.rebuild``). An eviction always levels them again: its axis is
    #: composed in Python from then on.
    RELEVELS: ClassVar[bool] = True
    #: the rows (before the last :meth:`rebuild`) of the members it kept, in order
    _kept: list[int] = []  # noqa: RUF012 (replaced per rebuild, never mutated)
    #: the axis indices of the members :meth:`rebuild` appends to all those it kept,
    #: for :meth:`_set_members` (None: every member's index is read)
    _appended: list[int] | None = None

    def __init__(self, owner: LaneOwner) -> None:
        self._owner = owner
        self.members: list[Process] = []
        self.axes: list[Axis] = []
        self._joining: list[tuple[Process, Axis]] = []
        self._slot: dict[int, int] = {}  # id(process) -> row in the arrays
        self.idx = np.zeros(0, dtype=np.intp)  # the members' axis indices
        self.at: Index = self.idx  # the same, as a slice when consecutive
        self.arrays: dict[str, np.ndarray] = {f: self._empty(f) for f in self.FIELDS}
        #: membership changed since the last rebuild
        self.changed = False
        self._batch = None

    # -- snapshots: ``_slot`` is keyed by object identity, which a copy does not keep ------
    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_slot"] = [
            (i, self._slot[id(p)]) for i, p in enumerate(self.members) if id(p) in self._slot
        ]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        slots = state.pop("_slot")
        self.__dict__.update(state)
        self._slot = {id(self.members[i]): k for i, k in slots}

    def _empty(self, field: str) -> np.ndarray:
        width = self.WIDTHS.get(field)
        shape = (0,) if width is None else (0, width)
        return np.zeros(shape, dtype=self.DTYPES.get(field, float))

    def __len__(self) -> int:
        return len(self.members) + len(self._joining)

    @staticmethod
    def accepts(p: Process) -> bool:
        """``p`` (the only, active process of its axis) is in this lane's state."""
        raise NotImplementedError

    def admit(self, p: Process, ax: Axis) -> None:
        self._batch = None
        p.lane = self
        self._joining.append((p, ax))
        self.changed = True
        if self.RELEVELS:
            self._owner.followed = True
        else:
            self._owner.joined = True

    def hand_in_all(self, joining: Sequence[tuple[Process, Axis]]) -> None:
        """:meth:`hand_in` of each of ``joining``, in order: admitted without marking the
        owner, which the caller does (jogs at speed from the profile lane: ``joined``;
        gears locked by the catch-up lane: ``handed``)."""
        self._batch = None
        for p, _ in joining:
            p.lane = self
        self._joining.extend(joining)
        self.changed = True

    def hand_in(self, p: Process, ax: Axis) -> None:
        """:meth:`admit` ``p`` from another lane that stepped it at the level it keeps
        here (the caller records the level: ``GroupLanes._offer_locked``)."""
        self._batch = None
        p.lane = self
        self._joining.append((p, ax))
        self.changed = True

    def evict(self, p: Process) -> None:
        """Write the lane's state back into ``p`` and drop it."""
        if p.lane is not self:
            return
        p.lane = None
        p.offer_pending = True
        k = self._slot.pop(id(p), None)
        if k is not None:
            self._store(p, k)
        self.changed = True
        self._owner.dirty = True

    def pass_on(self, p: Process) -> None:
        """:meth:`evict` ``p`` from this time-driven lane (``RELEVELS`` False) for a
        successor on its axis that joins a time-driven lane before the next rebuild (a
        jog replaced by a jog): the followers that read the axis keep their level, so the
        owner is marked ``joined``, not ``dirty``. The caller marks it ``dirty`` if the
        successor does not join."""
        owner = self._owner
        dirty = owner.dirty
        self.evict(p)
        owner.dirty = dirty
        owner.joined = True

    def within(self, indices: Collection[int]) -> bool:
        """Every process in the lane (members and those joining) is on an axis whose
        index is in ``indices``."""
        return all(i in indices for i in self.idx.tolist()) and all(
            ax.index in indices for _, ax in self._joining
        )

    def evict_all(self, aborted: tuple[ProcessState, AbortReason] | None = None) -> None:
        """:meth:`evict` every process in the lane, at once (a group stop empties the
        lanes of its group): the lane's columns are read as Python lists while the
        members are stored (``_store`` reads the same values, without a numpy scalar
        per field). ``aborted``: the state and abort reason then given to every member
        (what ``Process.abort`` writes), in the same pass."""
        slot = self._slot
        if (
            slot
            and len(slot) == len(self.members)
            and type(self)._store_columns is not (Lane._store_columns)
        ):
            # every member still here, in row order: written column by column
            members = self.members
            arrays = self.arrays
            self._store_columns(members, {f: arrays[f].tolist() for f in self.STORED})
            if aborted is None:
                for p in members:
                    p.lane = None
                    p.offer_pending = True
            else:
                state, reason = aborted
                for p in members:
                    p.lane = None
                    p.offer_pending = True
                    p.state = state
                    p.abort_reason = reason
            self._slot = {}
            aborted = None
        elif slot:
            arrays = self.arrays
            self.arrays = cast(dict[str, np.ndarray], {f: a.tolist() for f, a in arrays.items()})
            try:
                for p in self.members:
                    k = slot.get(id(p))
                    if k is not None and p.lane is self:
                        p.lane = None
                        p.offer_pending = True
                        self._store(p, k)
            finally:
                self.arrays = arrays
            self._slot = {}
        if aborted is not None:
            state, reason = aborted
            for p in self.members:
                p.state = state
                p.abort_reason = reason
        for p, _ in self._joining:
            if p.lane is self:
                p.lane = None
                p.offer_pending = True
        self.changed = True
        self._owner.dirty = True

    def clear(self) -> list[Process]:
        """After :meth:`evict_all`, with nothing joining: leave the lane empty now, as
        its next :meth:`rebuild` would (no member, empty arrays, nothing to rebuild),
        so that a group stop's first step does not rebuild the lanes it emptied field
        by field. Returns the members dropped (the caller decides when they are
        freed)."""
        members = self.members
        # (zero-length views: the dtype and row shape a rebuild's selection leaves)
        self.arrays = {f: a[:0] for f, a in self.arrays.items()}
        self._joining = []
        self._slot = {}
        self._batch = None
        self._set_members([], [])
        self.changed = False
        return members

    def replans(self, p: Process) -> bool:
        """``p`` can be planned anew where it is (:meth:`replan`): not in this lane."""
        return False

    def replan(self, p: Process) -> bool:
        """See :meth:`.ramps.PlanLane.replan` (this lane never keeps a member planned
        anew: :meth:`replans` is False)."""
        raise NotImplementedError

    def sync(self, p: Process) -> None:
        """Write the lane's state into ``p`` and keep it."""
        k = self._slot.get(id(p))
        if k is not None and p.lane is self:
            self._store(p, k)

    def move_out(self, rows: Sequence[int] | np.ndarray) -> list[Axis]:
        """Evict the members at ``rows`` before the lane steps them: they change state in
        this step, so their axes are composed in Python. Returns those axes."""
        out = []
        for k in rows:
            p = self.members[int(k)]
            self.evict(p)
            out.append(self.axes[int(k)])
        return out

    def rebuild(self) -> None:
        """Drop evicted members (keeping the others' array values) and add the new ones."""
        if not self.changed:
            return
        slot = self._slot
        n = len(self.members)
        if len(slot) == n:
            # every member still has its slot (an eviction pops it): all kept
            keep = list(range(n))
            members = list(self.members)
            axes = list(self.axes)
        else:
            # (a lane emptied at once, evict_all, has no slots left: nothing to look up)
            keep = [k for k, p in enumerate(self.members) if slot.get(id(p)) == k] if slot else []
            members = [self.members[k] for k in keep]
            axes = [self.axes[k] for k in keep]
        admitted = len(self._joining)
        joining = self._joining
        if joining:
            # (C-level passes: a batch of many joins, usually all still joining)
            lanes = list(map(_LANE, map(_FIRST, joining)))
            if lanes.count(self) != admitted:
                joining = [(p, ax) for p, ax in joining if p.lane is self]
        self._joining = []
        # a batch admitted alone and left whole: its columns are ready (no row by row)
        columns = self._batch_columns(joining) if len(joining) == admitted else None
        self._batch = None
        rows = [] if columns is not None else [self._load(p, ax) for p, ax in joining]
        # (the rows as columns at once: one transposition instead of a pass per field)
        loaded = list(zip(*rows, strict=True)) if rows else []
        whole = len(keep) == len(self.members)
        self._kept = keep
        sel = None if whole else np.array(keep, dtype=np.intp)
        for j, f in enumerate(self.FIELDS):
            if columns is not None and not keep:
                # nothing kept: the batch's columns alone (a copy: two fields may share
                # one column, and the lanes write their fields in place)
                self.arrays[f] = np.array(columns[j], dtype=self.DTYPES.get(f, float))
                continue
            # (every member kept: the arrays as they are, no selection to copy them)
            old = self.arrays[f] if sel is None else self.arrays[f][sel]
            if columns is not None:
                self.arrays[f] = np.concatenate((old, columns[j]))
            elif rows:
                new = np.array(loaded[j], dtype=self.DTYPES.get(f, float))
                new = new.reshape((len(rows), *old.shape[1:]))
                # (nothing kept: the new rows alone, no concatenation with nothing)
                self.arrays[f] = np.concatenate((old, new)) if keep else new
            else:
                self.arrays[f] = old if sel is not None else old.copy()
        if whole and joining:
            # members appended to those kept, in order: their slots and indices added to
            # the others' (what _set_members would compute again for every member)
            start = len(members)
            added, new_axes = zip(*joining, strict=True)
            members += added
            axes += new_axes
            self._slot.update(zip(map(id, added), range(start, len(members)), strict=True))
            self._appended = list(map(_INDEX, new_axes))
            self._set_members(members, axes)
        else:
            members += map(_FIRST, joining)
            axes += map(_SECOND, joining)
            self._set_members(members, axes)
        self.changed = False

    def _set_members(self, members: list[Process], axes: list[Axis]) -> None:
        """Take ``members`` on ``axes`` (in row order). After :meth:`rebuild` appended
        members to all those kept (``_appended``: their axis indices), their slots are
        already in ``_slot`` and the kept members' indices are those of ``idx``: only
        the new ones are read."""
        self.members = members
        self.axes = axes
        added = self._appended
        if added is not None:
            self._appended = None
            indices = [*self.idx.tolist(), *added]
        else:
            self._slot = {id(p): k for k, p in enumerate(members)}
            indices = [ax.index for ax in axes]
        at = compact_list(indices)
        self.at = at
        self.idx = np.arange(at.start, at.stop, dtype=np.intp) if isinstance(at, slice) else at

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        raise NotImplementedError

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        """The ``FIELDS`` of ``joining`` (every member admitted since the last rebuild,
        none evicted) as arrays, if they joined as one batch whose state the lane kept;
        None: load them one by one (:meth:`_load`)."""
        return None

    def _store(self, p: Process, k: int) -> None:
        raise NotImplementedError

    def _store_columns(self, members: list[Any], columns: dict[str, list[Any]]) -> None:
        """:meth:`_store` of every member (``members[k]`` at row ``k``) from the
        columns as lists: the same values, without a call per member (a lane that does
        not define it is stored member by member)."""
        raise NotImplementedError


class LevelledLane(Lane):
    """A lane of followers: each member reads a master (``midx``) through ``source``.

    Members on a command reference read their master's command of this cycle, so they
    step by level (:mod:`.group` orders them): ``levels[L]`` is the slice of level L in
    the lane's arrays, ``slaves[L]`` and ``masters[L]`` index its members' and their
    masters' axes.
    """

    #: the level of each member, in member order, as last ordered (a class default for
    #: lanes restored from older state: not known, so levelled again)
    member_levels: list[int] = []  # noqa: RUF012 (replaced per order, never mutated)

    def __init__(self, owner: LaneOwner, source: MasterReference) -> None:
        super().__init__(owner)
        self.source = source
        self.midx = np.zeros(0, dtype=np.intp)
        self.levels: list[slice] = []
        self.slaves: list[Index] = []
        self.masters: list[Index] = []
        self.whole: list[bool] = []
        self.member_levels: list[int] = []

    #: after :meth:`rebuild`: the masters' indices of the members, in member order
    #: (those kept from ``midx``, those appended read from their processes), for
    #: :meth:`order`; None when ``midx`` did not hold the members before it
    new_midx: list[int] | None = None
    #: the masters' indices of the batch the last :meth:`rebuild` appended, when its
    #: admission gave them (``BatchedLane.take_batch``); read once, by that rebuild
    batch_masters: list[int] | None = None
    #: ``midx`` no longer holds the members' masters: a :meth:`rebuild` that could not
    #: carry them over ran since the last :meth:`order` (a class default for lanes
    #: restored from older state)
    midx_stale = False

    @staticmethod
    def master_index(p: Process) -> int:
        raise NotImplementedError

    def rebuild(self) -> None:
        """:meth:`Lane.rebuild`, carrying the masters' indices of the members kept over
        to ``new_midx``. The indices the members had are those of the last rebuild when
        it has not been ordered yet (a lane rebuilt twice before its order: a follower
        evicted while the followers are levelled, after the members admitted were
        rebuilt), else ``midx``, as the last :meth:`order` left it; ``midx`` describes
        the members of that order only, which a rebuild since may have changed."""
        if not self.changed:
            return
        pending = self.new_midx
        old: list[int] | None
        if pending is not None:
            old = pending
        elif self.midx_stale:
            old = None
        else:
            old = self.midx.tolist()
        known = old is not None and len(old) == len(self.members)
        self.batch_masters = None
        super().rebuild()
        batch_masters, self.batch_masters = self.batch_masters, None
        if known:
            assert old is not None
            kept = self._kept
            midx = [old[k] for k in kept] if len(kept) != len(old) else list(old)
            appended = len(self.members) - len(kept)
            if batch_masters is not None and len(batch_masters) == appended:
                midx += batch_masters
            else:
                master_index = self.master_index
                midx += [master_index(p) for p in self.members[len(kept) :]]
            self.new_midx = midx
        else:
            self.new_midx = None
            self.midx_stale = True

    def order(self, levels: list[int]) -> None:
        """Sort the members by ``levels`` (one per member, in member order)."""
        midx = self.new_midx
        self.new_midx = None
        self.midx_stale = False  # (set again below, from the members as they are now)
        if midx is None or len(midx) != len(self.members):
            master_index = self.master_index
            midx = [master_index(p) for p in self.members]
        if not self.members:
            if self.levels:
                # emptied (a group stop): what the sort below leaves, without sorting
                # every field's empty array again
                self.levels = []
                self.slaves = []
                self.masters = []
                self.whole = []
            if len(self.midx):
                self.midx = np.zeros(0, dtype=np.intp)
            self.member_levels = []
            return
        if levels == sorted(levels):
            # in level order already (a lane of one level): what the sort would leave
            ordered = list(levels)
        else:
            perm = sorted(range(len(self.members)), key=levels.__getitem__)
            sel = np.array(perm, dtype=np.intp)
            for f in self.FIELDS:
                self.arrays[f] = self.arrays[f][sel]
            self._set_members([self.members[k] for k in perm], [self.axes[k] for k in perm])
            ordered = [levels[k] for k in perm]
            midx = [midx[k] for k in perm]
        self.member_levels = ordered
        depth = ordered[-1] + 1 if ordered else 0
        self.levels = []
        start = 0
        for level in range(depth):
            stop = bisect_right(ordered, level, start)
            self.levels.append(slice(start, stop))
            start = stop
        self.midx = np.array(midx, dtype=np.intp)
        at = self.at
        self.slaves = [
            at if sl.start == 0 and sl.stop == len(ordered) else compact(self.idx[sl])
            for sl in self.levels
        ]
        #: the level is the whole lane (its results can replace the arrays, not fill them)
        self.whole = [sl.start == 0 and sl.stop == len(self.members) for sl in self.levels]
        self.masters = [compact_list(midx[sl]) for sl in self.levels]

    def step(self, s: AxisArrays, level: int, dt: float, compose: Compose) -> None:
        """Step the members at ``level`` (moving out those that change state)."""
        raise NotImplementedError
