"""The ramps of one group stop as rows of arrays, their objects made only when read.

A group stop planned in one batch (:func:`..stop_plan.stop_axes`) gives every axis a
trapezoidal :class:`~..processes.StopRamp` to rest. Building 256 ramp objects (and their
profiles and limits) costs about a microsecond and a half each, in the very cycle that
must stop the machine on time; nothing reads them in the usual case: the stop lane steps
them and ends them at rest. So :class:`StopRows` keeps the ramps of one batch as arrays
(the axis's base, the ramp's position, velocity, acceleration and deceleration) and makes
a ramp's object when something reads its axis's processes (``Axis.processes``: an
instruction's status, a snapshot, a command on the axis, a test). The object made is the
one the constructor would have made at the stop, in the state a stop lane member has:
``lane`` the group's :class:`~.ramps.StopLane`, its kinematics those of the stop until
the lane writes them back (``evict``, ``sync``), which the lane routes here. Made or not,
the row keeps being stepped by the lane until the ramp leaves it.

Rows leave by being marked (``live``), not removed: the arrays are compacted once, at the
lane's next rebuild, however many left. A row that reaches rest ends in the lane (the
axis's base takes the ramp's displacement, its processes become empty), as
:meth:`StopLane._come_to_rest <.ramps.StopLane._come_to_rest>` ends a member; a ramp
whose object was made is ended in its object as well.

The arithmetic of a step is :meth:`StopLane.step <.ramps.StopLane.step>`'s, itself
``StopRamp.step``'s: the results are bit-identical to the objects stepped one by one
(``tests/unit/test_stop_plan.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..axis import Axis
from ..enums import ProcessState
from ..limits import Limits
from ..processes import Process, StopRamp
from ..state import AxisArrays, Index, compact
from .base import LaneOwner

_DONE = ProcessState.DONE

#: makes a ramp as the constructor would: (dt, deceleration, velocity, owner, limits)
MakeRamp = Callable[[float, float, float, object, Limits | None], StopRamp]


class StopRows:
    """The ramps of one group stop on ``axes`` (in Servo Control, drive on, each with a
    velocity to ramp down): ``base`` the axes' bases once the stop folded in what it
    replaced, ``velocity`` and ``deceleration`` the ramps' (neither written here: the
    rows' own arrays are copies)."""

    def __init__(
        self,
        lane: Any,
        owner_lanes: LaneOwner,
        axes: list[Axis],
        idx: np.ndarray,
        base: np.ndarray,
        velocity: np.ndarray,
        deceleration: np.ndarray,
        dt: float,
        owner: object,
        make: MakeRamp,
        at: Index | None = None,
    ) -> None:
        self.lane = lane
        self._lanes = owner_lanes
        self.axes = axes
        self.idx = idx  # the axes' array indices
        #: the same as :func:`..state.compact` gives them (``at``, if the caller has it)
        self.at: Index = compact(self.idx) if at is None else at
        n = len(axes)
        self.base = base
        self.pos = np.zeros(n)
        self.vel = velocity.copy()
        self.acc = np.zeros(n)
        self.decel = deceleration
        #: the velocity the ramp started from (its object is made from it)
        self.v0 = velocity
        #: rows whose ramp is still in the lane
        self.live = np.ones(n, dtype=bool)
        self.left = 0  # rows marked out since the last compaction
        self.dt = dt
        self.owner = owner
        self._make = make
        #: axis index -> row, made when a ramp is first made (:attr:`row_of`)
        self._row_of: dict[int, int] | None = None
        #: row -> the ramp's object, once made
        self.made: dict[int, StopRamp] = {}
        self._row_by_id: dict[int, int] = {}  # id(made ramp) -> row
        self._limits: dict[tuple[float, float], Limits] = {}

    # -- snapshots: ``_row_by_id`` is keyed by object identity, which a copy does not keep --
    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        del state["_row_by_id"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        # (state saved before ``row_of`` was made lazily held the dict itself)
        state["_row_of"] = state.pop("row_of", state.get("_row_of"))
        self.__dict__.update(state)
        self._row_by_id = {id(r): k for k, r in self.made.items()}

    @property
    def row_of(self) -> dict[int, int]:
        """Axis index -> row (made the first time a ramp is made: a stop that nothing
        reads before it ends never needs it)."""
        row_of = self._row_of
        if row_of is None:
            row_of = self._row_of = dict(zip(self.idx.tolist(), range(len(self.idx)), strict=True))
        return row_of

    def __len__(self) -> int:
        return int(self.live.sum()) if self.left else len(self.axes)

    def materialise(self, ax: Axis) -> None:
        """Make ``ax``'s ramp as the constructor would have made it at the stop and give
        the axis its processes ([ramp]); the row stays in the lane."""
        k = self.row_of[ax.index]
        v = float(self.v0[k])
        d = float(self.decel[k])
        key = (v, d)
        limits = self._limits.get(key)
        r = self._make(self.dt, d, v, self.owner, limits)
        if limits is None:
            self._limits[key] = r.limits
        r.lane = self.lane
        r.offer_pending = False
        self.made[k] = r
        self._row_by_id[id(r)] = k
        ax.stop_rows = None
        ax._processes = [r]

    def row(self, p: Process) -> int | None:
        """The row of the made ramp ``p``, if it is still one of these rows."""
        k = self._row_by_id.get(id(p))
        return k if k is not None and self.made.get(k) is p else None

    def store(self, p: Process, k: int) -> None:
        """Write row ``k``'s kinematics into its ramp ``p``."""
        p.position = float(self.pos[k])
        p.velocity = float(self.vel[k])
        p.acceleration = float(self.acc[k])

    def evict(self, p: Process, k: int) -> None:
        """``p`` (row ``k``) leaves the lane: its kinematics written back, the row
        marked out (compacted at the next rebuild)."""
        self.store(p, k)
        p.lane = None
        p.offer_pending = True
        del self.made[k]
        del self._row_by_id[id(p)]
        self.live[k] = False
        self.left += 1
        self._lanes.dirty = True

    def compact(self) -> bool:
        """Drop the rows marked out; False when none is left."""
        if not self.left:
            return True
        keep = np.flatnonzero(self.live)
        if keep.size == 0:
            self.axes = []
            self.made = {}
            self._row_by_id = {}
            return False
        first, last = int(keep[0]), int(keep[-1])
        if last - first + 1 == keep.size:
            # the rows left are one block (the axes that still ramp were stopped from
            # the higher speeds, usually consecutive): slices, views instead of copies
            block = slice(first, last + 1)
            self.axes = self.axes[block]
            self.idx = self.idx[block]
            at = self.at
            if isinstance(at, slice):
                self.at = slice(at.start + first, at.start + last + 1)
            else:
                self.at = compact(self.idx)
            for name in ("base", "pos", "vel", "acc", "decel", "v0"):
                setattr(self, name, getattr(self, name)[block])
            self.made = {k - first: r for k, r in self.made.items()}
        else:
            new_row = np.cumsum(self.live) - 1
            self.axes = [self.axes[k] for k in keep.tolist()]
            self.idx = self.idx[keep]
            self.at = compact(self.idx)
            for name in ("base", "pos", "vel", "acc", "decel", "v0"):
                setattr(self, name, getattr(self, name)[keep])
            self.made = {int(new_row[k]): r for k, r in self.made.items()}
        self.live = np.ones(keep.size, dtype=bool)
        self.left = 0
        self._row_by_id = {id(r): k for k, r in self.made.items()}
        self._row_of = None
        return True

    def step(self, s: AxisArrays, dt: float, compose: Callable[[Axis], None]) -> None:
        """``StopLane.step`` over the rows: the rows that reach rest end here (or, a made
        ramp no longer alone on its axis, are moved out and composed in Python)."""
        v0 = self.vel
        dv = self.decel * dt
        ending = np.abs(v0) <= dv * (1.0 + 1e-9)
        v1 = v0 - np.copysign(dv, v0)
        resting: list[int] = []
        movers: list[Axis] = []
        if ending.any():
            rows = np.flatnonzero(ending & self.live)
            resting, odd = self._resting(rows.tolist())
            for k in odd:
                p = self.made[k]
                self.evict(p, k)
                movers.append(self.axes[k])
            v1[np.flatnonzero(ending)] = 0.0  # the ramp's last step: to rest exactly
        pos = self.pos
        pos += 0.5 * (v0 + v1) * dt
        acc = (v1 - v0) / dt
        self.vel, self.acc = v1, acc
        at = self.at
        s.cmd_pos[at] = self.base + pos
        s.cmd_vel[at] = v1
        s.cmd_acc[at] = acc
        if resting:
            self._come_to_rest(s, resting)
        for ax in movers:
            compose(ax)

    def _resting(self, rows: Sequence[int]) -> tuple[list[int], list[int]]:
        """Rows reaching rest that end here (their ramp is the axis's only process,
        nothing buffered: always so for a ramp not made yet), and the others."""
        if not self.made:
            return list(rows), []
        resting, odd = [], []
        for k in rows:
            p = self.made.get(k)
            if p is None:
                resting.append(k)
                continue
            ax = self.axes[k]
            procs = ax._processes
            if ax.stop_rows is None and len(procs) == 1 and procs[0] is p and ax.buffered is None:
                resting.append(k)
            else:
                odd.append(k)
        return resting, odd

    def _come_to_rest(self, s: AxisArrays, rows: list[int]) -> None:
        """End the ramps of ``rows``: what ``StopLane._come_to_rest`` does for a member
        (the axis's base takes the displacement, no process left, the command the base at
        rest, not busy), and for a made ramp its end state (done, at rest)."""
        rows_arr = np.array(rows, dtype=np.intp)
        positions = self.pos[rows_arr].tolist()
        axes = self.axes
        bases = []
        for k, x in zip(rows, positions, strict=True):
            ax = axes[k]
            b = ax.base + x
            ax.base = b
            ax.stop_rows = None
            ax._processes = []
            bases.append(b)
        if self.made:
            accelerations = self.acc[rows_arr].tolist()
            for k, x, a in zip(rows, positions, accelerations, strict=True):
                p = self.made.pop(k, None)
                if p is not None:
                    del self._row_by_id[id(p)]
                    p.lane = None
                    p.offer_pending = True
                    p.position = x
                    p.velocity = 0.0
                    p.acceleration = a
                    p.state = _DONE
        at = self.idx[rows_arr]
        s.cmd_pos[at] = np.array(bases) + 0.0
        s.cmd_vel[at] = 0.0
        s.cmd_acc[at] = 0.0
        s.busy[at] = False
        s.dirty.update(at.tolist())
        self.live[rows_arr] = False
        self.left += len(rows)
        self._lanes.dirty = True
