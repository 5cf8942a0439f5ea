"""Jerk-limited ramps to a velocity on their way: jogs and speed changes (MAJ,
MC_MoveVelocity, MCD, overrides), paused moves and jerk-limited stops (MAS with DecelJerk,
MC_Stop / MC_Halt with Jerk), all planned in closed form (:class:`~..scurve.SCurveProfile`,
``JerkPlan.sample``); the sample that ends the plan is the process's own (moved out).

Like the other time-driven lanes it reads no other axis, so it steps first. Position
targets (ruckig's) and fallbacks stay in Python.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..processes import JogProcess, MoveProcess, Process, StopRamp
from ..scurve import SEGMENTS, SCurveProfile
from ..scurve_plan import jerk_plans
from .ramps import PlanLane

#: the per-segment fields of a plan (one row of SEGMENTS values per member)
PLAN_FIELDS = ("start", "seg_pos", "seg_vel", "seg_acc", "half", "jerk", "jhalf", "jsixth")


class SCurveLane(PlanLane):
    """Jerk-limited velocity ramps within their plan, stepped as arrays with the
    operations of ``SCurveProfile.step``, in the same order."""

    FIELDS = ("base", "cycles", "dt", "done", *PLAN_FIELDS, "pos", "vel", "acc")
    WIDTHS: ClassVar[dict[str, int]] = dict.fromkeys(PLAN_FIELDS, SEGMENTS)

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
        )

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        """The joining members' ``FIELDS`` as arrays: the plans not built yet (ramps
        commanded since the last step) built in one pass (:func:`..scurve_plan.jerk_plans`),
        the others loaded one by one."""
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
            add((ax.base, float(prof.cycles), prof._dt, p.position, p.velocity, p.acceleration))
            add(request)
        if not requested:
            return None  # every plan built already: row by row, as before
        m = len(requested)
        cols = np.array(requests, dtype=float).reshape(m, 16)
        dt = cols[:, 2]
        plans = jerk_plans(dt, cols[:, 6:])
        planned = (
            cols[:, 0], cols[:, 1], dt, plans.done, plans.start, plans.pos, plans.vel,
            plans.acc, plans.half, plans.jerk, plans.jhalf, plans.jsixth, cols[:, 3],
            cols[:, 4], cols[:, 5],
        )  # fmt: skip
        if not rows:
            return list(planned)
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
