"""Fast lanes: the steady states of many axes stepped as numpy arrays.

Most axes of a large machine spend most of their time in one of two steady states: a jog
at speed (constant velocity) or a locked gear with a real ratio on one master. Stepping
those as one Python process object per axis costs about a microsecond each; a lane steps
all of them with a few array operations that repeat the objects' floating-point operations
in the same order, so the results are bit-identical (a test runs a controller with and one
without lanes side by side).

Membership:

- An axis joins a lane when its only process is in such a state and it has no buffered
  command; the controller checks this after composing the axis in Python.
- It leaves when anything touches its motion: a new command, a stop, a release, an abort
  (``Controller.settle``), a change of dynamics (``ProfiledProcess.change_dynamics``).
  Leaving first writes the lane's values back into the process object: while an axis is
  in a lane, its process's ``position``, ``velocity`` and ``acceleration`` are stale.

Order, masters before slaves: jogs have no master; a gear on an actual position reads
feedback, which composition never changes; a gear on a command position reads its
master's command of this cycle, so it is at level k + 1 when its master's gear is at
level k, at level 0 when its master jogs in a lane, has no motion or is in another
group, and leaves the lane (it is composed in Python after its master) when its master
is composed in Python.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .gearing import GearProcess, MasterSource
from .processes import JogProcess, Process

if TYPE_CHECKING:
    from .axis import Axis
    from .controller import Controller
    from .group import MotionGroup


class _Lane:
    """Members (process, axis) and their state as parallel arrays.

    Members that joined since the last :meth:`rebuild` wait in ``_joining``: their
    process objects are current until the lane steps them.
    """

    #: names of the float arrays, loaded from a member by :meth:`_load`
    FIELDS: tuple[str, ...] = ()

    def __init__(self, owner: GroupLanes) -> None:
        self._owner = owner
        self.members: list[Process] = []
        self.axes: list[Axis] = []
        self._joining: list[tuple[Process, Axis]] = []
        self._slot: dict[int, int] = {}  # id(process) -> index in the arrays
        self.idx = np.zeros(0, dtype=np.intp)  # slave axis indices
        self.arrays: dict[str, np.ndarray] = {f: np.zeros(0) for f in self.FIELDS}

    def __len__(self) -> int:
        return len(self.members) + len(self._joining)

    def admit(self, p: Process, ax: Axis) -> None:
        p.lane = self
        self._joining.append((p, ax))
        self._owner.dirty = True

    def evict(self, p: Process) -> None:
        """Write the lane's state back into ``p`` and drop it."""
        if p.lane is not self:
            return
        p.lane = None
        k = self._slot.pop(id(p), None)
        if k is not None:
            self._store(p, k)
        self._owner.dirty = True

    def rebuild(self) -> None:
        """Drop evicted members (keeping the others' array values) and add the new ones."""
        keep = [k for k, p in enumerate(self.members) if p.lane is self]
        members = [self.members[k] for k in keep]
        axes = [self.axes[k] for k in keep]
        joining = [(p, ax) for p, ax in self._joining if p.lane is self]
        self._joining = []
        rows = [self._load(p, ax) for p, ax in joining]
        sel = np.array(keep, dtype=np.intp)
        for j, f in enumerate(self.FIELDS):
            old = self.arrays[f][sel]
            new = np.array([r[j] for r in rows], dtype=float)
            self.arrays[f] = np.concatenate((old, new)) if rows else old
        members += [p for p, _ in joining]
        axes += [ax for _, ax in joining]
        self._set_members(members, axes)

    def _set_members(self, members: list[Process], axes: list[Axis]) -> None:
        self.members = members
        self.axes = axes
        self._slot = {id(p): k for k, p in enumerate(members)}
        self.idx = np.array([ax.index for ax in axes], dtype=np.intp)

    def _load(self, p: Process, ax: Axis) -> tuple[float, ...]:
        raise NotImplementedError

    def _store(self, p: Process, k: int) -> None:
        raise NotImplementedError


class JogLane(_Lane):
    """Jogs at speed: the profile integrates its held velocity (``Profile.step``)."""

    FIELDS = ("base", "pos", "vel", "dt")

    @staticmethod
    def eligible(p: Process) -> bool:
        return type(p) is JogProcess and p.profile.finished

    def _load(self, p: Process, ax: Axis) -> tuple[float, ...]:
        assert isinstance(p, JogProcess)
        prof = p.profile
        return (ax.base, prof.position, prof.velocity, prof.dt)

    def _store(self, p: Process, k: int) -> None:
        assert isinstance(p, JogProcess)
        pos = float(self.arrays["pos"][k])
        p.profile.position = pos
        p.position = pos

    def step(self, ctl: Controller) -> None:
        if not self.members:
            return
        a = self.arrays
        pos = a["pos"]
        pos += a["vel"] * a["dt"]
        idx = self.idx
        ctl.cmd_pos[idx] = a["base"] + pos
        ctl.cmd_vel[idx] = a["vel"]
        ctl.cmd_acc[idx] = 0.0


