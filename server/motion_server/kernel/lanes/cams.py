"""Cam lanes: locked position cams on one master (MAPC, MC_CamIn), stepped as arrays.

A member is a :class:`~..cams.CamProcess` locked on a master read through the lane's
``source``, following both master directions, with no Pending successor, inside its
profile's range (Once, Persistent) or repeating it (Continuous). The lane repeats
``CamProcess._locked_step``'s operations in the same order; the profile is evaluated once
per distinct profile of a level (:meth:`CamProfile.evaluate_many
<..cam_profile.CamProfile.evaluate_many>`), so 256 slaves on one table cost one search.
A Continuous cam passing its profile's end stays in the lane (the pass is counted); a Once
or Persistent cam leaving the range is an event: it is moved out and stepped in Python.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter
from typing import Any, ClassVar

import numpy as np

from ..axis import Axis
from ..cam_profile import CamProfile
from ..cams import CamMode, CamPhase, CamProcess, MasterDirection
from ..enums import MasterReference, ProcessKind
from ..processes import Process
from ..state import AxisArrays, compact
from .base import Compose, LaneOwner, LevelledLane

_CONTINUOUS = float(CamMode.CONTINUOUS)

#: the lane's fields read from a cam (:meth:`CamLane._load`) and the attributes that hold
#: them, in one getter (:meth:`CamLane._batch_columns`)
_STATE_FIELDS = {
    "origin": "origin",
    "scale": "scale",
    "ms": "master_scaling",
    "cam_lock": "cam_lock",
    "f0": "f0",
    "m0": "m0",
    "mode": "mode",
    "k": "k",
    "v_prev": "v_prev",
    "m_last": "m_prev",
    "x": "x",
    "pos": "position",
    "vel": "velocity",
    "acc": "acceleration",
}
_STATE_NAMES = tuple(_STATE_FIELDS)
_STATE = attrgetter(*_STATE_FIELDS.values())
#: a member's master index (``CamLane.master_index``), without a call per member
_MASTER = attrgetter("index")
#: the fields that are the profile's (the same for every cam on it)
_PROFILE_NAMES = ("start", "end", "length", "rise")


class CamLane(LevelledLane):
    """Locked position cams on one master (see the module docstring)."""

    FIELDS = (
        "base",
        "origin",
        "scale",
        "ms",
        "cam_lock",
        "f0",
        "m0",
        "start",
        "end",
        "length",
        "rise",
        "mode",
        "k",
        "passes",
        "v_prev",
        "m_last",
        "x",
        "pos",
        "vel",
        "acc",
    )
    DTYPES: ClassVar[dict[str, Any]] = {"passes": np.int64}

    #: the member list of a rebuild made of one batch, until the lane is ordered (see
    #: :meth:`rebuild`; a class default: None)
    _fresh: list[Process] | None = None

    #: per level: every cam of it is Continuous (set when the lane is ordered; None, a
    #: class default, for a lane restored from state saved before: the general step)
    _continuous: list[bool] | None = None

    def __init__(self, owner: LaneOwner, source: MasterReference) -> None:
        super().__init__(owner, source)
        #: per level: (profile, rows of the level's arrays) for each distinct profile
        self.by_profile: list[list[tuple[CamProfile, slice | np.ndarray]]] = []
        self._continuous = []

    @staticmethod
    def accepts(p: Process) -> bool:
        return (
            type(p) is CamProcess
            and p.kind == ProcessKind.POSITION_CAM
            and p.index is not None
            and p.phase == CamPhase.LOCKED
            and p.master_direction == MasterDirection.BIDIRECTIONAL
            and p.successor is None
            and p.ramp is None
            and p.in_range
            and p.engaged
        )

    @staticmethod
    def master_index(p: Process) -> int:
        # (called per member at every order: a member is a cam with a master, accepts)
        return p.index  # type: ignore[attr-defined]

    def _load(self, p: Process, ax: Axis) -> tuple[Any, ...]:
        assert isinstance(p, CamProcess)
        prof = p.profile
        return (
            ax.base,
            p.origin,
            p.scale,
            p.master_scaling,
            p.cam_lock,
            p.f0,
            p.m0,
            prof.start,
            prof.end,
            prof.length,
            prof.rise,
            float(p.mode),
            float(p.k),
            p.passes,
            p.v_prev,
            p.m_prev,
            p.x,
            p.position,
            p.velocity,
            p.acceleration,
        )

    def admit_batch(
        self,
        joining: Sequence[tuple[Process, Axis]],
        columns: dict[str, np.ndarray],
        levels: dict[int, int] | None,
    ) -> None:
        """:meth:`admit` of each of ``joining`` (new cams, in order, each the only process
        of an axis that had none, already marked as in this lane and offered), with
        their ``FIELDS`` but ``base`` as ``columns``, what :meth:`_load` would read
        (:func:`~..cam_batch.start_position_cams` computes them from the masters' arrays
        and the cams' shared parameters): the next rebuild takes them instead of
        reading the cams one by one, if nothing joined after them and none left.

        ``levels``: the command level each new cam will have, by ``id`` of the cam (the
        caller checked that no follower already in the lanes reads one of these
        slaves): the next rebuild orders the follower lanes by the levels they had and
        these (``GroupLanes._hand_over``) instead of levelling every follower again.
        None: the followers are levelled again, as after any admission."""
        mine = self._joining
        self._batch = (joining[0][0], len(mine), len(joining), columns)
        mine.extend(joining)
        self.changed = True
        owner = self._owner
        if levels is None:
            owner.dirty = True
            return
        owner.handed = True
        handed = owner.__dict__.get("_handed")
        if handed is None:
            owner._handed = handed = {}  # type: ignore[attr-defined]
        handed.update(levels)

    def _batch_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        """The ``FIELDS`` of the cams joining, column by column: those of a batch
        (:meth:`admit_batch`) as it left them, the others read from the cams
        (:meth:`_read_columns`)."""
        batch = self._batch
        if batch is not None:
            first, before, count, columns = batch
            if len(joining) == before + count and joining[before][0] is first:
                col = dict(columns)
                col["base"] = np.array([ax.base for _, ax in joining[before:]], dtype=float)
                if before:
                    head = self._read_columns(joining[:before])
                    assert head is not None  # (cams joined before the batch)
                    return [
                        np.concatenate((h, col[f])) for h, f in zip(head, self.FIELDS, strict=True)
                    ]
                return [col[f] for f in self.FIELDS]
        return self._read_columns(joining)

    def _read_columns(self, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
        """The ``FIELDS`` of the cams joining, column by column: the values
        :meth:`_load` reads, with one attribute getter per cam and one array for all
        (not a tuple per cam and an array per field), the profile's constants
        broadcast when every cam runs on one profile (the usual case: many slaves on
        one table)."""
        if not joining:
            return None  # (nothing to add: the members kept are all there is)
        procs = [p for p, _ in joining]
        n = len(procs)
        block = np.array([_STATE(p) for p in procs], dtype=float).reshape((n, len(_STATE_NAMES)))
        col = {name: block[:, j] for j, name in enumerate(_STATE_NAMES)}
        profiles = [p.profile for p in procs]  # type: ignore[attr-defined]
        first = profiles[0]
        if all(q is first for q in profiles):
            for name in _PROFILE_NAMES:
                col[name] = np.full(n, getattr(first, name), dtype=float)
        else:
            for name in _PROFILE_NAMES:
                col[name] = np.array([getattr(q, name) for q in profiles], dtype=float)
        col["base"] = np.array([ax.base for _, ax in joining], dtype=float)
        col["passes"] = np.array([p.passes for p in procs], dtype=np.int64)  # type: ignore[attr-defined]
        return [col[f] for f in self.FIELDS]

    def _store(self, p: Process, k: int) -> None:
        assert isinstance(p, CamProcess)
        a = self.arrays
        p.position = float(a["pos"][k])
        p.velocity = float(a["vel"][k])
        p.acceleration = float(a["acc"][k])
        p.v_prev = float(a["v_prev"][k])
        p.k = int(a["k"][k])
        p.passes = int(a["passes"][k])
        p.x = float(a["x"][k])
        p.m_prev = p.m_eff = float(a["m_last"][k])

    def rebuild(self) -> None:
        """:meth:`Lane.rebuild <.base.Lane.rebuild>`; when the lane was empty and one
        batch is all that joined (:meth:`admit_batch`, none of it evicted), the same
        result straight from the batch's columns: no row to keep, select or append."""
        batch = self._batch
        joining = self._joining
        if (
            not self.changed
            or batch is None
            or self.members
            or batch[1] != 0
            or len(joining) != batch[2]
        ):
            super().rebuild()
            return
        procs = [p for p, _ in joining]
        if any(p.lane is not self for p in procs):
            super().rebuild()
            return
        columns = self._batch_columns(joining)
        assert columns is not None
        axes = [ax for _, ax in joining]
        self._joining = []
        self._batch = None
        self._kept = []
        dtypes = self.DTYPES
        # (copies: two fields may share one column, and the lane writes its fields in place)
        self.arrays = {
            f: np.array(c, dtype=dtypes.get(f, float))
            for f, c in zip(self.FIELDS, columns, strict=True)
        }
        self.members = procs
        self.axes = axes
        self._slot = dict(zip(map(id, procs), range(len(procs)), strict=True))
        self.idx = np.array([ax.index for ax in axes], dtype=np.intp)
        self.at = compact(self.idx)
        self.changed = False
        self._fresh = procs

    def order(self, levels: list[int]) -> None:
        fresh = self._fresh is self.members
        self._fresh = None
        n = len(levels)
        if fresh and n and levels.count(levels[0]) == n:
            # a lane just made of one batch, every cam at one level L (the usual batch):
            # what LevelledLane.order leaves (nothing to sort; levels below L empty),
            # without walking the members level by level
            top = levels[0]
            self.member_levels = list(levels)
            self.levels = [slice(0, 0)] * top + [slice(0, n)]
            self.midx = np.array(list(map(_MASTER, self.members)), dtype=np.intp)
            self.slaves = [compact(self.idx[sl]) for sl in self.levels]
            self.whole = [sl.stop - sl.start == n for sl in self.levels]
            self.masters = [compact(self.midx[sl]) for sl in self.levels]
        else:
            super().order(levels)
        mode = self.arrays["mode"]
        self._continuous = [bool(np.all(mode[sl] == _CONTINUOUS)) for sl in self.levels]
        self.by_profile = []
        members = self.members
        if members:
            first = members[0].profile  # type: ignore[attr-defined]
            if all(p.profile is first for p in members):  # type: ignore[attr-defined]
                # one profile for the whole lane: one evaluation per level, no grouping
                self.by_profile = [[(first, slice(None))] for _ in self.levels]
                return
        for sl in self.levels:
            groups: dict[int, tuple[CamProfile, list[int]]] = {}
            for row in range(sl.start, sl.stop):
                p = self.members[row]
                assert isinstance(p, CamProcess)
                groups.setdefault(id(p.profile), (p.profile, []))[1].append(row - sl.start)
            parts: list[tuple[CamProfile, slice | np.ndarray]] = []
            for prof, rows in groups.values():
                if len(groups) == 1:
                    parts.append((prof, slice(None)))
                else:
                    parts.append((prof, np.array(rows, dtype=np.intp)))
            self.by_profile.append(parts)

    def step(self, s: AxisArrays, lv: int, dt: float, compose: Compose) -> None:
        a = self.arrays
        level = self.levels[lv]
        mi = self.masters[lv]
        m_arr, v_arr, a_arr = s.master_arrays(self.source)
        m = m_arr[mi]
        v = v_arr[mi]
        # CamProcess._locked_step: x from the master's displacement since the lock
        x = a["cam_lock"][level] + (m - a["m0"][level]) / a["ms"][level]
        start = a["start"][level]
        length = a["length"][level]
        flags = self._continuous
        if flags is not None and flags[lv]:
            # every cam of the level Continuous (the usual case): the selections below
            # all take their Continuous branch, and no cam leaves its range
            self._step_continuous(s, lv, x, m, v, a_arr, dt)
            return
        cont = a["mode"][level] == _CONTINUOUS
        # events first (nothing written yet): a Once or Persistent cam leaving its range
        leaving = ~cont & ((x < start) | (x > a["end"][level]))
        movers: list[Axis] = []
        if leaving.any():
            movers = self.move_out(np.flatnonzero(leaving) + (level.start or 0))
        if a_arr is not None:
            am = a_arr[mi]
        else:
            am = (v - a["v_prev"][level]) / dt
        a["v_prev"][level] = v
        a["m_last"][level] = m
        a["x"][level] = x
        k = np.where(cont, np.floor((x - start) / length), 0.0)
        passed = cont & (k != a["k"][level])
        if passed.any():
            a["passes"][level] += passed
            a["k"][level] = k
        c = np.where(cont, x - k * length, x)
        f = np.empty_like(c)
        f1 = np.empty_like(c)
        f2 = np.empty_like(c)
        for prof, rows in self.by_profile[lv]:
            f[rows], f1[rows], f2[rows] = prof.evaluate_many(c[rows])
        scale = a["scale"][level]
        ms = a["ms"][level]
        fk = np.where(cont, f + k * a["rise"][level], f)
        pos = a["origin"][level] + scale * (fk - a["f0"][level])
        r = v / ms
        vel = scale * f1 * r
        acc = scale * (f2 * r * r + f1 * (am / ms))
        a["pos"][level], a["vel"][level], a["acc"][level] = pos, vel, acc
        si = self.slaves[lv]
        s.cmd_pos[si] = a["base"][level] + pos
        s.cmd_vel[si] = vel
        s.cmd_acc[si] = acc
        for ax in movers:
            compose(ax)

    def _step_continuous(
        self,
        s: AxisArrays,
        lv: int,
        x: np.ndarray,
        m: np.ndarray,
        v: np.ndarray,
        a_arr: np.ndarray | None,
        dt: float,
    ) -> None:
        """:meth:`step` of a level of Continuous cams only: the same operations, in the
        same order, without the selections by mode (each would take its Continuous
        branch) and without looking for cams leaving their range (none does)."""
        a = self.arrays
        level = self.levels[lv]
        mi = self.masters[lv]
        if a_arr is not None:
            am = a_arr[mi]
        else:
            am = (v - a["v_prev"][level]) / dt
        a["v_prev"][level] = v
        a["m_last"][level] = m
        a["x"][level] = x
        length = a["length"][level]
        k = np.floor((x - a["start"][level]) / length)
        passed = k != a["k"][level]
        if passed.any():
            a["passes"][level] += passed
            a["k"][level] = k
        c = x - k * length
        parts = self.by_profile[lv]
        if len(parts) == 1 and isinstance(parts[0][1], slice):
            f, f1, f2 = parts[0][0].evaluate_many(c)  # one profile for the whole level
        else:
            f = np.empty_like(c)
            f1 = np.empty_like(c)
            f2 = np.empty_like(c)
            for prof, rows in parts:
                f[rows], f1[rows], f2[rows] = prof.evaluate_many(c[rows])
        scale = a["scale"][level]
        ms = a["ms"][level]
        fk = f + k * a["rise"][level]
        pos = a["origin"][level] + scale * (fk - a["f0"][level])
        r = v / ms
        vel = scale * f1 * r
        acc = scale * (f2 * r * r + f1 * (am / ms))
        a["pos"][level], a["vel"][level], a["acc"][level] = pos, vel, acc
        si = self.slaves[lv]
        s.cmd_pos[si] = a["base"][level] + pos
        s.cmd_vel[si] = vel
        s.cmd_acc[si] = acc
