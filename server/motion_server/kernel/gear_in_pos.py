"""MC_GearInPos: gearing that locks on at given master and slave sync positions.

The master's travel direction is the sign of RatioDenominator, the slave's the sign of
RatioNumerator; the ratio is numerator / denominator (signed). The slave follows the
master's **actual** position (the seed: SlaveCommandPosition = MasterActualPosition x
RatioNumerator / RatioDenominator).

Phases (``sync_state``): WAITING until the master reaches MasterStartDistance before
MasterSyncPosition (the slave keeps the velocity it had, usually rest); SYNCHRONIZING:
the lock-on, planned in the master-position domain as a quintic slave(m) from the last
waiting sample to the sync point, with slope (ds/dm) = slave velocity / master velocity at
the start and = ratio at the end, curvature 0 at both ends; IN_SYNC: slave = slave sync
position + ratio x (master - master sync position). Because the slave is a function of
the master's position, it arrives at SlaveSyncPosition with velocity ratio x master
velocity exactly when the master reaches MasterSyncPosition, whatever the master's speed
does meanwhile.

SyncMode immediate with the master at or past its start point (MasterStartDistance
before MasterSyncPosition) or the slave at or beyond SlaveSyncPosition when the block
starts: no waiting and no lock-on. The seed: "If either the master or slave axis are
beyond their respective sync start positions, the slave axis will immediately
synchronize to the master axis [...] If the slave axis is ahead of the master axis at the
time of synchronization, the slave axis will move backwards." The process is IN_SYNC in
its first step: the slave's command is placed on SlaveSyncPosition + ratio x (master -
MasterSyncPosition) and follows it from there (the drive moves the axis there, backwards
when the slave was ahead), with Warning set (the seed: "slave axis acceleration may be
excessive").

:func:`plan_sync` judges the inputs as the seed's SyncMode rules say (ErrorID 13 when
they are inconsistent) and picks the next occurrence of a sync position on rotary axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import IntEnum
from typing import Any

from .axis import Axis
from .enums import MasterReference, ProcessKind
from .errors import ErrorCode, MotionError
from .gearing import remember_direction
from .processes import Process
from .state import StepContext

#: sync positions and distances beyond this magnitude are refused (ErrorID 13)
POSITION_LIMIT = 1e12


class SyncMode(IntEnum):
    NORMAL = 0
    IMMEDIATE = 1


class SyncState(IntEnum):
    """Published as ``SyncState``: waiting 0, synchronizing (lock-on) 1, in sync 2."""

    WAITING = 0
    SYNCHRONIZING = 1
    IN_SYNC = 2


def _inconsistent(message: str) -> MotionError:
    return MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"inconsistent inputs: {message}")


def next_occurrence(position: float, reference: float, direction: int, rollover: float) -> float:
    """The first unwound position congruent to ``position`` (mod ``rollover``) strictly
    beyond ``reference`` in ``direction``."""
    if direction > 0:
        k = math.floor((reference - position) / rollover) + 1
    else:
        k = math.ceil((reference - position) / rollover) - 1
    return position + k * rollover


@dataclass(frozen=True)
class SyncPlan:
    """Unwound sync geometry of one MC_GearInPos execution."""

    master_sync: float
    slave_sync: float
    #: master position where the lock-on begins (StartSync)
    start: float
    start_distance: float
    #: master travel direction (sign of RatioDenominator)
    direction: int
    numerator: int
    denominator: int
    #: the seed's warning rule: MasterStartDistance x |ratio| < the slave sync distance
    excessive: bool
    #: SyncMode immediate with the master at or past its start point, or the slave at or
    #: beyond its sync position: in sync at once (the slave moves back if ahead)
    immediate: bool = False

    @property
    def ratio(self) -> float:
        return self.numerator / self.denominator


def plan_sync(
    master: Axis,
    slave: Axis,
    numerator: int,
    denominator: int,
    master_sync: float,
    slave_sync: float,
    mode: SyncMode,
    start_distance: float,
    dt: float,
) -> SyncPlan:
    """Judge the inputs against the current positions (master actual, slave command)."""
    if numerator == 0 or denominator == 0:
        raise _inconsistent("RatioNumerator and RatioDenominator must be non-zero")
    if not all(abs(x) <= POSITION_LIMIT for x in (master_sync, slave_sync, start_distance)):
        raise _inconsistent(f"positions and distances must be finite and within {POSITION_LIMIT:g}")
    d = 1 if denominator > 0 else -1
    ds = 1 if numerator > 0 else -1
    m0 = master.actual_position_unwound
    s0 = slave.command_position_unwound
    rm, rs = master.config.rollover, slave.config.rollover
    if mode == SyncMode.IMMEDIATE:
        if rm > 0.0 or rs > 0.0:
            raise _inconsistent("SyncMode 1 needs master and slave with rollover 0")
        if start_distance < 0.0:
            raise _inconsistent("MasterStartDistance must be >= 0")
    else:
        if start_distance <= 0.0:
            raise _inconsistent("MasterStartDistance must be positive")
        if start_distance <= abs(master.actual_velocity) * dt:
            raise _inconsistent(
                f"MasterStartDistance {start_distance} must exceed the master's travel per "
                f"update ({abs(master.actual_velocity) * dt})"
            )
    if rm > 0.0:
        if not 0.0 <= master_sync < rm:
            raise _inconsistent(f"MasterSyncPosition must be in [0, {rm})")
        m_sync = next_occurrence(master_sync, m0 + d * start_distance, d, rm)
    else:
        m_sync = master_sync
        if mode == SyncMode.NORMAL and d * (m_sync - m0) <= start_distance:
            raise _inconsistent(
                "the master must be before MasterSyncPosition by more than MasterStartDistance"
            )
    if rs > 0.0:
        if not 0.0 <= slave_sync < rs:
            raise _inconsistent(f"SlaveSyncPosition must be in [0, {rs})")
        s_sync = next_occurrence(slave_sync, s0, ds, rs)
    else:
        s_sync = slave_sync
        if mode == SyncMode.NORMAL and ds * (s_sync - s0) <= 0.0:
            raise _inconsistent("the slave must be before SlaveSyncPosition")
    excessive = abs(s_sync - s0) > start_distance * abs(numerator / denominator)
    slave_beyond = ds * (s_sync - s0) <= 0.0
    master_beyond = d * (m0 - (m_sync - d * start_distance)) >= 0.0
    immediate = mode == SyncMode.IMMEDIATE and (slave_beyond or master_beyond)
    return SyncPlan(
        m_sync,
        s_sync,
        m_sync - d * start_distance,
        start_distance,
        d,
        int(numerator),
        int(denominator),
        excessive,
        immediate,
    )


class Quintic:
    """q(u) on u in [0, 1] with q(0) = 0 and given q'(0), q''(0), q(1), q'(1), q''(1)."""

    __slots__ = ("c1", "c2", "c3", "c4", "c5")

    def __init__(self, v0: float, a0: float, p1: float, v1: float, a1: float) -> None:
        self.c1 = v0
        self.c2 = 0.5 * a0
        self.c3 = 10.0 * p1 - 6.0 * v0 - 1.5 * a0 - 4.0 * v1 + 0.5 * a1
        self.c4 = -15.0 * p1 + 8.0 * v0 + 1.5 * a0 + 7.0 * v1 - a1
        self.c5 = 6.0 * p1 - 3.0 * v0 - 0.5 * a0 - 3.0 * v1 + 0.5 * a1

    def __call__(self, u: float) -> tuple[float, float, float]:
        """q(u), q'(u), q''(u)."""
        c1, c2, c3, c4, c5 = self.c1, self.c2, self.c3, self.c4, self.c5
        q = u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))))
        q1 = c1 + u * (2.0 * c2 + u * (3.0 * c3 + u * (4.0 * c4 + 5.0 * c5 * u)))
        q2 = 2.0 * c2 + u * (6.0 * c3 + u * (12.0 * c4 + 20.0 * c5 * u))
        return q, q1, q2

    def peak_curvature(self) -> float:
        """max |q''(u)| on [0, 1] (q'' is a cubic: its ends and the roots of q''')."""
        candidates = [0.0, 1.0]
        a, b, c = 60.0 * self.c5, 24.0 * self.c4, 6.0 * self.c3
        if a != 0.0:
            disc = b * b - 4.0 * a * c
            if disc >= 0.0:
                r = math.sqrt(disc)
                candidates += [(-b - r) / (2.0 * a), (-b + r) / (2.0 * a)]
        elif b != 0.0:
            candidates.append(-c / b)
        return max(abs(self(u)[2]) for u in candidates if 0.0 <= u <= 1.0)


