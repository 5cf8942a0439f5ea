"""Master Driven Speed Control (MDSC): master assignments and master-driven processes.

An MDAC assigns a master axis to a slave for a motion type (All, Jog, Move). A MAJ or MAM
whose dynamics are in master units then runs a *master-driven* process: its profile
advances with the master's travel instead of time. Speed is in slave units per master
unit, acceleration in units per master unit², jerk in units per master unit³, so the
slave's speed is the programmed speed times the master's speed.

Decisions (where the Logix manuals leave it open):

- Lock direction is "immediate, forward only": the profile advances with the master's
  forward travel; a master moving in reverse holds the slave where it is.
- A virtual master is read at its command position, a feedback-only master at its actual
  position, whatever the MasterReference says (the manuals' rule).
- Changing the master: an MDAC All to another master while an MDAC All is in place makes
  the reassignment *pending*; the next MAJ/MAM on the slave that goes IP switches it. A
  master-driven instruction that changes the slave's master while the slave moves is
  refused when the new master is idle (ERR 97) or when the new effective speed, programmed
  speed × new master speed, is under 5 % of the slave's speed (ERR 103); the pending
  reassignment then stays pending. Processes already running keep the master they started
  with; only new instructions use the new one.
- A link of a type other than All is reassigned only after a stop breaks it (ERR 105).
- A link breaks on MAS All, MGS, MASD, MGSD, a fault or a mode change on the slave, and on
  MGS, MASD, MGSD, a fault or a mode change on the master. Breaking a link does not move
  an axis; the stop that broke it does.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from enum import IntEnum
from typing import TYPE_CHECKING, Any

import ruckig

from .enums import AbortReason, AxisState, AxisType, ProcessKind
from .errors import ErrorCode, MotionError
from .processes import Process
from .profiles import Limits

if TYPE_CHECKING:
    from .axis import Axis
    from .controller import Controller

#: a slave moving slower than this (units/s) counts as standing still for the master change
MOVING_EPSILON = 1e-9
#: the new effective slave speed must be at least this share of the speed before a change
MIN_SPEED_SHARE = 0.05


class MotionType(IntEnum):
    """MDAC Motion Type: which single-axis motion the assignment covers."""

    ALL = 0
    JOG = 1
    MOVE = 2


class MasterReference(IntEnum):
    """Master position source (Logix numbering)."""

    ACTUAL = 0
    COMMAND = 1


class LinkState(IntEnum):
    """State of one MDAC assignment; IP is set while PENDING or ENABLED."""

    RELEASED = 0
    PENDING = 1
    ENABLED = 2


#: the motion type each process kind belongs to
KIND_TYPE: dict[ProcessKind, MotionType] = {
    ProcessKind.JOG: MotionType.JOG,
    ProcessKind.MOVE: MotionType.MOVE,
}


def covers(link_type: MotionType, motion: MotionType) -> bool:
    return link_type == MotionType.ALL or link_type == motion


def overlap(a: MotionType, b: MotionType) -> bool:
    return a == MotionType.ALL or b == MotionType.ALL or a == b


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


def master_position(ctl: Controller, master: Axis, reference: MasterReference) -> float:
    """Unwound position of the master as the link reads it."""
    i = master.index
    if master.type == AxisType.VIRTUAL:
        return float(ctl.cmd_pos[i])
    if master.type == AxisType.FEEDBACK_ONLY or reference == MasterReference.ACTUAL:
        return float(ctl.act_pos[i])
    return float(ctl.cmd_pos[i])


def master_speed(ctl: Controller, master: Axis, reference: MasterReference) -> float:
    """The master's forward speed (units/s) as the link reads it; reverse counts as 0."""
    i = master.index
    if master.type == AxisType.VIRTUAL:
        v = float(ctl.cmd_vel[i])
    elif master.type == AxisType.FEEDBACK_ONLY or reference == MasterReference.ACTUAL:
        v = float(ctl.act_vel[i])
    else:
        v = float(ctl.cmd_vel[i])
    return max(v, 0.0)


