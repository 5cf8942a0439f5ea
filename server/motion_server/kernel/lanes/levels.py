"""The levels of a group's command followers: who steps after whom.

A follower on a command position reads its master's command of this cycle, so it steps
after its master: level 0 when the master is in a time-driven lane, in an
actual-position lane, in another group or has no motion; level k + 1 when the master is
a command follower at level k. A follower whose master is composed in Python leaves its
lane (it is composed in Python after its master). :class:`FollowerLevels` works the
levels out for :class:`.group.GroupLanes` (which holds the lanes it reads): all of them
again, or, after followers were admitted with nothing else changed, only theirs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..axis import Axis
from ..enums import MasterReference
from ..group import MotionGroup
from ..processes import Process
from .base import LevelledLane
from .ramps import CruiseLane, ProfileLane, StopLane
from .scurve import SCurveLane


class FollowerLevels:
    """The levelling of :class:`.group.GroupLanes`, whose attributes it reads."""

    group: MotionGroup
    followers: dict[MasterReference, tuple[LevelledLane, ...]]
    cruise: CruiseLane
    profiles: ProfileLane
    stops: StopLane
    scurves: SCurveLane
    dirty: bool
    #: number of levels of command followers
    depth: int
    #: per command follower lane: its member list and their levels when it was last
    #: ordered (the same list object and levels again: nothing to sort); a class default
    #: for lanes restored from a snapshot saved before it existed
    _ordered: dict[LevelledLane, tuple[list[Process], list[int]]] | None = None
    #: the followers admitted that :meth:`_order_command_followers` levels alone (set
    #: by ``GroupLanes._hand_over`` just before it calls it)
    _admitted: (
        tuple[
            dict[LevelledLane, list[int]],
            list[tuple[LevelledLane, list[int]]],
            list[np.ndarray],
        ]
        | None
    ) = None

    def _order_levelled(self, levels_of: dict[LevelledLane, list[int]]) -> None:
        """Order each command follower lane of ``levels_of`` by those levels (one per
        member, in member order) and take the number of levels again."""
        ordered = self._ordered
        if ordered is None:
            ordered = self._ordered = {}
        for lane, levels in levels_of.items():
            lane.order(levels)
            ordered[lane] = (lane.members, lane.member_levels)
        self.depth = max(
            (len(lane.levels) for lane in self.followers[MasterReference.COMMAND]), default=0
        )

    def _level_admitted(
        self,
        levels_of: dict[LevelledLane, list[int]],
        admitted: list[tuple[LevelledLane, list[int]]],
        read: list[np.ndarray],
        axes: Sequence[Axis],
    ) -> bool:
        """The levels of the followers ``admitted`` (lane, rows after its rebuild; -1 in
        ``levels_of``) written into ``levels_of``, the others' left as they were
        (:meth:`_hand_over`); False when that is not enough: an admitted axis is the
        master of a follower that was in a lane before the rebuild (``read``, their
        masters' indices: those that left count too, which only errs on the safe side;
        that follower's master was at rest or composed in Python, and its level
        changes), or an admitted follower's master is composed in Python."""
        parts = [
            lane.idx[rows[0] :] if len(rows) == len(lane.members) - rows[0] else lane.idx[rows]
            for lane, rows in admitted
        ]
        new_idx = parts[0] if len(parts) == 1 else np.concatenate(parts)
        if read:
            # (marked in an array by axis index: np.isin sorts, ten times dearer)
            read_by = np.zeros(len(axes), dtype=bool)
            for masters in read:
                read_by[masters] = True
            if read_by[new_idx].any():
                return False
        # the usual masters inline (another group, a stop row, at rest, a time-driven or
        # actual-position lane: level 0); a command follower's through _level_of
        group = self.group.number
        for lane, rows in admitted:
            levels = levels_of[lane]
            members = lane.members
            midx = lane.new_midx
            if midx is None or len(midx) != len(members):
                master_index = lane.master_index
                midx = [master_index(p) for p in members]
            for row in rows:
                if levels[row] >= 0:
                    continue  # levelled already, as a master of another admitted
                master = axes[midx[row]]
                if master.group == group and master.stop_rows is None:
                    procs = master._processes
                    if procs:
                        up = procs[0].lane
                        if len(procs) != 1 or up is None:
                            return False  # composed in Python
                        if up in levels_of or (
                            isinstance(up, LevelledLane) and up.source == MasterReference.COMMAND
                        ):
                            if self._level_of(lane, row, levels_of, axes, 0) is None:
                                return False
                            continue
                    elif master.buffered is not None:
                        return False
                levels[row] = 0
        return True

    def _level_of(
        self,
        lane: LevelledLane,
        row: int,
        levels_of: dict[LevelledLane, list[int]],
        axes: Sequence[Axis],
        depth: int,
    ) -> int | None:
        """The level of the follower admitted at ``row`` of ``lane`` (after the lanes'
        rebuild), as :meth:`_order_command_followers` levels it, written into
        ``levels_of``: 0 when its master is in another group, in a time-driven or
        actual-position lane or a stop row, or without motion; one more than its
        master's when the master is a command follower (a follower kept, or one admitted
        now, worked out first). None when the master is composed in Python (the
        follower must leave its lane: the full rebuild does that)."""
        levels = levels_of[lane]
        if levels[row] >= 0:
            return levels[row]
        if depth > len(axes):
            return None  # a loop (gearing refuses them): guarded anyway
        midx = lane.new_midx
        p = lane.members[row]
        master = axes[midx[row] if midx is not None else lane.master_index(p)]
        level = 0
        if master.group == self.group.number and master.stop_rows is None:
            procs = master._processes
            if procs:
                q = procs[0]
                up = q.lane
                if len(procs) != 1 or up is None:
                    return None
                if up in levels_of:
                    assert isinstance(up, LevelledLane)
                    above = self._level_of(up, up._slot[id(q)], levels_of, axes, depth + 1)
                    if above is None:
                        return None
                    level = above + 1
                elif isinstance(up, LevelledLane) and up.source == MasterReference.COMMAND:
                    # a follower whose lane did not change: the level it was ordered at
                    level = up.member_levels[up._slot[id(q)]] + 1
            elif master.buffered is not None:
                return None
        levels[row] = level
        return level

    def _order_command_followers(self, axes: Sequence[Axis]) -> None:
        """Level the command followers (:mod:`.group`'s order) and order their lanes by
        level; a follower whose master is composed in Python leaves its lane. After
        followers were admitted to their lanes with nothing else changed
        (``_admitted``, left by :meth:`_hand_over`), only they are levelled
        (:meth:`_level_admitted`), or ``dirty`` is set when that is not enough."""
        pending = self._admitted
        if pending is not None:
            self._admitted = None
            levels_of = pending[0]
            if self._level_admitted(*pending, axes):
                self._order_levelled(levels_of)
            else:
                self.dirty = True
            return
        lanes = self.followers[MasterReference.COMMAND]
        group = self.group.number
        by_axis: dict[int, tuple[LevelledLane, Process]] = {}
        for lane in lanes:
            for p, ax in zip(lane.members, lane.axes, strict=True):
                by_axis[id(ax)] = (lane, p)
        first = (
            self.cruise,
            self.profiles,
            self.stops,
            self.scurves,
            *self.followers[MasterReference.ACTUAL],
        )
        stepped_first: set[int] = set()
        if by_axis:
            stepped_first = {id(ax) for lane in first for ax in lane.axes}
            stepped_first.update(id(ax) for ax in self.stops.row_axes)
        memo: dict[int, int | None] = {}

        def level(ax: Axis) -> int | None:
            """Level of ``ax``'s follower; None when it cannot stay in its lane."""
            key = id(ax)
            if key in memo:
                return memo[key]
            memo[key] = None  # no loops (gearing refuses them); guards anyway
            lane, p = by_axis[key]
            master = axes[lane.master_index(p)]
            mkey = id(master)
            result: int | None
            if master.group != group or mkey in stepped_first:
                result = 0
            elif mkey in by_axis:
                up = level(master)
                result = None if up is None else up + 1
            elif not master.processes and master.buffered is None:
                result = 0  # no motion: its command does not change while composing
            else:
                result = None  # composed in Python: the slave must follow it there
            memo[key] = result
            return result

        ordered = self._ordered
        if ordered is None:
            ordered = self._ordered = {}
        depth = 0
        for lane in lanes:
            levels = [level(ax) for ax in lane.axes]
            if None in levels:
                for p, lv in zip(list(lane.members), levels, strict=True):
                    if lv is None:
                        lane.evict(p)
                lane.rebuild()
            kept = [lv for lv in levels if lv is not None]
            last = ordered.get(lane)
            if last is None or last[0] is not lane.members or last[1] != kept:
                # (a rebuild or an order replaces the member list: the same list is the
                # same members in the same order, already sorted by these levels)
                lane.order(kept)
                ordered[lane] = (lane.members, kept)
            depth = max(depth, len(lane.levels))
        self.depth = depth