class GearInPosProcess(Process):
    """The MC_GearInPos motion on the slave (see the module docstring)."""

    kind = ProcessKind.GEAR

    def __init__(
        self,
        ctx: StepContext,
        slave: Axis,
        master: Axis,
        numerator: int,
        denominator: int,
        master_sync: float,
        slave_sync: float,
        mode: SyncMode,
        start_distance: float,
        velocity: float = 0.0,
        acceleration: float = 0.0,
        owner: Any = None,
    ) -> None:
        super().__init__(owner)
        self.sync_state = SyncState.WAITING
        self.locked = False
        #: the lock-on has begun (stays set once in sync)
        self.start_sync = False
        #: excessive lock-on acceleration expected or happened (the seed's warning)
        self.warning = False
        self.direction = 1 if numerator * denominator > 0 else -1
        self._slave = slave
        self._mi = master.index
        self._pos, self._vel, _ = ctx.master_arrays(MasterReference.ACTUAL)
        self._m_prev = float(self._pos[self._mi])
        self._v_prev = float(self._vel[self._mi])
        self._hold = float(velocity)
        self._hold_cycles = 0
        self.velocity = self._hold
        self._m_a = self._p_a = self._L = self._p_sync = 0.0
        self._quintic: Quintic | None = None
        # judged against the positions when the process starts (a buffered start comes
        # later): inconsistent inputs raise, and the kernel keeps the motion it would
        # have replaced
        self.plan: SyncPlan | None = plan_sync(
            master,
            slave,
            numerator,
            denominator,
            master_sync,
            slave_sync,
            mode,
            start_distance,
            slave.period,
        )
        self.masters = (master.number,)
        self.warning = self.plan.excessive
        remember_direction(slave, self.direction)

    @property
    def reached(self) -> bool:
        return self.locked or super().reached

    @property
    def remaining_master_distance(self) -> float:
        """Master travel left to MasterSyncPosition (0 once in sync)."""
        if self.plan is None or self.sync_state == SyncState.IN_SYNC:
            return 0.0
        return self.plan.direction * (self.plan.master_sync - self._m_prev)

    def shifted(self, d: float) -> None:
        super().shifted(d)
        if self.plan is not None:
            self.plan = replace(self.plan, slave_sync=self.plan.slave_sync + d)

    def master_shifted(self, index: int, d: float) -> None:
        if index != self._mi:
            return
        if self.plan is not None:
            plan = self.plan
            self.plan = replace(plan, master_sync=plan.master_sync + d, start=plan.start + d)
        self._m_prev += d
        self._m_a += d

    def _sync_offset(self) -> float:
        """What the slave's base and its other processes add to this one's position."""
        slave = self._slave
        return slave.base + sum(p.position for p in slave.processes if p is not self and p.active)

    def _begin_lock_on(self) -> None:
        """Plan slave(m) from the last waiting sample to the sync point."""
        plan = self.plan
        assert plan is not None
        slave = self._slave
        self.sync_state = SyncState.SYNCHRONIZING
        self.start_sync = True
        self._p_sync = plan.slave_sync - self._sync_offset()
        self._m_a, self._p_a = self._m_prev, self.position
        length = plan.master_sync - self._m_a
        if plan.direction * length <= 0.0:
            # nothing left to lock on over: synchronise at once (a jump, warned)
            self._L = 0.0
            self.warning = True
            return
        self._L = length
        vm = self._v_prev
        slope0 = self._hold / vm if abs(vm) > 1e-12 else 0.0
        delta = self._p_sync - self._p_a
        q = Quintic(slope0 * length, 0.0, delta, plan.ratio * length, 0.0)
        self._quintic = q
        peak = q.peak_curvature() / (length * length) * vm * vm
        if abs(delta) > plan.start_distance * abs(plan.ratio):
            self.warning = True
        if peak > slave.config.max_acceleration:
            self.warning = True

    def step(self, ctx: StepContext, dt: float) -> None:
        plan = self.plan
        assert plan is not None
        m = float(self._pos[self._mi])
        vm = float(self._vel[self._mi])
        am = (vm - self._v_prev) / dt
        if self.sync_state == SyncState.WAITING and plan.immediate:
            # immediate synchronisation: placed on the geared position at once
            self.start_sync = True
            self.warning = True
            self._p_sync = plan.slave_sync - self._sync_offset()
            self.sync_state = SyncState.IN_SYNC
            self.locked = True
            self.status_changed = True  # GearingLockStatus
        elif self.sync_state == SyncState.WAITING:
            if plan.direction * (m - plan.start) < 0.0:
                self._hold_cycles += 1
                self.position = self._hold * (self._hold_cycles * dt)
                self.velocity = self._hold
                self.acceleration = 0.0
                self._m_prev, self._v_prev = m, vm
                return
            self._begin_lock_on()
        if self.sync_state == SyncState.SYNCHRONIZING:
            q = self._quintic
            length = self._L
            u = (m - self._m_a) / length if q is not None else 1.0
            if u < 1.0 and q is not None:
                u = max(u, 0.0)
                s, s1, s2 = q(u)
                self.position = self._p_a + s
                self.velocity = s1 / length * vm
                self.acceleration = s2 / (length * length) * vm * vm + s1 / length * am
                self._m_prev, self._v_prev = m, vm
                return
            self.sync_state = SyncState.IN_SYNC
            self.locked = True
            self.status_changed = True  # GearingLockStatus
        self.position = self._p_sync + (m - plan.master_sync) * plan.numerator / plan.denominator
        self.velocity = plan.ratio * vm
        self.acceleration = plan.ratio * am
        self._m_prev, self._v_prev = m, vm