class MasterProfile:
    """A ruckig trajectory planned in the master-position domain (offline, sampled at the
    master travel ``s``): positions in slave units, "velocity" a ratio (units per master
    unit). Beyond its duration a velocity target continues at constant ratio and a
    position target holds."""

    def __init__(
        self, limits: Limits, ratio: float, velocity: float | None, position: float | None
    ) -> None:
        limits = limits.validated()
        inp = ruckig.InputParameter(1)
        inp.current_position = [0.0]
        inp.current_velocity = [float(ratio)]
        inp.current_acceleration = [0.0]
        if position is not None:
            if not math.isfinite(position):
                raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "distance must be finite")
            inp.control_interface = ruckig.ControlInterface.Position
            inp.target_position = [float(position)]
            inp.target_velocity = [0.0]
            direction = position
        else:
            assert velocity is not None
            if not math.isfinite(velocity):
                raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "speed must be finite")
            inp.control_interface = ruckig.ControlInterface.Velocity
            inp.target_velocity = [float(velocity)]
            direction = velocity if velocity != 0.0 else ratio
        inp.target_acceleration = [0.0]
        top = abs(velocity) if velocity is not None and position is None else 0.0
        inp.max_velocity = [max(limits.velocity, abs(ratio), top)]
        if direction >= 0.0:
            inp.max_acceleration = [limits.acceleration]
            inp.min_acceleration = [-limits.deceleration]
        else:
            inp.max_acceleration = [limits.deceleration]
            inp.min_acceleration = [-limits.acceleration]
        inp.max_jerk = [limits.ruckig_jerk]
        self._traj = ruckig.Trajectory(1)
        try:
            result = ruckig.Ruckig(1).calculate(inp, self._traj)
        except RuntimeError as exc:  # pragma: no cover - inputs are validated beforehand
            raise MotionError(ErrorCode.PROFILE_FAILED, str(exc)) from exc
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise MotionError(ErrorCode.PROFILE_FAILED, f"ruckig result {result}")
        self.duration = float(self._traj.duration)
        self.target_position = position

    def at(self, s: float) -> tuple[float, float]:
        """Position and ratio after master travel ``s``."""
        if self.target_position is not None and s >= self.duration:
            return self.target_position, 0.0
        p, v, _ = self._traj.at_time(max(s, 0.0))
        return float(p[0]), float(v[0])


class MasterDrivenProcess(Process):
    """A jog or move whose profile advances with the forward travel of its master."""

    def __init__(
        self,
        ctl: Controller,
        master: Axis,
        reference: MasterReference,
        limits: Limits,
        ratio: float,
        owner: Any = None,
    ) -> None:
        super().__init__(owner)
        self.master = master.number
        self.masters = (master.number,)
        self.reference = reference
        self.limits = limits.validated()
        #: master travel (forward) since the process started
        self.travel = 0.0
        self.ratio = ratio
        #: the slave follows the master at the programmed ratio (TrackingMaster)
        self.tracking = False
        self._master = master
        self._last_master = master_position(ctl, master, reference)
        self._origin = 0.0  # position at the last (re)plan
        self._plan_travel = 0.0  # travel at the last (re)plan
        self.profile = self._plan(ratio)
        self._sample()
        self.velocity = self.ratio * master_speed(ctl, master, reference)

    # -- planning -------------------------------------------------------------------------
    def _plan(self, ratio: float) -> MasterProfile:
        raise NotImplementedError

    @property
    def target_ratio(self) -> float:
        raise NotImplementedError

    def _sample(self) -> None:
        p, u = self.profile.at(self.travel - self._plan_travel)
        self.position = self._origin + p
        self.ratio = u
        tol = 1e-9 * max(1.0, abs(self.target_ratio))
        if abs(u - self.target_ratio) <= tol:
            self.tracking = True

    def _replan(self) -> None:
        self._origin = self.position
        self._plan_travel = self.travel
        self.profile = self._plan(self.ratio)
        self.tracking = False
        self._sample()

    # -- stepping -------------------------------------------------------------------------
    def step(self, ctl: Controller, dt: float) -> None:
        m = master_position(ctl, self._master, self.reference)
        ds = max(m - self._last_master, 0.0)
        self._last_master = m
        self.travel += ds
        before = self.velocity
        self._sample()
        self.velocity = self.ratio * ds / dt
        self.acceleration = (self.velocity - before) / dt
        self._after_sample()

    def _after_sample(self) -> None:
        pass

    def change_limits(self, limits: Limits) -> None:
        """Motion Change Dynamics: re-plan from here with new limits (master units)."""
        self.limits = limits.validated()
        self._replan()


