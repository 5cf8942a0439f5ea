"""Jerk-limited ramps to a velocity on their way: jogs and speed changes (MAJ,
MC_MoveVelocity, MCD, overrides), paused moves and jerk-limited stops (MAS with DecelJerk,
MC_Stop / MC_Halt with Jerk), all planned in closed form (:class:`~..scurve.SCurveProfile`,
``JerkPlan.sample``). The plans of the ramps commanded since the last step are built
together when they join (:mod:`..scurve_plan`). A jog that reaches its velocity, alone
on its axis, is ended by the lane and handed to the cruise lane (as the profile lane
does for trapezoidal jogs); the sample that ends any other plan is the process's own
(moved out).

Like the other time-driven lanes it reads no other axis, so it steps first. Position
targets (ruckig's) and fallbacks stay in Python.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..processes import JogProcess, MoveProcess, Process, StopRamp
from ..scurve import SEGMENTS, SCurveProfile
from ..scurve_plan import TARGET, jerk_plan_row, jerk_plans
from ..state import AxisArrays
from .base import Compose
from .batches import admit_rows, batch_of, spread
from .ramps import PlanLane

#: the per-segment fields of a plan (one row of SEGMENTS values per member)
PLAN_FIELDS = ("start", "seg_pos", "seg_vel", "seg_acc", "half", "jerk", "jhalf", "jsixth")


class SCurveLane(PlanLane):
    """Jerk-limited velocity ramps within their plan, stepped as arrays with the
    operations of ``SCurveProfile.step``, in the same order."""

    FIELDS = (
        "base", "cycles", "dt", "done", *PLAN_FIELDS, "pos", "vel", "acc", "end", "end_pos",
        "end_vel",
    )  # fmt: skip
    WIDTHS: ClassVar[dict[str, int]] = dict.fromkeys(PLAN_FIELDS, SEGMENTS)

    def _restore_ends(self) -> None:
        """A lane saved before it kept the plans' ends: take them from its members'
        plans (at its first rebuild or step: while a snapshot is being loaded the
        members may not be restored yet)."""
        if "end" in self.arrays:
            return
        plans = [p.profile.plan for p in self.members]  # type: ignore[attr-defined]
        self.arrays["end"] = np.array([q.end for q in plans], dtype=float)
        self.arrays["end_pos"] = np.array([q.end_position for q in plans], dtype=float)
        self.arrays["end_vel"] = np.array([q.end_velocity for q in plans], dtype=float)

    def rebuild(self) -> None:
        self._restore_ends()
        super().rebuild()

    def step(self, s: AxisArrays, compose: Compose) -> None:
        self._restore_ends()
        super().step(s, compose)

    @staticmethod
    def accepts(p: Process) -> bool:
        kind = type(p)
        if kind is not JogProcess and kind is not MoveProcess and kind is not StopRamp:
            return False
        prof = p.profile  # type: ignore[attr-defined]
        return (
            isinstance(prof, SCurveProfile)
            and prof.planned
            and prof.ruckig is None
            and not prof.finished
        )

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, JogProcess | MoveProcess | StopRamp)
        prof = p.profile
        assert isinstance(prof, SCurveProfile) and prof.plan is not None
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
            plan.jerk,
            plan.jhalf,
            plan.jsixth,
            p.position,
            p.velocity,
            p.acceleration,
            plan.end,
            plan.end_position,
            plan.end_velocity,
        )

    @staticmethod
    def _planned(cols: np.ndarray) -> list[np.ndarray]:
        """The ``FIELDS`` of m ramps not planned yet, from their rows (base, cycles, dt,
        position, velocity, acceleration, then the profile's request), of shape (m, 16):
        the plans built in one pass (:func:`..scurve_plan.jerk_plans`)."""
        dt = cols[:, 2]
        plans = jerk_plans(dt, cols[:, 6:])
        return [
            cols[:, 0], cols[:, 1], dt, plans.done, plans.start, plans.pos, plans.vel,
            plans.acc, plans.half, plans.jerk, plans.jhalf, plans.jsixth, cols[:, 3],
            cols[:, 4], cols[:, 5], plans.end, plans.end_pos, cols[:, 6 + TARGET],
        ]  # fmt: skip

    def admit_batch(
        self,
        joining: Sequence[tuple[Process, Axis]],
        base: np.ndarray,
        kinds: Sequence[tuple[float, ...]],
        which: np.ndarray | None,
    ) -> None:
        """Admit ``joining`` (jerk-limited velocity targets just commanded on axes at
        rest, their plans still requests: :func:`..jog_batch.start_jogs`) in this order;
        ``base`` their axes' bases; ``kinds`` the distinct rows of what
        :meth:`_batch_columns` reads of each after the base (cycles, dt, position,
        velocity, acceleration, the request), ``which`` the kind of each (None: all the
        first). The plans, the same for every ramp of a kind, are built once per kind
        (:func:`..scurve_plan.jerk_plan_row`); if the batch is all that joins before the
        next rebuild, the rebuild takes its columns as they are."""
        rows = []
        for kind in kinds:
            cycles, dt, x, v, a = kind[:5]
            request = kind[5:]
            *plan, (done, end, end_pos) = jerk_plan_row(dt, request)
            rows.append((cycles, dt, done, *plan, x, v, a, end, end_pos, request[TARGET]))
        admit_rows(self, joining, spread(self, base, rows, which))

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        """The joining members' ``FIELDS`` as arrays: those of a batch admitted alone
        (:meth:`admit_batch`) as they are; else the plans not built yet (ramps commanded
        since the last step) built in one pass (:func:`..scurve_plan.jerk_plans`), the
        others loaded one by one."""
        columns = batch_of(self, joining)
        if columns is not None:
            return columns
        requested: list[int] = []
        requests: list[float] = []
        add = requests.extend
        rows: list[tuple[Any, ...]] = []
        for k, (p, ax) in enumerate(joining):
            prof = p.profile  # type: ignore[attr-defined]
            request = prof.request
            if request is None:
                rows.append(self._load(p, ax))
                continue
            requested.append(k)
            add((ax.base, prof.cycles, prof._dt, p.position, p.velocity, p.acceleration))
            add(request)
        if not requested:
            return None  # every plan built already: row by row, as before
        m = len(requested)
        # (the floats packed as doubles, bit for bit: five times faster than numpy's
        # conversion of a list; read-only columns, which the rebuild concatenates)
        planned = self._planned(np.frombuffer(struct.pack(f"{16 * m}d", *requests)).reshape(m, 16))
        if not rows:
            return planned
        # both kinds: place each column's rows where their members are
        n = len(joining)
        at = np.array(requested, dtype=np.intp)
        others = np.setdiff1d(np.arange(n, dtype=np.intp), at)
        columns = []
        for j, f in enumerate(self.FIELDS):
            width = self.WIDTHS.get(f)
            col = np.empty((n,) if width is None else (n, width))
            col[at] = planned[j]
            col[others] = np.array([r[j] for r in rows], dtype=float)
            columns.append(col)
        return columns

    def _ending(self, s: AxisArrays, rows: np.ndarray) -> tuple[list[int], list[int]]:
        """A jog that reaches its velocity, its axis's only process with nothing
        buffered and the drive on, is ended by the lane (:meth:`_end`): the usual case;
        the others (paused moves, stops and the rest) by their process's own step."""
        if len(rows) == len(self.members) and self._all_jogs_alone(s):
            # every plan ends in this step (a batch of jogs reaching their speed
            # together), each a jog alone on its axis: all ended, in row order
            return rows.tolist(), []
        ended, odd = [], []
        drive_on = s.drive_on
        for k in rows.tolist():
            p, ax = self.members[k], self.axes[k]
            procs = ax.processes
            if (
                type(p) is JogProcess
                and len(procs) == 1
                and procs[0] is p
                and ax.buffered is None
                and drive_on[ax.index]
            ):
                ended.append(k)
            else:
                odd.append(k)
        return ended, odd

    def _end(self, s: AxisArrays, rows: list[int], t: np.ndarray) -> None:
        """The jogs at ``rows`` reach their velocity at the sample ``t``: what composing
        their axes does (``SCurveProfile.finish_plan``, ``JogProcess._after_step``,
        ``Motion.compose`` of a single process, then ``Motion.offer``: at speed, it joins
        the cruise lane), with the finishing sample computed as arrays, the same
        operations in the same order. The plan of a jog whose plan is still a request
        is not built: a finished profile does not need it."""
        a = self.arrays
        r = np.array(rows, dtype=np.intp)
        gap = t[r] - a["end"][r]
        end_vel = a["end_vel"][r]
        # finish_plan: end_position + max(t - end, 0.0) * end_velocity
        x = a["end_pos"][r] + np.where(gap < 0.0, 0.0, gap) * end_vel
        cmd = a["base"][r] + x
        positions, velocities = x.tolist(), end_vel.tolist()
        cycles = (a["cycles"][r]).tolist()  # already counted this sample
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
        for p, x_k, v_k, c in zip(ended, positions, velocities, cycles, strict=True):
            # (a JogProcess on an SCurveProfile: _ending, accepts)
            prof = p.profile  # type: ignore[attr-defined]
            prof.cycles = int(c)
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
        # admitted to the cruise lane in row order (``Lane.admit`` of each), with the
        # columns its rebuild would read of them (``CruiseLane._load``)
        at_speed = list(zip(ended, their_axes, strict=True))
        cruise = self._owner.cruise  # type: ignore[attr-defined]
        cruise.hand_in_all(at_speed)
        dt = a["dt"][r]
        cruise.take_batch(at_speed, [[ax.base for ax in their_axes], x, end_vel, dt, end_vel * dt])
        self.changed = True
        # from this lane to the cruise lane, both time-driven: the followers keep their
        # levels (``Lane.RELEVELS``), as for the jogs the profile lane hands over
        self._owner.joined = True

    def _sample(
        self, rows: np.ndarray, seg: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        a = self.arrays
        v0 = a["seg_vel"][rows, seg]
        a0 = a["seg_acc"][rows, seg]
        pos = a["seg_pos"][rows, seg] + tau * (
            v0 + tau * (a["half"][rows, seg] + tau * a["jsixth"][rows, seg])
        )
        vel = v0 + tau * (a0 + tau * a["jhalf"][rows, seg])
        acc = a0 + tau * a["jerk"][rows, seg]
        return pos, vel, acc
