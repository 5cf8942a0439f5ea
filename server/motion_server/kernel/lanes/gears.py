"""Follower lanes: gears on one master, locked (real or fraction ratio) or catching up at a
rate (the MAG clutch, the trapezoidal PLCopen catch-up).

Each member reads its master through the lane's ``source`` (command or actual position,
``AxisArrays.master_arrays``); command followers step by level, after their masters.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..enums import MasterReference
from ..gearing import GearProcess, RateRamp
from ..processes import Process
from ..state import AxisArrays
from .base import Compose, LevelledLane

#: fraction gears step in int64 counts while |master counts| stays below this; beyond, a
#: member is moved out to Python integers (which never overflow)
COUNTS_LIMIT = 2.0**62


def gear_source(p: GearProcess) -> MasterReference:
    c = p.single
    assert c is not None
    return MasterReference.COMMAND if c.acc is not None else MasterReference.ACTUAL


class BatchedLane(LevelledLane):
    """A follower lane that can take a batch of members as columns: gears the catch-up
    lane locked (:meth:`CatchUpLane._lock`), gears started together
    (:mod:`..gear_batch`)."""

    def take_batch(
        self,
        joining: Sequence[tuple[Process, Axis]],
        columns: list[Any],
        masters: list[int] | None = None,
    ) -> None:
        """``joining`` were admitted last, in this order; ``columns`` holds their
        ``FIELDS``, what :meth:`_load` would read, and ``masters`` (if given) their
        masters' indices, what :meth:`master_index` would read: if they are all that
        joined since the last rebuild, the next rebuild takes them instead of reading
        every member."""
        mine = self._joining
        if (
            joining
            and len(mine) == len(joining)
            and all(q is p for (q, _), (p, _) in zip(mine, joining, strict=True))
        ):
            self._batch = (joining[0][0], len(joining), columns, masters)

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        batch = self._batch
        if batch is None or not joining or joining[0][0] is not batch[0]:
            return None
        if len(joining) != batch[1]:
            return None
        # (the rebuild appends exactly this batch: its masters' indices go with it; a
        # batch restored from older state has none)
        self.batch_masters = batch[3] if len(batch) > 3 else None
        return [np.asarray(col, dtype=float) for col in batch[2]]

    def admit_started(
        self,
        joining: Sequence[tuple[Process, Axis]],
        columns: list[Any] | None,
        at_zero: bool,
        masters: list[int] | None = None,
    ) -> None:
        """:meth:`~.base.Lane.admit` of each of ``joining`` (gears just started on axes
        without motion, in this order, each already marked ``p.lane is self``), with
        their ``FIELDS`` as ``columns`` (None: loaded one by one at the rebuild) and
        their masters' indices as ``masters`` (None: read at the rebuild).

        ``at_zero``: every one of them steps at level 0 and no follower's level changes
        by their joining (the caller checked: each reads a master stepped before every
        follower, and no follower in the lanes reads their slaves). The rebuild then
        orders the follower lanes by the levels their members had, these at 0
        (``GroupLanes._hand_over``, as for gears handed over locked), instead of
        levelling every follower again; otherwise the followers are levelled again,
        as ``admit`` does."""
        if not joining:
            return
        self._batch = None
        self._joining.extend(joining)
        self.changed = True
        if columns is not None:
            self.take_batch(joining, columns, masters)
        owner = self._owner
        if not at_zero:
            owner.dirty = True
            return
        if self.source == MasterReference.COMMAND:
            # the levels by identity, read by the hand-over (a dict of the owner's own:
            # not the class default of lanes restored from older state)
            handed = vars(owner).get("_handed")
            if handed is None:
                handed = {}
                owner._handed = handed  # type: ignore[attr-defined]
            handed.update(dict.fromkeys([id(p) for p, _ in joining], 0))
        owner.handed = True


class GearLane(BatchedLane):
    """Locked real-ratio gears on one master (``GearProcess.step``, locked, one term)."""

    FIELDS = ("base", "at_lock", "lock_pos", "num", "den", "ratio", "v_prev", "pos", "vel", "acc")
    STORED = ("pos", "vel", "acc", "v_prev")

    @staticmethod
    def accepts(p: Process) -> bool:
        if type(p) is not GearProcess or not p.locked:
            return False
        c = p.single
        return c is not None and not c.exact

    @staticmethod
    def master_index(p: Process) -> int:
        assert isinstance(p, GearProcess) and p.single is not None
        return p.single.index

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, GearProcess) and p.single is not None
        c = p.single
        return (
            ax.base,
            p.at_lock,
            c.lock_pos,
            c.num,
            c.den,
            c.ratio,
            c.v_prev,
            p.position,
            p.velocity,
            p.acceleration,
        )

    def _store(self, p: Process, k: int) -> None:
        assert isinstance(p, GearProcess) and p.single is not None
        a = self.arrays
        p.position = float(a["pos"][k])
        p.velocity = float(a["vel"][k])
        p.acceleration = float(a["acc"][k])
        p.single.v_prev = float(a["v_prev"][k])

    def _store_columns(self, members: list[Any], columns: dict[str, list[Any]]) -> None:
        for p, x, v, a, vp in zip(members, columns["pos"], columns["vel"], columns["acc"],
                                  columns["v_prev"], strict=True):  # fmt: skip
            p.position = x
            p.velocity = v
            p.acceleration = a
            p.single.v_prev = vp

    def step(self, s: AxisArrays, lv: int, dt: float, compose: Compose) -> None:
        a = self.arrays
        level = self.levels[lv]
        mi = self.masters[lv]
        m_arr, v_arr, a_arr = s.master_arrays(self.source)
        m, v = m_arr[mi], v_arr[mi]
        ratio = a["ratio"][level]
        # the operations and their order of GearProcess.step's locked one-master path
        pos = a["at_lock"][level] + (m - a["lock_pos"][level]) * a["num"][level] / a["den"][level]
        vel = ratio * v
        acc = ratio * a_arr[mi] if a_arr is not None else ratio * (v - a["v_prev"][level]) / dt
        a["v_prev"][level] = v
        if self.whole[lv]:
            a["pos"], a["vel"], a["acc"] = pos, vel, acc
        else:
            a["pos"][level], a["vel"][level], a["acc"][level] = pos, vel, acc
        si = self.slaves[lv]
        s.cmd_pos[si] = a["base"][level] + pos
        s.cmd_vel[si] = vel
        s.cmd_acc[si] = acc


class FractionLane(LevelledLane):
    """Locked fraction-ratio gears on one master, exact in integer counts
    (``GearProcess.step`` through ``_Coupling.displacement``): int64 while the product of
    the master's counts since the lock and SlaveCounts fits, Python integers beyond."""

    FIELDS = (
        "base",
        "at_lock",
        "cpu_m",
        "cpu_s",
        "ratio",
        "v_prev",
        "lock_counts",
        "num",
        "den",
        "span",
        "counts",
        "pos",
        "vel",
        "acc",
    )
    DTYPES: ClassVar[dict[str, Any]] = {
        f: np.int64 for f in ("lock_counts", "num", "den", "span", "counts")
    }

    @staticmethod
    def accepts(p: Process) -> bool:
        if type(p) is not GearProcess or not p.locked:
            return False
        c = p.single
        if c is None or not c.exact:
            return False
        return abs(c.lock_counts) < COUNTS_LIMIT and 0 < abs(c.num) < 2**62 and 0 < c.den < 2**62

    @staticmethod
    def master_index(p: Process) -> int:
        assert isinstance(p, GearProcess) and p.single is not None
        return p.single.index

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, GearProcess) and p.single is not None
        c = p.single
        return (
            ax.base,
            p.at_lock,
            c.cpu_m,
            c.cpu_s,
            c.ratio,
            c.v_prev,
            c.lock_counts,
            c.num,
            c.den,
            2**62 // abs(c.num),  # |counts since lock| up to this: x SlaveCounts fits int64
            c.slave_counts,
            p.position,
            p.velocity,
            p.acceleration,
        )

    def _store(self, p: Process, k: int) -> None:
        assert isinstance(p, GearProcess) and p.single is not None
        a = self.arrays
        p.position = float(a["pos"][k])
        p.velocity = float(a["vel"][k])
        p.acceleration = float(a["acc"][k])
        p.single.v_prev = float(a["v_prev"][k])
        p.single.slave_counts = int(a["counts"][k])

    def step(self, s: AxisArrays, lv: int, dt: float, compose: Compose) -> None:
        a = self.arrays
        level = self.levels[lv]
        mi = self.masters[lv]
        m_arr, v_arr, a_arr = s.master_arrays(self.source)
        m, v = m_arr[mi], v_arr[mi]
        # _Coupling.displacement: (round(m x cpu_m) - lock counts) x num // den, in counts
        mc = m * a["cpu_m"][level]
        fits = np.abs(mc) < COUNTS_LIMIT  # False for inf and NaN too
        counts = np.rint(np.where(fits, mc, 0.0)).astype(np.int64)
        delta = counts - a["lock_counts"][level]
        fits &= np.abs(delta) <= a["span"][level]
        movers = []
        if not fits.all():
            rows = np.flatnonzero(~fits) + (level.start or 0)
            movers = self.move_out(rows)
        n = delta * a["num"][level] // a["den"][level]
        pos = a["at_lock"][level] + n / a["cpu_s"][level]
        ratio = a["ratio"][level]
        vel = ratio * v
        # _Coupling.acceleration: ratio x (a master acceleration, or its velocity difference)
        if a_arr is not None:
            acc = ratio * a_arr[mi]
        else:
            acc = ratio * ((v - a["v_prev"][level]) / dt)
        a["v_prev"][level] = v
        a["counts"][level] = n
        a["pos"][level] = pos
        a["vel"][level] = vel
        a["acc"][level] = acc
        si = self.slaves[lv]
        s.cmd_pos[si] = a["base"][level] + pos
        s.cmd_vel[si] = vel
        s.cmd_acc[si] = acc
        for ax in movers:
            compose(ax)


