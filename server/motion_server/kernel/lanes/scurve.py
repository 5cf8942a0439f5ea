"""Jerk-limited profiles on their way: ramps to a velocity (jogs and speed changes:
MAJ, MC_MoveVelocity, MCD, overrides; paused moves; jerk-limited stops: MAS with
DecelJerk, MC_Stop / MC_Halt with Jerk) and moves to a position (MAM, MC_MoveAbsolute,
MC_MoveRelative), all planned in closed form (:class:`~..scurve.SCurveProfile`,
``JerkPlan.sample``). A move's plan has eight segments, a velocity ramp's four: the lane
keeps eight columns, a ramp's last four empty (they start where its plan ends, so no
sample before the end falls in them). The plans of the ramps commanded since the last
step are built together when they join (:mod:`..scurve_plan`). A jog that reaches its
velocity, alone on its axis, is ended by the lane and handed to the cruise lane (as the
profile lane does for trapezoidal jogs); the sample that ends any other plan (a move's
included) is the process's own (moved out).

Like the other time-driven lanes it reads no other axis, so it steps first. What the
closed forms leave to ruckig (:data:`..scurve.FALLBACKS`) joins as well once ruckig's
plan is turned into segments (:mod:`..ruckig_plan`); the rare plan that is not stays in
Python.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..processes import JogProcess, MoveProcess, Process, StopRamp
from ..scurve import POSITION_SEGMENTS, SEGMENTS, JerkPlan, SCurveProfile
from ..scurve_plan import TARGET, jerk_plan_row, jerk_plans
from ..state import AxisArrays
from .base import Compose
from .batches import admit_rows, spread
from .ramps import PlanLane

#: the per-segment fields of a plan (one row of POSITION_SEGMENTS values per member)
PLAN_FIELDS = ("start", "seg_pos", "seg_vel", "seg_acc", "half", "jerk", "jhalf", "jsixth")
#: the empty segments after a velocity ramp's four
_PAD = POSITION_SEGMENTS - SEGMENTS
_ZEROS = (0.0,) * _PAD


def pad_plan(end: float, fields: tuple[tuple[float, ...], ...]) -> tuple[tuple[float, ...], ...]:
    """The ``PLAN_FIELDS`` of a plan as the lane holds them: a velocity ramp's four
    segments and four empty ones that start at its ``end`` (a move's eight as they are)."""
    start, pos, vel, acc, half, jerk, jhalf, jsixth = fields
    if len(start) == POSITION_SEGMENTS:
        return fields
    z = _ZEROS
    return (
        (*start, end, end, end, end), pos + z, vel + z, acc + z, half + z, jerk + z,
        jhalf + z, jsixth + z,
    )  # fmt: skip


def pad_columns(end: np.ndarray, columns: list[np.ndarray]) -> list[np.ndarray]:
    """:func:`pad_plan` of the ``PLAN_FIELDS`` columns of m velocity ramps, (m, 4) each."""
    start, *rest = columns
    m = len(end)
    out = [np.concatenate((start, np.repeat(end[:, None], _PAD, axis=1)), axis=1)]
    zeros = np.zeros((m, _PAD))
    out.extend(np.concatenate((c, zeros), axis=1) for c in rest)
    return out


def plan_row(
    cycles: float, dt: float, kinematics: tuple[float, ...], plan: JerkPlan
) -> tuple[Any, ...]:
    """A member's ``FIELDS`` but the base: its profile's ``cycles`` and ``dt``, its
    ``plan`` (padded: :func:`pad_plan`), its position, velocity and acceleration
    (``kinematics``), the plan's end."""
    fields = (
        plan.start, plan.pos, plan.vel, plan.acc, plan.half, plan.jerk, plan.jhalf,
        plan.jsixth,
    )  # fmt: skip
    return (
        cycles, dt, plan.done, *pad_plan(plan.end, fields), *kinematics, plan.end,
        plan.end_position, plan.end_velocity,
    )  # fmt: skip


def planned_row(p: Process) -> tuple[Any, ...]:
    """What the lane reads of ``p`` (a member whose plan is built) after its axis's
    base (:func:`plan_row`)."""
    assert isinstance(p, JogProcess | MoveProcess | StopRamp)
    prof = p.profile
    assert isinstance(prof, SCurveProfile) and prof.plan is not None
    kinematics = (p.position, p.velocity, p.acceleration)
    return plan_row(float(prof.cycles), prof.dt, kinematics, prof.plan)


class SCurveLane(PlanLane):
    """Jerk-limited velocity ramps within their plan, stepped as arrays with the
    operations of ``SCurveProfile.step``, in the same order."""

    FIELDS = (
        "base", "cycles", "dt", "done", *PLAN_FIELDS, "pos", "vel", "acc", "end", "end_pos",
        "end_vel",
    )  # fmt: skip
    WIDTHS: ClassVar[dict[str, int]] = dict.fromkeys(PLAN_FIELDS, POSITION_SEGMENTS)

    def __setstate__(self, state: dict[str, Any]) -> None:
        # saved when the lane held four segments (velocity ramps only): pad them
        arrays = state.get("arrays", {})
        start = arrays.get("start")
        if start is not None and start.shape[1] == SEGMENTS:
            # (saved before the lane kept the plans' ends, too: the empty segments start
            # at infinity, where no sample reaches them either)
            end = arrays["end"] if "end" in arrays else np.full(len(start), np.inf)
            padded = pad_columns(end, [arrays[f] for f in PLAN_FIELDS])
            arrays.update(zip(PLAN_FIELDS, padded, strict=True))
        super().__setstate__(state)

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

    #: the starts column the lane last looked at, and whether a move is among its rows
    _moves: tuple[np.ndarray, bool] | None = None

    def _segment(self, t: np.ndarray, st: np.ndarray) -> np.ndarray:
        """``JerkPlan.segment`` of every member: the first four segments, then the last
        four when a move is in the lane (a velocity ramp's start at its end, where no
        sample before the end falls). Whether a move is in is worked out again whenever
        the column is another array (a rebuild, a member leaving)."""
        seg = (t >= st[:, 1]).astype(np.intp) + (t >= st[:, 2]) + (t >= st[:, 3])
        moves = self._moves
        if moves is None or moves[0] is not st:
            moves = self._moves = (st, bool((st[:, 4] < self.arrays["end"]).any()))
        if moves[1]:
            # (each a count: numpy adds two boolean arrays as a logical or)
            seg += (t >= st[:, 4]).astype(np.intp) + (t >= st[:, 5]) + (t >= st[:, 6])
            seg += t >= st[:, 7]
        return seg

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state.pop("_moves", None)  # (a cache of the arrays)
        return state

    def replan(self, p: Process) -> bool:
        kept = super().replan(p)
        self._moves = None  # (a row rewritten in place: a move may be among them now)
        return kept

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        return (ax.base, *planned_row(p))

    #: what :meth:`_planned` reads of a ramp not planned yet: base, cycles, dt,
    #: position, velocity, acceleration, then the profile's request (10 floats)
    ROW_WIDTH = 16

    @staticmethod
    def _request_head(p: Process, ax: Axis) -> tuple[float, ...]:
        prof = p.profile  # type: ignore[attr-defined]
        return (ax.base, prof.cycles, prof._dt, p.position, p.velocity, p.acceleration)

    @staticmethod
    def _planned(cols: np.ndarray) -> list[np.ndarray]:
        """The ``FIELDS`` of m ramps not planned yet, from their rows (base, cycles, dt,
        position, velocity, acceleration, then the profile's request), of shape (m, 16):
        the plans built in one pass (:func:`..scurve_plan.jerk_plans`)."""
        dt = cols[:, 2]
        plans = jerk_plans(dt, cols[:, 6:])
        fields = pad_columns(
            plans.end,
            [plans.start, plans.pos, plans.vel, plans.acc, plans.half, plans.jerk,
             plans.jhalf, plans.jsixth],
        )  # fmt: skip
        return [
            cols[:, 0], cols[:, 1], dt, plans.done, *fields, cols[:, 3], cols[:, 4],
            cols[:, 5], plans.end, plans.end_pos, cols[:, 6 + TARGET],
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
            fields = pad_plan(end, tuple(plan))
            rows.append((cycles, dt, done, *fields, x, v, a, end, end_pos, request[TARGET]))
        admit_rows(self, joining, spread(self, base, rows, which))

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
