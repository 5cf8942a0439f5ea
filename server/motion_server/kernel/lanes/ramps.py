"""Time-driven lanes: jogs at speed, trapezoidal jogs and moves on their way, and
trapezoidal stop ramps (every MGS stop, MAS, MC_Stop and MC_Halt without jerk).

None of them reads another axis, so they step first, before any follower.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from operator import attrgetter, is_, itemgetter
from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..enums import ProcessState
from ..move_plan import velocity_plan_row, velocity_plans
from ..processes import JogProcess, MoveProcess, Process, StopRamp
from ..state import AxisArrays
from ..trapezoid import SEGMENTS, TrapezoidProfile
from .base import Compose, Lane
from .batches import admit_rows, batch_of, spread
from .stop_rows import StopRows

_DONE = ProcessState.DONE
_STOP_ROWS = attrgetter("stop_rows")
_BUFFERED = attrgetter("buffered")
_PROCESSES = attrgetter("_processes")
_FIRST = itemgetter(0)
_BASE = attrgetter("base")


class CruiseLane(Lane):
    """Jogs at speed: the profile integrates its held velocity (``Profile.step`` and
    ``TrapezoidProfile.step`` once finished)."""

    RELEVELS = False

    FIELDS = ("base", "pos", "vel", "dt", "advance")
    STORED = ("pos",)

    @staticmethod
    def accepts(p: Process) -> bool:
        return type(p) is JogProcess and p.profile.finished

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, JogProcess)
        prof = p.profile
        # the profile adds velocity x dt every step: the same product each time
        return (ax.base, prof.position, prof.velocity, prof.dt, prof.velocity * prof.dt)

    def _store(self, p: Process, k: int) -> None:
        assert isinstance(p, JogProcess)
        pos = float(self.arrays["pos"][k])
        p.profile.position = pos
        p.position = pos

    def _store_columns(self, members: list[Any], columns: dict[str, list[Any]]) -> None:
        for p, pos in zip(members, columns["pos"], strict=True):
            p.profile.position = pos
            p.position = pos

    def take_batch(self, joining: Sequence[tuple[Process, Axis]], columns: list[Any]) -> None:
        """``joining`` (jogs the profile lane ended at speed, ``ProfileLane._end``) were
        admitted last, in this order; ``columns`` holds their ``FIELDS``, what
        :meth:`_load` would read: if they are all that joined since the last rebuild,
        the next rebuild takes the columns instead of loading them one by one."""
        mine = self._joining
        if len(mine) == len(joining) and all(
            q is p for (q, _), (p, _) in zip(mine, joining, strict=True)
        ):
            self._batch = (joining[0][0], len(joining), columns)

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        batch = self._batch
        if batch is None or not joining or joining[0][0] is not batch[0]:
            return None
        if len(joining) != batch[1]:
            return None
        return [np.asarray(col, dtype=float) for col in batch[2]]

    def place(self, s: AxisArrays) -> None:
        """After a rebuild: the members' velocity and acceleration, which stay constant
        while they cruise (nothing else writes them while the axis is in the lane)."""
        s.cmd_vel[self.at] = self.arrays["vel"]
        s.cmd_acc[self.at] = 0.0

    def step(self, s: AxisArrays) -> None:
        if not self.members:
            return
        a = self.arrays
        pos = a["pos"]
        pos += a["advance"]
        s.cmd_pos[self.at] = a["base"] + pos


class PlanLane(Lane):
    """Profiles sampled from a plan of segments at exact multiples of dt (the trapezoid
    of :mod:`..trapezoid`, the S-curve of :mod:`..scurve`): the members' cycle counts,
    the segment each is in, and the sample that ends a plan moved out to its own step.
    A subclass gives the polynomial of a segment (:meth:`_sample`)."""

    RELEVELS = False

    def __init__(self, owner: Any) -> None:
        super().__init__(owner)
        self._rows = np.zeros(0, dtype=np.intp)

    def _store(self, p: Process, k: int) -> None:
        prof = p.profile  # type: ignore[attr-defined]
        a = self.arrays
        prof.cycles = int(a["cycles"][k])
        prof.position = p.position = float(a["pos"][k])
        prof.velocity = p.velocity = float(a["vel"][k])
        prof.acceleration = p.acceleration = float(a["acc"][k])

    def _set_members(self, members: list[Process], axes: list[Axis]) -> None:
        super()._set_members(members, axes)
        self._rows = np.arange(len(members), dtype=np.intp)

    def replans(self, p: Process) -> bool:
        """``p`` has a row here (not one still joining), so a change of its dynamics
        can rewrite it: the caller syncs it (:meth:`sync`), plans it anew, then calls
        :meth:`replan`."""
        return p.lane is self and id(p) in self._slot

    def replan(self, p: Process) -> bool:
        """``p``, a member synced and then planned anew (MCD, an override): if this lane
        still takes it, its row is written from it as :meth:`_load` reads it, what
        leaving the lane and joining it again would load, and True. Its axis stays in
        the lane, and the followers reading it keep their lanes and levels. Else it
        leaves the lane without its state written back (it holds the new plan) and
        False."""
        k = self._slot[id(p)]
        if not self.accepts(p):
            del self._slot[id(p)]
            p.lane = None
            self.changed = True
            self._owner.dirty = True
            return False
        arrays = self.arrays  # (a rebuild's arrays: its own, writable)
        for f, value in zip(self.FIELDS, self._load(p, self.axes[k]), strict=True):
            arrays[f][k] = value
        return True

    #: the floats :meth:`_request_head` and the profile's request make, per ramp
    ROW_WIDTH: ClassVar[int]

    @staticmethod
    def _request_head(p: Process, ax: Axis) -> tuple[float, ...]:
        """What :meth:`_planned` reads of ``p`` before its profile's request."""
        raise NotImplementedError

    @staticmethod
    def _planned(rows: np.ndarray) -> list[np.ndarray]:
        """The ``FIELDS`` of m ramps not planned yet from their rows (``ROW_WIDTH``
        each: :meth:`_request_head`, then the request), the plans built in one pass."""
        raise NotImplementedError

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        """The joining members' ``FIELDS`` as arrays: those of a batch admitted alone
        (``admit_batch``) as they are; else the plans not built yet (ramps commanded since
        the last step) built in one pass (:meth:`_planned`), the others loaded one by
        one."""
        columns = batch_of(self, joining)
        if columns is not None:
            return columns
        requested: list[int] = []
        requests: list[float] = []
        add = requests.extend
        head = self._request_head
        rows: list[tuple[Any, ...]] = []
        loaded: list[int] = []  # (the positions of ``rows``)
        for k, (p, ax) in enumerate(joining):
            request = p.profile.request  # type: ignore[attr-defined]
            if request is None:
                rows.append(self._load(p, ax))
                loaded.append(k)
                continue
            requested.append(k)
            add(head(p, ax))
            add(request)
        if not requested:
            return None  # every plan built already: row by row, as before
        m = len(requested)
        width = self.ROW_WIDTH
        # (the floats packed as doubles, bit for bit: five times faster than numpy's
        # conversion of a list; read-only columns, which the rebuild concatenates)
        packed = np.frombuffer(struct.pack(f"{width * m}d", *requests)).reshape(m, width)
        planned = self._planned(packed)
        if not rows:
            return planned
        # both kinds: place each column's rows where their members are
        n = len(joining)
        at = np.array(requested, dtype=np.intp)
        # (not numpy's setdiff1d: its first call imports numpy.ma, 10 ms in a cycle)
        others = np.array(loaded, dtype=np.intp)
        columns = []
        for j, f in enumerate(self.FIELDS):
            width_f = self.WIDTHS.get(f)
            dtype = self.DTYPES.get(f, float)
            col = np.empty((n,) if width_f is None else (n, width_f), dtype=dtype)
            col[at] = planned[j]
            col[others] = np.array([r[j] for r in rows], dtype=dtype)
            columns.append(col)
        return columns

    def admit_planned(
        self,
        joining: Sequence[tuple[Process, Axis]],
        base: np.ndarray,
        kinds: Sequence[tuple[Any, ...]],
        which: np.ndarray | None,
    ) -> None:
        """Admit ``joining`` (moves just commanded, planned:
        :func:`..move_batch.start_moves`) in this order; ``base`` their axes' bases;
        ``kinds`` the distinct rows of what :meth:`_load` reads of each after the base
        (the moves of one distance share their plan), ``which`` the kind of each (None:
        all the first). If the batch is all that joins before the next rebuild, the
        rebuild takes its columns as they are."""
        admit_rows(self, joining, spread(self, base, kinds, which))

    def _sample(
        self, rows: np.ndarray, seg: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, acceleration) at ``tau`` into segment ``seg``."""
        raise NotImplementedError

    def _segment(self, t: np.ndarray, st: np.ndarray) -> np.ndarray:
        """The segment each sample at ``t`` falls in (``st``: the starts of four)."""
        return (t >= st[:, 1]).astype(np.intp) + (t >= st[:, 2]) + (t >= st[:, 3])

    def step(self, s: AxisArrays, compose: Compose) -> None:
        if not self.members:
            return
        a = self.arrays
        cycles = a["cycles"]
        t = (cycles + 1.0) * a["dt"]
        ending = t >= a["done"]
        movers: list[Axis] = []
        ended: list[int] = []
        if ending.any():
            ended, odd = self._ending(s, np.flatnonzero(ending))
            movers = self.move_out(odd) if odd else []
        cycles += 1.0
        st = a["start"]
        seg = self._segment(t, st)
        rows = self._rows
        pos, vel, acc = self._sample(rows, seg, t - st[rows, seg])
        a["pos"], a["vel"], a["acc"] = pos, vel, acc
        at = self.at
        s.cmd_pos[at] = a["base"] + pos
        s.cmd_vel[at] = vel
        s.cmd_acc[at] = acc
        if ended:
            self._end(s, ended, t)
        for ax in movers:
            compose(ax)

    def _all_jogs_alone(self, s: AxisArrays) -> bool:
        """The test of :meth:`_ending` for every member at once, as whole-list passes:
        each a jog (not landing, in a lane with landings), its axis's only process (no
        stop row), nothing buffered, the drive on."""
        members, axes = self.members, self.axes
        n = len(members)
        if (
            ("landing" in self.arrays and self.arrays["landing"].any())
            or list(map(type, members)).count(JogProcess) != n
            or list(map(_STOP_ROWS, axes)).count(None) != n
            or list(map(_BUFFERED, axes)).count(None) != n
            or not s.drive_on[self.idx].all()
        ):
            return False
        procs = list(map(_PROCESSES, axes))
        return list(map(len, procs)).count(1) == n and all(map(is_, map(_FIRST, procs), members))

    def _ending(self, s: AxisArrays, rows: np.ndarray) -> tuple[list[int], list[int]]:
        """The rows whose plan ends this step, split into those the lane ends itself
        (:meth:`_end`) and those moved out to their process's own step."""
        return [], rows.tolist()

    def _end(self, s: AxisArrays, rows: list[int], t: np.ndarray) -> None:
        """The jogs at ``rows`` (from :meth:`_ending`) reach their velocity at the sample
        ``t``: what composing their axes does (the profile's ``finish_plan``,
        ``JogProcess._after_step``, ``Motion.compose`` of a single process, then
        ``Motion.offer``: at speed, it joins the cruise lane), with the finishing sample
        computed as arrays, the same operations in the same order. Each jog leaves this
        lane for the cruise lane, admitted in row order (``Lane.admit`` of each) with the
        columns its rebuild would read of them (``CruiseLane._load``); its plan stays as
        it is, built or still a request (a finished profile does not need it)."""
        a = self.arrays
        r = np.array(rows, dtype=np.intp)
        gap = t[r] - a["end"][r]
        end_vel = a["end_vel"][r]
        # finish_plan: end_position + max(t - end, 0.0) * end_velocity (not landing)
        x = a["end_pos"][r] + np.where(gap < 0.0, 0.0, gap) * end_vel
        cmd = a["base"][r] + x
        positions, velocities = x.tolist(), end_vel.tolist()
        # already counted this sample; whole numbers (int() of each, as integers)
        cycles = a["cycles"][r].astype(np.int64).tolist()
        idx = self.idx[r]
        s.cmd_pos[idx] = cmd
        s.cmd_vel[idx] = end_vel
        s.cmd_acc[idx] = 0.0
        slot = self._slot
        members, axes = self.members, self.axes
        if len(rows) == len(members):
            # every member (a batch of jogs at speed together): no slot is left
            ended, their_axes = members, axes
            slot.clear()
        else:
            ended = [members[k] for k in rows]
            their_axes = [axes[k] for k in rows]
            for p in ended:
                slot.pop(id(p), None)
        bases = list(map(_BASE, their_axes))
        for p, x_k, v_k, c in zip(ended, positions, velocities, cycles, strict=True):
            # (a JogProcess: _ending, accepts)
            prof = p.profile  # type: ignore[attr-defined]
            prof.cycles = c
            prof.finished = True
            prof.position = x_k
            prof.velocity = v_k
            prof.acceleration = 0.0
            p.position = x_k
            p.velocity = v_k
            p.acceleration = 0.0
            p.at_speed = True  # type: ignore[attr-defined]
            # leaves this lane and is offered at once (Motion.offer): to the cruise lane
            p.lane = None
            p.offer_pending = False
        at_speed = list(zip(ended, their_axes, strict=True))
        cruise = self._owner.cruise  # type: ignore[attr-defined]
        cruise.hand_in_all(at_speed)
        dt = a["dt"][r]
        cruise.take_batch(at_speed, [bases, x, end_vel, dt, end_vel * dt])
        self.changed = True
        # from this lane to the cruise lane, both time-driven: the followers keep their
        # levels (``Lane.RELEVELS``)
        self._owner.joined = True


