"""Time-driven lanes: jogs at speed, trapezoidal jogs and moves on their way, and
trapezoidal stop ramps (every MGS stop, MAS, MC_Stop and MC_Halt without jerk).

None of them reads another axis, so they step first, before any follower.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..enums import ProcessState
from ..processes import JogProcess, MoveProcess, Process, StopRamp
from ..state import AxisArrays
from ..trapezoid import SEGMENTS, TrapezoidProfile
from .base import Compose, Lane
from .stop_rows import StopRows

_DONE = ProcessState.DONE


class CruiseLane(Lane):
    """Jogs at speed: the profile integrates its held velocity (``Profile.step`` and
    ``TrapezoidProfile.step`` once finished)."""

    FIELDS = ("base", "pos", "vel", "dt", "advance")

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

    def _sample(
        self, rows: np.ndarray, seg: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, acceleration) at ``tau`` into segment ``seg``."""
        raise NotImplementedError

    def step(self, s: AxisArrays, compose: Compose) -> None:
        if not self.members:
            return
        a = self.arrays
        cycles = a["cycles"]
        t = (cycles + 1.0) * a["dt"]
        ending = t >= a["done"]
        movers = self.move_out(np.flatnonzero(ending)) if ending.any() else []
        cycles += 1.0
        st = a["start"]
        seg = (t >= st[:, 1]).astype(np.intp) + (t >= st[:, 2]) + (t >= st[:, 3])
        rows = self._rows
        pos, vel, acc = self._sample(rows, seg, t - st[rows, seg])
        a["pos"], a["vel"], a["acc"] = pos, vel, acc
        at = self.at
        s.cmd_pos[at] = a["base"] + pos
        s.cmd_vel[at] = vel
        s.cmd_acc[at] = acc
        for ax in movers:
            compose(ax)


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
    )
    WIDTHS: ClassVar[dict[str, int]] = {
        f: SEGMENTS for f in ("start", "seg_pos", "seg_vel", "seg_acc", "half")
    }

    @staticmethod
    def accepts(p: Process) -> bool:
        if type(p) is not JogProcess and type(p) is not MoveProcess:
            return False
        prof = p.profile
        return isinstance(prof, TrapezoidProfile) and prof.plan is not None and not prof.finished

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
        )

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
        self._owner.dirty = True
