"""MDAC links: which master drives a slave, the pending reassignment, and the stops that
break a link (master-driven speed control, see :mod:`.master_driven` for the rules).

``Controller.mdsc`` is the :class:`MasterDrivenControl` of a controller. An MDAC calls
:meth:`MasterDrivenControl.assign`; MAJ/MAM start through :meth:`~MasterDrivenControl.start`
(time-driven) or :meth:`~MasterDrivenControl.start_master_driven`; stops call the
``break_*`` methods. Processes start and end through :class:`~.motion.Motion`.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from enum import IntEnum

import numpy as np

from .axis import Axis
from .enums import AbortReason, AxisState, AxisType, MasterReference, ProcessKind
from .errors import ErrorCode, MotionError
from .master_driven import (
    MIN_SPEED_SHARE,
    MOVING_EPSILON,
    SHARE_TOLERANCE,
    MasterDrivenProcess,
    MotionType,
    master_speed,
)
from .motion import Motion
from .power import PowerEvent, require
from .processes import JogProcess, MoveProcess, Process
from .state import StepContext


class LinkState(IntEnum):
    """State of one MDAC assignment; IP is set while PENDING or ENABLED."""

    RELEASED = 0
    PENDING = 1
    ENABLED = 2


#: the motion type each process kind belongs to
KIND_TYPE: dict[ProcessKind, MotionType] = {
    ProcessKind.JOG: MotionType.JOG,
    ProcessKind.MOVE: MotionType.MOVE,
    ProcessKind.TIME_CAM: MotionType.TIME_CAM,
}


def covers(link_type: MotionType, motion: MotionType) -> bool:
    return link_type == MotionType.ALL or link_type == motion


def overlap(a: MotionType, b: MotionType) -> bool:
    return a == MotionType.ALL or b == MotionType.ALL or a == b


def programmed_speed(ctx: StepContext, p: Process) -> float:
    """The speed (units/s) process ``p`` was programmed to run at, what the 5 % rule of a
    change of master compares: a master-driven process's programmed speed per master unit
    times its master's speed, a jog's speed, a move's speed limit; for other motion
    (gearing) its velocity."""
    if isinstance(p, MasterDrivenProcess):
        return abs(p.target_ratio) * p.master_speed(ctx)
    if isinstance(p, JogProcess):
        return abs(p.target_velocity)
    if isinstance(p, MoveProcess):
        return p.limits.velocity
    return abs(p.velocity)


class MasterLink:
    """One MDAC assignment of ``master`` to ``slave`` for ``motion_type``."""

    def __init__(
        self,
        slave: int,
        master: int,
        motion_type: MotionType,
        reference: MasterReference,
        owner: object = None,
    ) -> None:
        self.slave = slave
        self.master = master
        self.motion_type = motion_type
        self.reference = reference
        self.owner = owner
        self.state = LinkState.ENABLED
        self.release_reason = AbortReason.NONE
        #: master-driven processes started under this link (AC while one is active)
        self.processes: list[Process] = []
        #: after MGS: AC stays set until the slave has stopped
        self.hold_active: Callable[[], bool] | None = None

    @property
    def in_process(self) -> bool:
        return self.state != LinkState.RELEASED

    @property
    def active(self) -> bool:
        if self.hold_active is not None:
            if self.hold_active():
                return True
            self.hold_active = None
        return any(p.active for p in self.processes)

    def release(self, reason: AbortReason) -> None:
        if self.state != LinkState.RELEASED:
            self.state = LinkState.RELEASED
            self.release_reason = reason

    def __repr__(self) -> str:
        return (
            f"MasterLink(slave={self.slave}, master={self.master}, "
            f"{self.motion_type.name}, {self.state.name})"
        )


#: builds a master-driven process from (link, master axis, inherited ratio)
MasterFactory = Callable[[MasterLink, Axis, float], Process]


class MasterDrivenControl:
    """The MDAC assignments of a controller: the current link per slave and motion type,
    and the pending reassignment per slave."""

    def __init__(self, motion: Motion) -> None:
        self._motion = motion
        self._links: dict[int, list[MasterLink]] = {}
        self._pending: dict[int, MasterLink] = {}

    # -- look-up ----------------------------------------------------------------------------
    def links(self, slave: int) -> list[MasterLink]:
        """Current (enabled) links of a slave."""
        return list(self._links.get(slave, ()))

    def pending(self, slave: int) -> MasterLink | None:
        return self._pending.get(slave)

    def link_for(self, slave: int, motion: MotionType) -> MasterLink | None:
        for link in self._links.get(slave, ()):
            if covers(link.motion_type, motion):
                return link
        return None

    # -- MDAC -------------------------------------------------------------------------------
    def assign(
        self,
        slave: Axis,
        master: Axis,
        motion_type: MotionType,
        reference: MasterReference,
        owner: object = None,
    ) -> MasterLink:
        """Execute an MDAC: enable the link at once, or make it pending when it changes
        the master of an MDAC All in place."""
        if slave.number == master.number:
            raise MotionError(ErrorCode.MASTER_AXIS_CONFLICT, "an axis cannot be its own master")
        if slave.type == AxisType.FEEDBACK_ONLY:
            raise MotionError(ErrorCode.WRONG_AXIS_TYPE, f"{slave.name} is feedback only")
        require(slave, PowerEvent.ASSIGN)
        require(master, PowerEvent.ASSIGN)
        if self._follows(master.number, slave.number):
            raise MotionError(
                ErrorCode.MASTER_AXIS_CONFLICT,
                f"{master.name} already follows {slave.name}: the axes would be cross-coupled",
            )
        moving = abs(slave.command_velocity) > MOVING_EPSILON
        current = [
            lk for lk in self._links.get(slave.number, ()) if overlap(lk.motion_type, motion_type)
        ]
        change = False
        for lk in current:
            if lk.motion_type == MotionType.ALL and motion_type != MotionType.ALL:
                raise MotionError(
                    ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
                    "an MDAC All is active on the slave: only an MDAC All may follow it",
                )
            if lk.master != master.number:
                if lk.motion_type != MotionType.ALL or motion_type != MotionType.ALL:
                    raise MotionError(
                        ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
                        "the master of a Jog or Move assignment changes only after a stop "
                        "breaks the link",
                    )
                change = True
            elif lk.reference != reference and moving:
                raise MotionError(
                    ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
                    "the master reference cannot change while the slave moves",
                )
        link = MasterLink(slave.number, master.number, motion_type, reference, owner)
        old = self._pending.pop(slave.number, None)
        if old is not None:
            old.release(AbortReason.SUPERSEDED)
        if change:
            link.state = LinkState.PENDING
            self._pending[slave.number] = link
            return link
        self._install(link, current)
        return link

    def _install(self, link: MasterLink, replaced: list[MasterLink]) -> None:
        keep = [lk for lk in self._links.get(link.slave, ()) if lk not in replaced]
        for lk in replaced:
            link.processes.extend(p for p in lk.processes if p.active)
            lk.release(AbortReason.SUPERSEDED)
        link.state = LinkState.ENABLED
        self._links[link.slave] = [*keep, link]

    def _follows(self, axis: int, leader: int) -> bool:
        """True if ``axis`` follows ``leader`` through links or processes (transitively)."""
        frontier = [axis]
        seen: set[int] = set()
        while frontier:
            a = frontier.pop()
            if a == leader:
                return True
            if a in seen:
                continue
            seen.add(a)
            for lk in self._links.get(a, ()):
                frontier.append(lk.master)
            pend = self._pending.get(a)
            if pend is not None:
                frontier.append(pend.master)
            try:
                ax = self._motion.axis(a)
            except MotionError:
                continue
            for p in ax.processes:
                if p.active:
                    frontier.extend(p.masters)
        return False

    # -- motion instructions ----------------------------------------------------------------
    def start(
        self,
        slave: Axis,
        kind: ProcessKind,
        make: Callable[[float, float], Process],
        replace: Collection[ProcessKind] | None,
    ) -> Process:
        """Start a time-driven process; a pending reassignment covering it switches now
        (the master-driven motion that keeps running follows the new master: judged as a
        change of master, see :meth:`_judge_change`)."""
        mo = self._motion
        pend = self._pending.get(slave.number)
        if pend is None or not covers(pend.motion_type, KIND_TYPE[kind]):
            return mo.start(slave, make, replace=replace)
        mo.settle(slave)
        master = mo.axis(pend.master)
        v_m = master_speed(mo.s, master, pend.reference)
        replaced = self._replaced(slave, replace)
        moved = [p for p in self._moved_by(slave, pend) if p not in replaced]
        if moved:
            after = sum(abs(p.target_ratio) for p in moved) * v_m
            self._judge_change(slave, master, v_m, moved, after)
        p = mo.start(slave, make, replace=replace)
        self._switch(pend)
        return p

    def start_master_driven(
        self,
        slave: Axis,
        kind: ProcessKind,
        speed: float,
        make: MasterFactory,
        replace: Collection[ProcessKind] | None,
    ) -> Process:
        """Start a master-driven process under the slave's link (a pending one first).

        ``speed`` is the programmed speed in units per master unit (its magnitude is what
        the 5 % rule compares). Raises before anything moves when the change of master is
        refused.
        """
        mo = self._motion
        motion = KIND_TYPE[kind]
        pend = self._pending.get(slave.number)
        if pend is not None and not covers(pend.motion_type, motion):
            pend = None
        link = pend or self.link_for(slave.number, motion)
        if link is None:
            raise MotionError(
                ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
                f"master units need an MDAC with {slave.name} as slave first",
            )
        master = mo.axis(link.master)
        if master.state in (AxisState.AXIS_SHUTDOWN, AxisState.AXIS_FAULTED):
            raise MotionError(
                ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
                f"master {master.name} is {master.state.name.lower()}",
            )
        v_m = master_speed(mo.s, master, link.reference)
        mo.settle(slave)
        replaced = self._replaced(slave, replace)
        same_master = [
            p for p in replaced if isinstance(p, MasterDrivenProcess) and p.master == link.master
        ]
        others = [p for p in replaced if p not in same_master]
        # a pending change moves the master-driven motion that keeps running too
        moved: list[MasterDrivenProcess] = []
        if pend is not None:
            moved = [p for p in self._moved_by(slave, pend) if p not in replaced]
        if pend is not None or any(p.velocity != 0.0 for p in others):
            concerned: list[Process] = [*others, *moved]
            after = abs(speed) * v_m if v_m > MOVING_EPSILON else 0.0
            after += sum(abs(p.target_ratio) for p in moved) * v_m
            self._judge_change(slave, master, v_m, concerned, after)
        # the inherited state in the master domain: ratios of same-master processes add,
        # other velocities are divided by the master speed
        ratio = sum(p.ratio for p in same_master if isinstance(p, MasterDrivenProcess))
        if v_m > MOVING_EPSILON:
            ratio += sum(p.velocity for p in others) / v_m

        def factory(v: float, a: float) -> Process:
            return make(link, master, ratio)

        p = mo.start(slave, factory, replace=replace)
        if pend is not None:
            self._switch(pend)
        link.processes.append(p)
        return p

    def _replaced(self, slave: Axis, replace: Collection[ProcessKind] | None) -> list[Process]:
        return [p for p in slave.processes if p.active and (replace is None or p.kind in replace)]

    def _moved_by(self, slave: Axis, link: MasterLink) -> list[MasterDrivenProcess]:
        """The master-driven processes of ``slave`` that ``link`` takes to its master."""
        return [
            p
            for p in slave.processes
            if p.active
            and isinstance(p, MasterDrivenProcess)
            and p.master != link.master
            and covers(link.motion_type, KIND_TYPE[p.kind])
        ]

    def _judge_change(
        self,
        slave: Axis,
        master: Axis,
        v_m: float,
        concerned: Sequence[Process],
        after: float,
    ) -> None:
        """The seed's rule for a change of master while the slave moves: refused when the
        new master is idle (ERR 97), or when ``after``, the new effective speed of the
        motion that changes (programmed speed x the new master's speed), is less than 5 %
        of the programmed speed of ``concerned``, the motion it changes (ERR 103). Judged
        from programmed values, so the same request gets the same answer whatever the
        axes did before; a slave at rest is never refused."""
        if abs(slave.command_velocity) <= MOVING_EPSILON:
            return  # "If the slave is not moving when the master axis is changed, no problem"
        if v_m <= MOVING_EPSILON:
            raise MotionError(
                ErrorCode.MDSC_IDLE_MASTER_AND_SLAVE_MOVING,
                f"master {master.name} is idle while {slave.name} moves",
            )
        before = sum(programmed_speed(self._motion.s, p) for p in concerned)
        if after < MIN_SPEED_SHARE * before * (1.0 - SHARE_TOLERANCE):
            raise MotionError(
                ErrorCode.MDSC_INVALID_SLAVE_SPEED_REDUCTION,
                f"{slave.name} would run at {after:g} units/s instead of {before:g} "
                f"(less than {MIN_SPEED_SHARE:.0%})",
            )

    def _switch(self, link: MasterLink) -> None:
        """The pending reassignment takes over: the links it covers are released, and the
        master-driven processes still running on the slave follow the new master from
        this scan on (:meth:`MasterDrivenProcess.follow`)."""
        mo = self._motion
        self._pending.pop(link.slave, None)
        slave = mo.axis(link.slave)
        master = mo.axis(link.master)
        moved = self._moved_by(slave, link)
        for p in moved:
            p.follow(mo.s, master, link.reference)
        link.processes.extend(moved)
        if moved:
            slave.motion_changed()
            mo.coupling_changed()
        links = self._links.get(link.slave, [])
        replaced = [lk for lk in links if overlap(lk.motion_type, link.motion_type)]
        for lk in replaced:
            lk.release(AbortReason.SUPERSEDED)
        link.state = LinkState.ENABLED
        self._links[link.slave] = [*(lk for lk in links if lk not in replaced), link]

    @property
    def linked(self) -> bool:
        """Some link or pending reassignment exists (else there is nothing to break)."""
        return bool(self._links or self._pending)

    # -- breaking links ---------------------------------------------------------------------
    def break_slave(self, slave: Axis, reason: AbortReason, hold_active: bool = False) -> None:
        """Break every link (and the pending one) where ``slave`` is the slave."""
        for lk in self._links.pop(slave.number, []):
            self._break(lk, reason, hold_active)
        pend = self._pending.pop(slave.number, None)
        if pend is not None:
            pend.release(reason)

    def break_master(self, master: Axis, reason: AbortReason, hold_active: bool = False) -> None:
        """Break every link (and pending one) whose master is ``master``."""
        for slave, links in list(self._links.items()):
            keep = []
            for lk in links:
                if lk.master == master.number:
                    self._break(lk, reason, hold_active)
                else:
                    keep.append(lk)
            self._links[slave] = keep
        for slave, pend in list(self._pending.items()):
            if pend.master == master.number:
                pend.release(reason)
                del self._pending[slave]

    def break_axis(self, ax: Axis, reason: AbortReason, hold_active: bool = False) -> None:
        self.break_slave(ax, reason, hold_active)
        self.break_master(ax, reason, hold_active)

    def break_all(self, reason: AbortReason) -> None:
        for ax in self._motion.axes:
            self.break_slave(ax, reason)

    def _break(self, link: MasterLink, reason: AbortReason, hold_active: bool) -> None:
        """Release ``link``; its running processes switch to a time-driven stop. With
        ``hold_active`` (MGS) AC stays set until the slave has stopped."""
        slave = self._motion.axis(link.slave)
        was_active = link.active
        link.release(reason)
        self._motion.release(slave, link.processes, reason)
        if hold_active and was_active:
            link.hold_active = lambda: slave.moving

    def update(self) -> None:
        """Once per controller step: a fault on a slave or a master breaks its links."""
        if not self._links and not self._pending:
            return  # no MDAC link anywhere: nothing a fault could break
        axes = self._motion.axes
        faulted = np.flatnonzero(self._motion.s.axis_state == AxisState.AXIS_FAULTED)
        for i in faulted:
            ax = axes[int(i)]
            if ax.number in self._links or self._is_master(ax.number):
                self.break_axis(ax, AbortReason.FAULTED)

    def _is_master(self, number: int) -> bool:
        if any(lk.master == number for links in self._links.values() for lk in links):
            return True
        return any(p.master == number for p in self._pending.values())