class CatchUpLane(BatchedLane):
    """Gears on one master catching up at a rate (``GearProcess.step`` before the lock
    with a ``RateRamp``); the step that catches up (and locks) is the gear's own (moved
    out)."""

    FIELDS = ("base", "ratio", "v_prev", "accel", "decel", "pos", "vel", "acc")

    @staticmethod
    def accepts(p: Process) -> bool:
        return (
            type(p) is GearProcess
            and not p.locked
            and p.single is not None
            and type(p.ramp) is RateRamp
        )

    @staticmethod
    def master_index(p: Process) -> int:
        assert isinstance(p, GearProcess) and p.single is not None
        return p.single.index

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, GearProcess) and p.single is not None
        ramp = p.ramp
        assert isinstance(ramp, RateRamp)
        c = p.single
        return (
            ax.base,
            c.ratio,
            c.v_prev,
            ramp.accel,
            ramp.decel,
            ramp.position,
            ramp.velocity,
            ramp.acceleration,
        )

    def _store(self, p: Process, k: int) -> None:
        assert isinstance(p, GearProcess) and p.single is not None
        ramp = p.ramp
        assert ramp is not None
        a = self.arrays
        ramp.position = p.position = float(a["pos"][k])
        ramp.velocity = p.velocity = float(a["vel"][k])
        ramp.acceleration = p.acceleration = float(a["acc"][k])
        p.single.v_prev = float(a["v_prev"][k])

    def step(self, s: AxisArrays, lv: int, dt: float, compose: Compose) -> None:
        a = self.arrays
        level = self.levels[lv]
        mi = self.masters[lv]
        _, v_arr, _ = s.master_arrays(self.source)
        v = v_arr[mi]
        # GearProcess.step: target = sum of the couplings' velocities (0 + one term)
        target = 0.0 + a["ratio"][level] * v
        # RateRamp.step
        v0 = a["vel"][level]
        speeding_up = (np.abs(target) > np.abs(v0)) & (target * v0 >= 0.0)
        dv = np.where(speeding_up, a["accel"][level], a["decel"][level]) * dt
        gap = target - v0
        caught = np.abs(gap) <= dv
        movers: list[Axis] = []
        locking: list[int] = []
        v1 = v0 + np.copysign(dv, gap)
        if caught.any():
            locking, odd = self._locking(s, np.flatnonzero(caught) + (level.start or 0))
            movers = self.move_out(odd) if odd else []
            # RateRamp.step: the step that catches up lands on the target velocity
            v1 = np.where(caught, target, v1)
        pos = a["pos"][level] + 0.5 * (v0 + v1) * dt
        acc = (v1 - v0) / dt
        a["v_prev"][level] = v
        a["pos"][level] = pos
        a["vel"][level] = v1
        a["acc"][level] = acc
        si = self.slaves[lv]
        s.cmd_pos[si] = a["base"][level] + pos
        s.cmd_vel[si] = v1
        s.cmd_acc[si] = acc
        if locking:
            self.reached_level = lv
            self._lock(s, locking)
        for ax in movers:
            compose(ax)

    #: the gears :meth:`_lock` locked in the last step, to offer to the locked lanes
    #: (``GroupLanes``; a class default for lanes restored from older snapshots)
    reached: Sequence[tuple[Process, Axis]] = ()
    #: the level :attr:`reached` stepped at
    reached_level = 0

    def _locking(self, s: AxisArrays, rows: np.ndarray) -> tuple[list[int], list[int]]:
        """The rows that catch up this step, split into those the lane locks itself
        (:meth:`_lock`: a real ratio, the gear its axis's only process, nothing buffered,
        the drive on: the usual MAG clutch) and those moved out to the gear's own step."""
        locking, odd = [], []
        drive_on = s.drive_on
        for k in rows.tolist():
            p, ax = self.members[k], self.axes[k]
            # (the property's call saved: no stop row here unless its ramp is to be made)
            procs = ax._processes if ax.stop_rows is None else ax.processes
            c = p.single
            if (
                not c.exact
                and len(procs) == 1
                and procs[0] is p
                and ax.buffered is None
                and drive_on[ax.index]
            ):
                locking.append(k)
            else:
                odd.append(k)
        return locking, odd

    def _lock(self, s: AxisArrays, rows: list[int]) -> None:
        """Lock the gears at ``rows``, which caught up in this step (the lane has written
        their sample): what their own step and composition do (``RateRamp.step``,
        ``GearProcess._lock``, ``Motion.compose`` of a single process marking the changed
        status, ``Motion.offer``), without stepping them again. Each leaves this lane;
        :attr:`reached` hands them to the lanes of locked gears."""
        a = self.arrays
        r = np.array(rows, dtype=np.intp)
        pos, vel, acc = a["pos"][r].tolist(), a["vel"][r].tolist(), a["acc"][r].tolist()
        v_prev = a["v_prev"][r].tolist()
        slot = self._slot
        dirty = s.dirty
        reached: list[tuple[Process, Axis]] = []
        # the locked lane's FIELDS of each, as GearLane._load would read them
        base, lock_pos, num, den, masters = [], [], [], [], []
        members, axes = self.members, self.axes
        for j, k in enumerate(rows):
            p, ax = members[k], axes[k]
            # (a GearProcess on one real-ratio coupling with a RateRamp: accepts, _locking)
            ramp = p._ramp  # type: ignore[attr-defined]
            slot.pop(id(p), None)
            x = pos[j]
            ramp.position = p.position = x
            ramp.velocity = p.velocity = vel[j]
            ramp.acceleration = p.acceleration = acc[j]
            c = p.single  # type: ignore[attr-defined]
            c.v_prev = v_prev[j]
            # GearProcess._lock, with _Coupling.lock of a real ratio
            p.at_lock = x  # type: ignore[attr-defined]
            index = c.index
            m = c.pos.item(index)
            c.lock_pos = m
            c.slave_counts = 0
            p.locked = True  # type: ignore[attr-defined]
            base.append(ax.base)
            lock_pos.append(m)
            num.append(c.num)
            den.append(c.den)
            masters.append(index)
            # composition marks the status (GearingLockStatus) and the axis is offered
            dirty.add(ax.index)
            p.status_changed = False
            p.lane = None
            p.offer_pending = False
            reached.append((p, ax))
        self.reached = reached
        self.locked_columns = [
            base, pos, lock_pos, num, den, a["ratio"][r], v_prev, pos, vel, acc
        ]  # fmt: skip
        self.locked_masters = masters
        self.changed = True
        # handed to the lane of locked gears at the same level (GroupLanes._offer_locked)
        self._owner.handed = True

    #: the ``GearLane`` columns of :attr:`reached` (:meth:`GearLane.take_batch`), and
    #: their masters' indices
    locked_columns: list[Any] | None = None
    locked_masters: list[int] | None = None