class GearLane(_Lane):
    """Locked real-ratio gears on one master (``GearProcess.step``, locked, one term).

    The members are ordered by level; ``levels`` holds each level's slice.
    """

    FIELDS = ("base", "at_lock", "lock_pos", "num", "den", "ratio", "v_prev", "pos", "vel", "acc")

    def __init__(self, owner: GroupLanes, source: MasterSource) -> None:
        super().__init__(owner)
        self.source = source
        self.midx = np.zeros(0, dtype=np.intp)
        self.levels: list[slice] = []

    @staticmethod
    def eligible(p: Process) -> MasterSource | None:
        if type(p) is not GearProcess or not p.locked:
            return None
        c = p.single
        if c is None or c.exact:
            return None
        return MasterSource.COMMAND if c.acc is not None else MasterSource.ACTUAL

    def _load(self, p: Process, ax: Axis) -> tuple[float, ...]:
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

    def order(self, levels: list[int]) -> None:
        """Sort the members by ``levels`` (one per member, in member order)."""
        perm = sorted(range(len(self.members)), key=levels.__getitem__)
        sel = np.array(perm, dtype=np.intp)
        for f in self.FIELDS:
            self.arrays[f] = self.arrays[f][sel]
        self._set_members([self.members[k] for k in perm], [self.axes[k] for k in perm])
        sorted_levels = [levels[k] for k in perm]
        self.levels = []
        start = 0
        for k in range(1, len(perm) + 1):
            if k == len(perm) or sorted_levels[k] != sorted_levels[start]:
                self.levels.append(slice(start, k))
                start = k
        masters = []
        for p in self.members:
            assert isinstance(p, GearProcess) and p.single is not None
            masters.append(p.single.index)
        self.midx = np.array(masters, dtype=np.intp)

    def step(self, ctl: Controller, level: slice, dt: float) -> None:
        a = self.arrays
        mi = self.midx[level]
        if self.source == MasterSource.COMMAND:
            m, v, am = ctl.cmd_pos[mi], ctl.cmd_vel[mi], ctl.cmd_acc[mi]
        else:
            m, v = ctl.act_pos[mi], ctl.act_vel[mi]
            am = None
        ratio = a["ratio"][level]
        # the operations and their order of GearProcess.step's locked one-master path
        pos = a["at_lock"][level] + (m - a["lock_pos"][level]) * a["num"][level] / a["den"][level]
        vel = ratio * v
        acc = ratio * am if am is not None else ratio * (v - a["v_prev"][level]) / dt
        a["v_prev"][level] = v
        a["pos"][level] = pos
        a["vel"][level] = vel
        a["acc"][level] = acc
        si = self.idx[level]
        ctl.cmd_pos[si] = a["base"][level] + pos
        ctl.cmd_vel[si] = vel
        ctl.cmd_acc[si] = acc


class GroupLanes:
    """The lanes of one motion group, and the axes it still composes in Python."""

    def __init__(self, group: MotionGroup) -> None:
        self.group = group
        self.jogs = JogLane(self)
        self.cmd_gears = GearLane(self, MasterSource.COMMAND)
        self.act_gears = GearLane(self, MasterSource.ACTUAL)
        #: the group's axes in composition order, without those in a lane
        self.python_order: list[Axis] = list(group.order)
        self.dirty = False

    def offer(self, ax: Axis) -> None:
        """After ``ax`` was composed in Python: admit its process if it is steady."""
        p = ax.processes[0]
        if JogLane.eligible(p):
            self.jogs.admit(p, ax)
            return
        source = GearLane.eligible(p)
        if source == MasterSource.COMMAND:
            self.cmd_gears.admit(p, ax)
        elif source == MasterSource.ACTUAL:
            self.act_gears.admit(p, ax)

    def rebuild(self, ctl: Controller) -> None:
        self.jogs.rebuild()
        self.act_gears.rebuild()
        self.act_gears.order([0] * len(self.act_gears.members))
        self.cmd_gears.rebuild()
        self._order_command_gears(ctl)
        laned = {id(ax) for lane in (self.jogs, self.cmd_gears, self.act_gears) for ax in lane.axes}
        self.python_order = [ax for ax in self.group.order if id(ax) not in laned]
        self.dirty = False  # evictions while levelling set it: they are rebuilt above

    def _order_command_gears(self, ctl: Controller) -> None:
        lane = self.cmd_gears
        group = self.group.number
        by_axis = {id(ax): p for p, ax in zip(lane.members, lane.axes, strict=True)}
        jogging = {id(ax) for ax in self.jogs.axes}
        memo: dict[int, int | None] = {}

        def level(ax: Axis) -> int | None:
            """Level of ``ax``'s laned gear; None when it cannot stay in the lane."""
            key = id(ax)
            if key in memo:
                return memo[key]
            memo[key] = None  # no loops (gearing refuses them); guards anyway
            p = by_axis[key]
            assert isinstance(p, GearProcess) and p.single is not None
            master = ctl.axes[p.single.index]
            mkey = id(master)
            result: int | None
            if master.group != group or mkey in jogging:
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

        levels = [level(ax) for ax in lane.axes]
        if any(lv is None for lv in levels):
            for p, lv in zip(list(lane.members), levels, strict=True):
                if lv is None:
                    lane.evict(p)
            lane.rebuild()
            levels = [lv for lv in levels if lv is not None]
        lane.order(levels)  # type: ignore[arg-type]

    def step(self, ctl: Controller, dt: float) -> None:
        self.jogs.step(ctl)
        if self.act_gears.members:
            self.act_gears.step(ctl, slice(None), dt)
        for level in self.cmd_gears.levels:
            self.cmd_gears.step(ctl, level, dt)
