"""Electronic camming: the cam process behind MAPC, MATC and MC_CamIn.

A :class:`CamProcess` moves its slave along a :class:`~.cam_profile.CamProfile` f as a
function of a *cam coordinate* x, which advances with a master's position (a position
cam) or with time (a time cam):

    x = CamLock + (m - m_lock) / MasterScaling        (position cam, m the master's
                                                        unwound position)
    x = CamLock + (t - t_lock) / TimeScaling           (time cam, t = cycles x period)
    displacement = origin + scale x (F(x) - f(CamLock))

``scale`` is the signed slave scaling (Direction x SlaveScaling), ``origin`` the
displacement at the lock (0 for Logix's incremental cams). Like a locked gear, x is
computed from the absolute master displacement since the lock, never from a running sum,
so nothing drifts. What happens when x leaves the profile's range [start, end] is the
execution mode (:class:`CamMode`):

- **Once**: the cam completes; the slave stays at f(end) (or f(start) when the master ran
  backwards out of the range) and the process is done.
- **Continuous** (PLCopen periodic): the profile repeats; every pass adds f(end) -
  f(start) to the slave: F(x) = f(x - k L) + k (f(end) - f(start)), k = floor((x - start)
  / L).
- **Persistent** (PLCopen non-periodic): outside the range the slave holds at the end
  value (F(x) = f(clamped x)), unlocked; when the master comes back into the range the cam
  drives the slave again.

A cam may wait for its master to pass a lock position first (:class:`LockDirection`, the
Logix Forward only / Reverse only / Bi-directional schedules, valid in any turn of a
rotary master), and may follow one master direction only (:class:`MasterDirection`, the
slip clutch: the master's travel counts only while it goes beyond the furthest point it
reached in the allowed direction, so that the slave stays where it was while the master
goes back and resumes in phase once the master has returned).

A cam may have a *successor* (the Logix Pending schedule): it takes over, seamlessly, when
this cam completes (Once) or passes the end or the start of its profile (Continuous),
locked at the master position (or time) of that boundary, on the same master.

``passes`` counts the times the profile's end (or its start, running backwards) was
reached: PLCopen EndOfProfile pulses on each change.

A cam may *ramp in* over the cam coordinates [x_start, x_sync) (PLCopen MC_CamIn's
MasterStartDistance before MasterSyncPosition): the slave stays where it is until x_start,
then follows a quintic in x from its position at rest to the cam's position, slope and
curvature at x_sync, where it is in sync; planned in the master's domain (as MC_GearInPos
locks on), so a master that changes speed meanwhile does not spoil it.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Any

from .cam_profile import CamProfile
from .enums import AbortReason, MasterReference, ProcessKind, ProcessState
from .errors import ErrorCode, MotionError
from .gear_in_pos import Quintic
from .processes import Process
from .state import StepContext

# read every cycle, as module constants (see .enums)
_ACTIVE = ProcessState.ACTIVE


class CamMode(IntEnum):
    """Logix Execution Mode (once 0, continuous 1, persistent 2)."""

    ONCE = 0
    CONTINUOUS = 1
    PERSISTENT = 2


class LockDirection(IntEnum):
    """When a cam locks: at once, or when the master passes the master lock position
    forward, in reverse, or either way (the Logix Execution Schedule without Pending)."""

    IMMEDIATE = 0
    FORWARD = 1
    REVERSE = 2
    BIDIRECTIONAL = 3


class MasterDirection(IntEnum):
    """Logix Master Direction: which master travel drives the slave (0 both)."""

    BIDIRECTIONAL = 0
    FORWARD_ONLY = 1
    REVERSE_ONLY = 2


class CamPhase(IntEnum):
    WAITING = 0  # for the master to pass the master lock position
    LOCKED = 1


_IMMEDIATE = LockDirection.IMMEDIATE
_LOCKED = CamPhase.LOCKED


#: largest |scaling| accepted (PLCopen vendors refuse beyond +-2^31, Beckhoff 44037/38)
MAX_SCALING = 2.0**31


class CamProcess(Process):
    """One cam on a slave (see the module docstring).

    ``master`` is the master's array index and ``source`` its reference (None: a time
    cam). ``master_scaling`` is master units (or seconds) per cam unit. ``master_lock``
    and ``lock`` give the lock condition; ``rollover`` is the master's (0: linear).
    """

    # The state a new cam starts with, as class defaults: an instance stores what its
    # start or its steps change (many cams start in one scan; every store costs).
    phase: CamPhase = CamPhase.WAITING
    #: the master position (or time) of the lock, the furthest point reached (slip
    #: clutch), the master position and velocity of the previous cycle
    m0 = 0.0
    m_eff = 0.0
    m_prev = 0.0
    v_prev = 0.0
    #: cycles since the time cam's clock started (a time cam's t = cycles x dt)
    cycles = 0
    #: the period index of the last step (the cam coordinate ``x`` is the instance's)
    k = 0
    #: inside the profile's range (Persistent: False while it holds at an end)
    in_range = True
    #: master moving the way that drives the slave (slip clutch)
    engaged = True
    passes = 0
    successor: CamProcess | None = None
    #: the ramp-in (x_start, x_sync) still ahead and its plan
    ramp: tuple[float, float] | None = None
    blend: Quintic | None = None

    def __init__(
        self,
        ctx: StepContext,
        profile: CamProfile,
        mode: CamMode,
        scale: float,
        master_scaling: float,
        cam_lock: float,
        *,
        master: int | None = None,
        source: MasterReference = MasterReference.COMMAND,
        master_number: int = 0,
        lock: LockDirection = LockDirection.IMMEDIATE,
        master_lock: float = 0.0,
        rollover: float = 0.0,
        direction: MasterDirection = MasterDirection.BIDIRECTIONAL,
        origin: float = 0.0,
        ramp_in: tuple[float, float] | None = None,
        kind: ProcessKind | None = None,
        owner: Any = None,
    ) -> None:
        super().__init__(owner)
        # (many cams start in one scan: the enumerations are converted only when given as
        # plain integers, the profile's range read once)
        p_start: float = profile._start  # type: ignore[attr-defined]
        p_end: float = profile._end  # type: ignore[attr-defined]
        if not p_start <= cam_lock <= p_end:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"cam lock position {cam_lock:g} is outside the profile's master range "
                f"[{p_start:g}, {p_end:g}]",
            )
        if kind is None:
            kind = ProcessKind.POSITION_CAM if master is not None else ProcessKind.TIME_CAM
        #: a time cam may run on a master's travel (MATC master driven through MDAC)
        self.kind = kind
        self.profile = profile
        self.mode = mode if type(mode) is CamMode else CamMode(mode)
        self.scale = float(scale)
        self.master_scaling = float(master_scaling)
        self.cam_lock = cam_lock = float(cam_lock)
        self.f0 = profile.value(cam_lock)
        self.origin = float(origin)
        self.index = master
        self.masters = (master_number,) if master is not None else ()
        self.source = source
        self.lock_direction = lock if type(lock) is LockDirection else LockDirection(lock)
        self.master_lock = float(master_lock)
        self.rollover = float(rollover)
        self.master_direction = (
            direction if type(direction) is MasterDirection else MasterDirection(direction)
        )
        #: the cam coordinate of the last step
        self.x = cam_lock
        if ramp_in is not None:
            self.ramp = ramp_in
            x_start, x_sync = ramp_in
            span = x_sync - x_start
            if not span > 0.0:
                raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "empty ramp-in")
            f, f1, f2 = self._accumulated(x_sync)
            target = self.origin + self.scale * (f - self.f0)
            self.blend = Quintic(
                0.0, 0.0, target, self.scale * f1 * span, self.scale * f2 * span * span
            )
        m = 0.0
        if master is not None:
            pos, vel, _ = ctx.master_arrays(source)
            m = pos.item(master)
            self.v_prev = vel.item(master)
        self.m_prev = m
        if self.lock_direction is _IMMEDIATE:
            # _lock(m), without the call and the stores of what a new cam already holds
            self.phase = _LOCKED
            self.m0 = self.m_eff = m
            self.k = math.floor((cam_lock - p_start) / profile._length)  # type: ignore[attr-defined]
            self.status_changed = True

    @property
    def locked(self) -> bool:
        """PositionCamLockStatus / TimeCamLockStatus (PLCopen InSync): locked, ramped
        in, inside the range and driven by the master."""
        return (
            self.phase == CamPhase.LOCKED and self.in_range and self.engaged and self.ramp is None
        )

    def _accumulated(self, x: float) -> tuple[float, float, float]:
        """F(x), F'(x), F''(x) with a Continuous cam's passes added."""
        prof = self.profile
        if self.mode == CamMode.CONTINUOUS:
            k = math.floor((x - prof.start) / prof.length)
            f, f1, f2 = prof.evaluate(x - k * prof.length)
            return f + k * prof.rise, f1, f2
        return prof.evaluate(x)

    def _lock(self, m0: float) -> None:
        self.phase = CamPhase.LOCKED
        self.m0 = m0
        self.m_eff = m0
        self.x = cam_lock = self.cam_lock
        prof = self.profile
        self.k = math.floor((cam_lock - prof._start) / prof._length)  # type: ignore[attr-defined]
        self.offer_pending = True
        self.status_changed = True

    def follow(self, predecessor: CamProcess, m_boundary: float) -> None:
        """Take over from ``predecessor`` (Pending) at its boundary ``m_boundary``: same
        master and reference, locked there; the clock of a time cam goes on."""
        self.index = predecessor.index
        self.masters = predecessor.masters
        self.source = predecessor.source
        self.cycles = predecessor.cycles
        self.v_prev = predecessor.v_prev
        self.lock_direction = LockDirection.IMMEDIATE
        self._lock(m_boundary)
        self.status_changed = True

    # -- stepping -------------------------------------------------------------------------
    def step(self, ctx: StepContext, dt: float) -> None:
        if self.index is None:
            self.cycles += 1
            m = self.cycles * dt
            v_m = 1.0
            a_m = 0.0
        else:
            pos, vel, acc = ctx.master_arrays(self.source)
            i = self.index
            m = pos.item(i)
            v_m = vel.item(i)
            if acc is not None:
                a_m = acc.item(i)
            else:
                a_m = (v_m - self.v_prev) / dt
            self.v_prev = v_m
        if self.phase == CamPhase.WAITING:
            crossed = self._crossing(self.m_prev, m)
            self.m_prev = m
            if crossed is None:
                self.position = self.origin
                self.velocity = 0.0
                self.acceleration = 0.0
                return
            self._lock(crossed)
        self.m_prev = m
        self._locked_step(m, v_m, a_m)

    def _crossing(self, m1: float, m2: float) -> float | None:
        """The master lock position passed going from ``m1`` to ``m2`` in an allowed
        direction (on a rotary master: in any turn), or None."""
        lock = self.lock_direction
        target = self.master_lock
        r = self.rollover
        if lock in (LockDirection.FORWARD, LockDirection.BIDIRECTIONAL) and m2 > m1:
            if r > 0.0:
                j1 = math.floor((m1 - target) / r)
                j2 = math.floor((m2 - target) / r)
                if j2 > j1:
                    return target + j2 * r
            elif m1 < target <= m2:
                return target
        if lock in (LockDirection.REVERSE, LockDirection.BIDIRECTIONAL) and m2 < m1:
            if r > 0.0:
                j1 = math.ceil((m1 - target) / r)
                j2 = math.ceil((m2 - target) / r)
                if j2 < j1:
                    return target + j2 * r
            elif m2 <= target < m1:
                return target
        return None

    def _locked_step(self, m: float, v_m: float, a_m: float) -> None:
        engaged = True
        direction = self.master_direction
        if direction == MasterDirection.FORWARD_ONLY:
            if m >= self.m_eff:
                self.m_eff = m
            else:
                engaged = False
        elif direction == MasterDirection.REVERSE_ONLY:
            if m <= self.m_eff:
                self.m_eff = m
            else:
                engaged = False
        else:
            self.m_eff = m
        if engaged != self.engaged:
            self.engaged = engaged
            self.status_changed = True
        prof = self.profile
        ms = self.master_scaling
        x = self.cam_lock + (self.m_eff - self.m0) / ms
        self.x = x
        if self.ramp is not None:
            if self._ramp_step(x, v_m, a_m):
                return
            # in sync from this cycle: the passes count from here
            self.k = math.floor((x - prof.start) / prof.length)
        mode = self.mode
        if mode == CamMode.CONTINUOUS:
            k = math.floor((x - prof.start) / prof.length)
            c = x - k * prof.length
            if k != self.k:
                self.passes += 1
                if self.successor is not None:
                    self._hand_over(prof.start + max(k, self.k) * prof.length)
                    return
                self.k = k
            f, f1, f2 = prof.evaluate(c)
            self.position = self.origin + self.scale * ((f + k * prof.rise) - self.f0)
        else:
            inside = prof.start <= x <= prof.end
            if not inside:
                edge = prof.end if x > prof.end else prof.start
                if self.in_range:
                    self.passes += 1
                if mode == CamMode.ONCE:
                    if self.successor is not None:
                        self._hand_over(edge)
                        return
                    self.position = self.origin + self.scale * (prof.value(edge) - self.f0)
                    self.velocity = 0.0
                    self.acceleration = 0.0
                    self.in_range = False
                    self.finish()
                    return
                if self.in_range:
                    self.in_range = False
                    self.status_changed = True
                self.position = self.origin + self.scale * (prof.value(edge) - self.f0)
                self.velocity = 0.0
                self.acceleration = 0.0
                return
            if not self.in_range:
                self.in_range = True
                self.status_changed = True
            f, f1, f2 = prof.evaluate(x)
            self.position = self.origin + self.scale * (f - self.f0)
        if not engaged:
            self.velocity = 0.0
            self.acceleration = 0.0
            return
        r = v_m / ms
        self.velocity = self.scale * f1 * r
        self.acceleration = self.scale * (f2 * r * r + f1 * (a_m / ms))

    def _ramp_step(self, x: float, v_m: float, a_m: float) -> bool:
        """One step of the ramp-in; False once x has reached the sync position."""
        assert self.ramp is not None and self.blend is not None
        x_start, x_sync = self.ramp
        if x >= x_sync:
            self.ramp = None
            self.blend = None
            self.status_changed = True
            self.offer_pending = True
            return False
        if x <= x_start:
            self.position = 0.0
            self.velocity = 0.0
            self.acceleration = 0.0
            return True
        span = x_sync - x_start
        q, q1, q2 = self.blend((x - x_start) / span)
        r = v_m / self.master_scaling
        self.position = q
        self.velocity = q1 / span * r
        self.acceleration = q2 / (span * span) * r * r + q1 / span * (a_m / self.master_scaling)
        return True

    @property
    def ramping(self) -> bool:
        """Between the ramp-in's start and the sync position (PLCopen Active, not InSync)."""
        ramp = self.ramp
        return ramp is not None and self.x > ramp[0]

    def _hand_over(self, x_boundary: float) -> None:
        """This cam reached the boundary ``x_boundary`` (a raw cam coordinate) with a
        successor waiting: this one stops there, the successor locks there."""
        prof = self.profile
        succ = self.successor
        assert succ is not None
        if self.mode == CamMode.CONTINUOUS:
            k = math.floor((x_boundary - prof.start) / prof.length)
            f = prof.value(x_boundary - k * prof.length) + k * prof.rise
        else:
            f = prof.value(x_boundary)
        self.position = self.origin + self.scale * (f - self.f0)
        self.velocity = 0.0
        self.acceleration = 0.0
        m_boundary = self.m0 + (x_boundary - self.cam_lock) * self.master_scaling
        succ.follow(self, m_boundary)
        if self.mode == CamMode.ONCE:
            self.finish()
        else:
            self.state = ProcessState.ABORTED
            self.abort_reason = AbortReason.SUPERSEDED

    # -- ends and coordinates ---------------------------------------------------------------
    def abort(self, reason: AbortReason) -> None:
        super().abort(reason)
        succ = self.successor
        if succ is not None and succ.state == _ACTIVE:
            succ.abort(reason)

    def fail(self, code: int) -> None:
        super().fail(code)
        succ = self.successor
        if succ is not None and succ.state == _ACTIVE:
            succ.abort(AbortReason.SUPERSEDED)

    def master_shifted(self, index: int, d: float) -> None:
        """The master's coordinates moved by ``d``: the cam goes on as before (a lock
        position not reached yet keeps the reference it was given in, as Logix's does)."""
        if self.index != index:
            return
        self.m0 += d
        self.m_eff += d
        self.m_prev += d
        if self.phase == CamPhase.WAITING:
            self.master_lock += d

    @property
    def reached(self) -> bool:
        """In sync: a buffered PLCopen successor may start."""
        return self.locked or super().reached


def active_cam(slave: Any, kind: ProcessKind = ProcessKind.POSITION_CAM) -> CamProcess | None:
    """The slave's active cam of ``kind``, if any."""
    for p in slave.processes:
        if p.active and p.kind == kind and isinstance(p, CamProcess):
            return p
    return None