class MasterDrivenJog(MasterDrivenProcess):
    """MAJ in master units: run at ``speed`` units per master unit until stopped."""

    kind = ProcessKind.JOG

    def __init__(
        self,
        ctl: Controller,
        master: Axis,
        reference: MasterReference,
        speed: float,
        limits: Limits,
        ratio: float = 0.0,
        owner: Any = None,
    ) -> None:
        self.speed = speed
        super().__init__(ctl, master, reference, limits, ratio, owner)

    @property
    def target_ratio(self) -> float:
        return self.speed

    def _plan(self, ratio: float) -> MasterProfile:
        return MasterProfile(self.limits, ratio, velocity=self.speed, position=None)

    def change_speed(self, speed: float) -> None:
        sign = -1.0 if self.speed < 0 else 1.0
        self.speed = sign * abs(speed)
        self._replan()

    @property
    def reached(self) -> bool:
        return self.tracking or super().reached


class MasterDrivenMove(MasterDrivenProcess):
    """MAM in master units: travel ``distance`` and rest there when the master has moved
    far enough."""

    kind = ProcessKind.MOVE

    def __init__(
        self,
        ctl: Controller,
        master: Axis,
        reference: MasterReference,
        distance: float,
        limits: Limits,
        ratio: float = 0.0,
        owner: Any = None,
    ) -> None:
        self.distance = distance
        super().__init__(ctl, master, reference, limits, ratio, owner)

    @property
    def target_ratio(self) -> float:
        return math.copysign(self.limits.velocity, self.distance - self._origin)

    def _plan(self, ratio: float) -> MasterProfile:
        return MasterProfile(
            self.limits, ratio, velocity=None, position=self.distance - self._origin
        )

    def _after_sample(self) -> None:
        if self.travel - self._plan_travel >= self.profile.duration:
            self.position = self.distance
            self.velocity = 0.0
            self.finish()

    def change_speed(self, speed: float) -> None:
        self.limits = Limits(
            abs(speed), self.limits.acceleration, self.limits.deceleration, self.limits.jerk
        )
        self._replan()


#: builds a master-driven process from (link, master axis, inherited ratio)
MasterFactory = Callable[[MasterLink, "Axis", float], Process]