class ProfileLane(PlanLane):
    """Trapezoidal jogs and moves within their plan (``TrapezoidProfile.step`` and
    ``Plan.sample``); the sample that ends the plan is the process's own (moved out)."""

    FIELDS = (
        "base",
        "cycles",
        "dt",
        "done",
        "start",
        "seg_pos",
        "seg_vel",
        "seg_acc",
        "half",
        "pos",
        "vel",
        "acc",
        "end",
        "end_pos",
        "end_vel",
        "landing",
    )
    DTYPES: ClassVar[dict[str, Any]] = {"landing": bool}
    WIDTHS: ClassVar[dict[str, int]] = {
        f: SEGMENTS for f in ("start", "seg_pos", "seg_vel", "seg_acc", "half")
    }

    @staticmethod
    def accepts(p: Process) -> bool:
        if type(p) is not JogProcess and type(p) is not MoveProcess:
            return False
        prof = p.profile
        return isinstance(prof, TrapezoidProfile) and prof.planned and not prof.finished

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, JogProcess | MoveProcess)
        prof = p.profile
        assert isinstance(prof, TrapezoidProfile) and prof.plan is not None
        plan = prof.plan
        return (
            ax.base,
            float(prof.cycles),
            prof.dt,
            plan.done,
            plan.start,
            plan.pos,
            plan.vel,
            plan.acc,
            plan.half,
            p.position,
            p.velocity,
            p.acceleration,
            plan.end,
            plan.end_position,
            plan.end_velocity,
            plan.landing,
        )

    #: what :meth:`_planned` reads of a ramp not planned yet: base, dt, position,
    #: velocity, acceleration, then the profile's request (the plan's start position and
    #: velocity, the target, the acceleration and the deceleration)
    ROW_WIDTH = 10

    @staticmethod
    def _request_head(p: Process, ax: Axis) -> tuple[float, ...]:
        prof = p.profile  # type: ignore[attr-defined]
        return (ax.base, prof._dt, p.position, p.velocity, p.acceleration)

    @staticmethod
    def _planned(requests: np.ndarray) -> list[np.ndarray]:
        """The ``FIELDS`` of m velocity targets not planned yet, from their rows
        (base, dt, position, velocity, acceleration, then the profile's request), of
        shape (m, 10): the plans built in one pass (:func:`..move_plan.velocity_plans`)."""
        cols = requests.T
        base, dt, x, v, acc = cols[0], cols[1], cols[2], cols[3], cols[4]
        target = cols[7]
        plans = velocity_plans(dt, cols[5], cols[6], target, cols[8], cols[9])
        m = len(requests)
        return [
            base, np.zeros(m), dt, plans.done, plans.start, plans.pos, plans.vel, plans.acc,
            plans.half, x, v, acc, plans.end, plans.end_pos, target, np.zeros(m, dtype=bool),
        ]  # fmt: skip

    def admit_batch(
        self,
        joining: Sequence[tuple[Process, Axis]],
        base: np.ndarray,
        kinds: Sequence[tuple[float, ...]],
        which: np.ndarray | None,
    ) -> None:
        """Admit ``joining`` (velocity targets just commanded on axes at rest, their
        profiles' plans still requests: :func:`..jog_batch.start_jogs`) in this order;
        ``base`` their axes' bases; ``kinds`` the distinct rows of what
        :meth:`_batch_columns` reads of each after the base (dt, position, velocity,
        acceleration, the request), ``which`` the kind of each (None: all the first).
        The plans, the same for every jog of a kind, are built once per kind
        (:func:`..move_plan.velocity_plan_row`); if the batch is all that joins before
        the next rebuild, the rebuild takes its columns as they are."""
        rows = []
        for dt, x, v, a, p0, v0, target, acc, dec in kinds:
            start, pos, vel, seg_acc, half, (done, end, end_pos) = velocity_plan_row(
                dt, p0, v0, target, acc, dec
            )
            rows.append(
                (0.0, dt, done, start, pos, vel, seg_acc, half, x, v, a, end, end_pos,
                 target, False)
            )  # fmt: skip
        admit_rows(self, joining, spread(self, base, rows, which))

    def _ending(self, s: AxisArrays, rows: np.ndarray) -> tuple[list[int], list[int]]:
        """A jog that reaches its velocity, its axis's only process with nothing
        buffered and the drive on, is ended by the lane (:meth:`_end`): the usual case;
        the others (moves, which land, and the rest) by their process's own step."""
        members, axes = self.members, self.axes
        n = len(rows)
        if n == len(members) and self._all_jogs_alone(s):
            # every plan ends in this step (a batch of jogs reaching their speed
            # together), each a jog alone on its axis: all ended, in row order
            return rows.tolist(), []
        ended, odd = [], []
        # (read as lists once: a numpy scalar per row costs more than the test)
        landing = self.arrays["landing"][rows].tolist()
        drive_on = s.drive_on[self.idx[rows]].tolist()
        for j, k in enumerate(rows.tolist()):
            p, ax = members[k], axes[k]
            # (the property's call saved: no stop row here unless its ramp is to be made)
            procs = ax._processes if ax.stop_rows is None else ax.processes
            if (
                type(p) is JogProcess
                and not landing[j]
                and len(procs) == 1
                and procs[0] is p
                and ax.buffered is None
                and drive_on[j]
            ):
                ended.append(k)
            else:
                odd.append(k)
        return ended, odd

    def _sample(
        self, rows: np.ndarray, seg: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        a = self.arrays
        v0 = a["seg_vel"][rows, seg]
        acc = a["seg_acc"][rows, seg]
        pos = a["seg_pos"][rows, seg] + tau * (v0 + tau * a["half"][rows, seg])
        vel = v0 + tau * acc
        return pos, vel, acc


class StopLane(Lane):
    """Trapezoidal stop ramps (``StopRamp.step`` without jerk): the velocity drops by
    deceleration x dt per step; the step that reaches rest is the ramp's own (moved
    out). The ramps of a group stop join as :class:`~.stop_rows.StopRows` (``rows``):
    arrays whose ramp objects are made only when read; they step after the members."""

    FIELDS = ("base", "pos", "vel", "acc", "decel")
    STORED = ("pos", "vel", "acc")
    RELEVELS = False
    #: the group stops' rows (a class default for lanes restored from older state)
    rows: list[StopRows] = []  # noqa: RUF012 (replaced per instance, never mutated here)

    def __len__(self) -> int:
        return super().__len__() + sum(len(r) for r in self.rows)

    def add_rows(self, rows: StopRows) -> None:
        """A group stop's ramps join (stepped from the next step on)."""
        self.rows = [*self.rows, rows]
        self._owner.dirty = True

    @property
    def row_axes(self) -> list[Axis]:
        """The axes of the rows (after a rebuild: those whose ramp is in the lane)."""
        if len(self.rows) == 1:
            return self.rows[0].axes
        return [ax for r in self.rows for ax in r.axes]

    def evict(self, p: Process) -> None:
        if p.lane is self and self.rows and id(p) not in self._slot:
            for r in self.rows:
                k = r.row(p)
                if k is not None:
                    r.evict(p, k)
                    return
        super().evict(p)

    def sync(self, p: Process) -> None:
        if p.lane is self and self.rows and id(p) not in self._slot:
            for r in self.rows:
                k = r.row(p)
                if k is not None:
                    r.store(p, k)
                    return
        super().sync(p)

    def rebuild(self) -> None:
        if self.rows:
            self.rows = [r for r in self.rows if r.compact()]
        super().rebuild()

    @staticmethod
    def accepts(p: Process) -> bool:
        return type(p) is StopRamp and p.limits.trapezoidal

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, StopRamp)
        return (ax.base, p.position, p.velocity, p.acceleration, p.limits.deceleration)

    def _store(self, p: Process, k: int) -> None:
        a = self.arrays
        p.position = float(a["pos"][k])
        p.velocity = float(a["vel"][k])
        p.acceleration = float(a["acc"][k])

    def _store_columns(self, members: list[Any], columns: dict[str, list[Any]]) -> None:
        for p, x, v, a in zip(members, columns["pos"], columns["vel"], columns["acc"],
                              strict=True):  # fmt: skip
            p.position = x
            p.velocity = v
            p.acceleration = a

    def step(self, s: AxisArrays, dt: float, compose: Compose) -> None:
        if self.members:
            self._step_members(s, dt, compose)
        for rows in self.rows:
            rows.step(s, dt, compose)

    def _step_members(self, s: AxisArrays, dt: float, compose: Compose) -> None:
        a = self.arrays
        v0 = a["vel"]
        dv = a["decel"] * dt
        ending = np.abs(v0) <= dv * (1.0 + 1e-9)
        v1 = v0 - np.copysign(dv, v0)
        resting: list[int] = []
        movers: list[Axis] = []
        if ending.any():
            rows = np.flatnonzero(ending)
            resting, odd = self._resting(rows)
            if odd:
                movers = self.move_out(odd)
            v1[rows] = 0.0  # the ramp's last step: to rest exactly
        pos = a["pos"]
        pos += 0.5 * (v0 + v1) * dt
        acc = (v1 - v0) / dt
        a["vel"], a["acc"] = v1, acc
        at = self.at
        s.cmd_pos[at] = a["base"] + pos
        s.cmd_vel[at] = v1
        s.cmd_acc[at] = acc
        if resting:
            self._come_to_rest(s, resting)
        for ax in movers:
            compose(ax)

    def _resting(self, rows: np.ndarray) -> tuple[list[int], list[int]]:
        """The rows whose ramp reaches rest this step, split into those the lane ends
        itself (the ramp is its axis's only process, nothing buffered: the usual case)
        and the others, which their axes' composition ends in Python."""
        resting, odd = [], []
        for k in rows.tolist():
            p, ax = self.members[k], self.axes[k]
            procs = ax.processes
            if len(procs) == 1 and procs[0] is p and ax.buffered is None:
                resting.append(k)
            else:
                odd.append(k)
        return resting, odd

    def _come_to_rest(self, s: AxisArrays, rows: list[int]) -> None:
        """End the ramps at ``rows``, stepped to rest by the lane: what composing their
        axes does for a ramp that finishes (``StopRamp.step``, then ``Motion.compose``:
        the ramp is done and leaves the axis, its displacement folded into the base,
        the command is the base at rest, the axis no longer busy), without the calls."""
        a = self.arrays
        rows_arr = np.array(rows, dtype=np.intp)
        positions = a["pos"][rows_arr].tolist()
        accelerations = a["acc"][rows_arr].tolist()
        r = s.scalars
        dirty = s.dirty
        slot = self._slot
        for k, x, acc in zip(rows, positions, accelerations, strict=True):
            p, ax = self.members[k], self.axes[k]
            # leaves the lane (nothing to store: its state is set here)
            p.lane = None
            p.offer_pending = True
            slot.pop(id(p), None)
            p.position = x
            p.velocity = 0.0
            p.acceleration = acc
            p.state = _DONE
            ax.base += x
            ax.processes = []
            i = ax.index
            r.cmd_pos[i] = ax.base + 0.0
            r.cmd_vel[i] = 0.0
            r.cmd_acc[i] = 0.0
            r.busy[i] = False
            dirty.add(i)
        self.changed = True
        # at rest, without motion: the followers that read these axes keep level 0
        self._owner.joined = True
