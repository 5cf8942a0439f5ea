"""Follower lanes: gears on one master, locked (real or fraction ratio) or catching up at a
rate (the MAG clutch, the trapezoidal PLCopen catch-up).

Each member reads its master through the lane's ``source`` (command or actual position,
``AxisArrays.master_arrays``); command followers step by level, after their masters.
"""

from __future__ import annotations

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


class GearLane(LevelledLane):
    """Locked real-ratio gears on one master (``GearProcess.step``, locked, one term)."""

    FIELDS = ("base", "at_lock", "lock_pos", "num", "den", "ratio", "v_prev", "pos", "vel", "acc")

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


class CatchUpLane(LevelledLane):
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
        movers = []
        if caught.any():
            movers = self.move_out(np.flatnonzero(caught) + (level.start or 0))
        v1 = v0 + np.copysign(dv, gap)
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
        for ax in movers:
            compose(ax)