class MasterDrivenControl:
    """The MDAC assignments of a controller: the current link per slave and motion type,
    and the pending reassignment per slave."""

    def __init__(self, ctl: Controller) -> None:
        self._ctl = ctl
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
        for ax in (slave, master):
            if ax.state == AxisState.AXIS_SHUTDOWN:
                raise MotionError(ErrorCode.SHUTDOWN_STATE, f"{ax.name} is shut down")
            if ax.state == AxisState.AXIS_FAULTED:
                raise MotionError(ErrorCode.AXIS_FAULTED, f"{ax.name} is faulted")
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
                ax = self._ctl.axis(a)
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
        """Start a time-driven process; a pending reassignment covering it switches now."""
        motion = KIND_TYPE[kind]
        pend = self._pending.get(slave.number)
        p = self._ctl.start(slave, make, replace=replace)
        if pend is not None and covers(pend.motion_type, motion):
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
        ctl = self._ctl
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
        master = ctl.axis(link.master)
        if master.state in (AxisState.AXIS_SHUTDOWN, AxisState.AXIS_FAULTED):
            raise MotionError(
                ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE,
                f"master {master.name} is {master.state.name.lower()}",
            )
        v_m = master_speed(ctl, master, link.reference)
        replaced = [
            p for p in slave.processes if p.active and (replace is None or p.kind in replace)
        ]
        same_master = [
            p for p in replaced if isinstance(p, MasterDrivenProcess) and p.master == link.master
        ]
        others = [p for p in replaced if p not in same_master]
        v_slave = abs(slave.command_velocity)
        change = pend is not None or any(p.velocity != 0.0 for p in others)
        if change and v_slave > MOVING_EPSILON:
            if v_m <= MOVING_EPSILON:
                raise MotionError(
                    ErrorCode.MDSC_IDLE_MASTER_AND_SLAVE_MOVING,
                    f"master {master.name} is idle while {slave.name} moves",
                )
            if abs(speed) * v_m < MIN_SPEED_SHARE * v_slave:
                raise MotionError(
                    ErrorCode.MDSC_INVALID_SLAVE_SPEED_REDUCTION,
                    f"{slave.name} would slow to {abs(speed) * v_m:g} from {v_slave:g} units/s "
                    f"(under {MIN_SPEED_SHARE:.0%})",
                )
        # the inherited state in the master domain: ratios of same-master processes add,
        # other velocities are divided by the master speed
        ratio = sum(p.ratio for p in same_master if isinstance(p, MasterDrivenProcess))
        if v_m > MOVING_EPSILON:
            ratio += sum(p.velocity for p in others) / v_m

        def factory(v: float, a: float) -> Process:
            return make(link, master, ratio)

        p = ctl.start(slave, factory, replace=replace)
        if pend is not None:
            self._switch(pend)
        link.processes.append(p)
        return p

    def _switch(self, link: MasterLink) -> None:
        """The pending reassignment takes over: the links it covers are released (their
        running processes keep the master they started with)."""
        self._pending.pop(link.slave, None)
        links = self._links.get(link.slave, [])
        replaced = [lk for lk in links if overlap(lk.motion_type, link.motion_type)]
        for lk in replaced:
            lk.release(AbortReason.SUPERSEDED)
        link.state = LinkState.ENABLED
        self._links[link.slave] = [*(lk for lk in links if lk not in replaced), link]

    # -- breaking links ---------------------------------------------------------------------
    def break_slave(self, slave: Axis, reason: AbortReason, hold_active: bool = False) -> None:
        """Break every link (and the pending one) where ``slave`` is the slave."""
        for lk in self._links.pop(slave.number, []):
            self._release(lk, reason, slave if hold_active else None)
        pend = self._pending.pop(slave.number, None)
        if pend is not None:
            pend.release(reason)

    def break_master(self, master: Axis, reason: AbortReason, hold_active: bool = False) -> None:
        """Break every link (and pending one) whose master is ``master``."""
        for slave, links in list(self._links.items()):
            keep = []
            for lk in links:
                if lk.master == master.number:
                    held = self._ctl.axis(slave) if hold_active else None
                    self._release(lk, reason, held)
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
        for ax in self._ctl.axes:
            self.break_slave(ax, reason)

    @staticmethod
    def _release(link: MasterLink, reason: AbortReason, held: Axis | None) -> None:
        link.release(reason)
        if held is not None and link.active:
            link.hold_active = lambda: held.moving

    def update(self) -> None:
        """Once per controller step: a fault on a slave or a master breaks its links."""
        for ax in self._ctl.axes:
            if ax.state == AxisState.AXIS_FAULTED and (
                ax.number in self._links or self._is_master(ax.number)
            ):
                self.break_axis(ax, AbortReason.FAULTED)

    def _is_master(self, number: int) -> bool:
        if any(lk.master == number for links in self._links.values() for lk in links):
            return True
        return any(p.master == number for p in self._pending.values())


__all__ = [
    "LinkState",
    "MasterDrivenControl",
    "MasterDrivenJog",
    "MasterDrivenMove",
    "MasterDrivenProcess",
    "MasterLink",
    "MasterProfile",
    "MasterReference",
    "MotionType",
    "master_position",
    "master_speed",
]
