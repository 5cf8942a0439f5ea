"""Electronic gearing: the gear process behind MAG, MC_GearIn and MC_CombineAxes.

A :class:`GearProcess` moves its slave by a ratio of its masters' displacement. It has
two phases:

- **catching up** (the Logix clutch, the PLCopen catch-up): the slave's gear velocity
  ramps from what it inherited to the velocity the masters imply (ratio x master
  velocity), trapezoidal at a rate (:class:`RateRamp`) or jerk-limited (:class:`JerkRamp`,
  ruckig's velocity interface in closed form); the position is integrated from that
  velocity. When the speeds match, the gear locks.
- **locked**: slave displacement = displacement at lock + ratio x (master position -
  master position at lock), from the *absolute* master displacement since lock, never a
  running sum of increments. Fraction ratios (MAG ``RatioFormat`` fraction) are exact in
  integer feedback counts: slave counts = floor((master counts - master counts at lock) x
  SlaveCounts / MasterCounts), with Python integers.

Without a ramp (MAG clutch disabled) the gear locks at once: if the master moves, the
slave's velocity steps, as the MAG seed warns.

The master reference is read from the shared arrays while the slave composes
(``StepContext.master_arrays``, the one place that says where a master is read): the
command position is this cycle's (the controller composes masters before slaves, see
``masters``), the actual position is the feedback sampled at the start of the cycle (the
drive update runs after composition, so for a servo or virtual master it is the previous
cycle's drive output; feedback-only masters are sampled before composition). Rotary axes
gear on unwound positions: the arrays hold them.

:class:`VelocityHold` is what MC_GearOut leaves behind: the slave keeps the velocity it
had, until a stop.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, Protocol

import numpy as np

from .axis import Axis
from .enums import AxisType, MasterReference, ProcessKind
from .errors import ErrorCode, MotionError
from .processes import Process
from .profiles import Limits, SCurveProfile
from .state import StepContext

#: the master reference of a gear: the one :class:`~.enums.MasterReference` (Logix
#: numbering), under the name the gearing API has used
MasterSource = MasterReference


class GearPhase(IntEnum):
    CATCHING_UP = 0
    LOCKED = 1


def gearing_direction(slave: Axis) -> int:
    """+1 (same) or -1 (opposite): the current or previous gearing direction of ``slave``
    (+1 if it was never geared). Kept on the axis, with the rest of its state."""
    return slave.gear_direction


def remember_direction(slave: Axis, direction: int) -> None:
    slave.gear_direction = -1 if direction < 0 else 1


class CouplingGraph(Protocol):
    """What :func:`check_master` asks of the kernel: would a new link close a loop."""

    def would_cycle(self, slave: int, masters: Collection[int]) -> bool: ...


#: largest magnitude of a real gear ratio (slave units per master unit): beyond it a
#: master's displacement would overflow the slave's position
MAX_RATIO = 1e6


@dataclass(frozen=True)
class GearTerm:
    """One master of a gear: slave displacement = master displacement x numerator /
    denominator (position units). With ``counts`` the two are integers of feedback counts
    (slave counts per master counts; the conversion constants turn them into units)."""

    master: int
    source: MasterReference
    numerator: float | int
    denominator: float | int = 1
    counts: bool = False

    def validated(self) -> GearTerm:
        n, d = self.numerator, self.denominator
        if not (math.isfinite(n) and math.isfinite(d)) or d == 0 or n == 0:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"gear ratio {n}/{d}: numerator and denominator must be finite and non-zero",
            )
        if self.counts:
            if int(n) != n or int(d) != d or d < 0:
                raise MotionError(
                    ErrorCode.PARAMETER_OUT_OF_RANGE,
                    f"fraction gear ratio {n}/{d}: counts must be integers, master counts > 0",
                )
        elif not abs(n / d) <= MAX_RATIO:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"gear ratio {n}/{d} is beyond the largest ratio {MAX_RATIO:g}",
            )
        return self


def check_master(graph: CouplingGraph, slave: Axis, master: Axis, source: MasterReference) -> None:
    """The checks every gearing instruction makes on a master: a command reference needs
    a master that has a command position (ERR 8), and the coupling must not close a loop
    of master/slave links (ERR 10, also for a slave geared to itself)."""
    if source == MasterReference.COMMAND and master.type == AxisType.FEEDBACK_ONLY:
        raise MotionError(
            ErrorCode.WRONG_AXIS_TYPE,
            f"{master.name} is feedback only: gear to its actual position",
        )
    if graph.would_cycle(slave.number, (master.number,)):
        raise MotionError(
            ErrorCode.MASTER_AXIS_CONFLICT,
            f"gearing {slave.name} to {master.name} would cross-couple the axes",
        )


class _Coupling:
    """Run-time state of one :class:`GearTerm`: where to read the master, and the lock."""

    __slots__ = (
        "acc",
        "cpu_m",
        "cpu_s",
        "den",
        "exact",
        "index",
        "lock_counts",
        "lock_pos",
        "num",
        "pos",
        "ratio",
        "slave_counts",
        "v_prev",
        "vel",
    )

    def __init__(self, ctx: StepContext, slave: Axis, term: GearTerm) -> None:
        self.index = ctx.index_of(term.master)
        self.pos: np.ndarray
        self.vel: np.ndarray
        self.acc: np.ndarray | None
        self.pos, self.vel, self.acc = ctx.master_arrays(term.source)
        self.exact = term.counts
        self.cpu_m = float(ctx.conversion[self.index])
        self.cpu_s = float(slave.config.conversion_constant)
        if self.exact:
            self.num: Any = int(term.numerator)
            self.den: Any = int(term.denominator)
            self.ratio = self.num / self.den * self.cpu_m / self.cpu_s
        else:
            self.num = float(term.numerator)
            self.den = float(term.denominator)
            self.ratio = self.num / self.den
        self.lock_pos = self.pos.item(self.index)
        self.lock_counts = 0
        self.slave_counts = 0
        self.v_prev = self.vel.item(self.index)

    def lock(self) -> None:
        self.lock_pos = self.pos.item(self.index)
        self.slave_counts = 0
        if self.exact:
            try:
                self.lock_counts = round(self.lock_pos * self.cpu_m)
            except (OverflowError, ValueError):
                self.lock_counts = 0  # displacement() fails on such a master

    def shift(self, d: float) -> None:
        """The master's coordinates moved by ``d`` (its position was redefined): the
        displacement since the lock stays what it was. For a fraction ratio the lock
        moves by the counts the master's reading moved (exact for a redefinition by a
        whole number of counts; otherwise the slave may take up a count's share once)."""
        self.lock_pos += d
        if self.exact:
            m = self.pos.item(self.index)
            # (a master beyond any sensible travel: displacement() fails on it anyway)
            with contextlib.suppress(OverflowError, ValueError):
                self.lock_counts += round(m * self.cpu_m) - round((m - d) * self.cpu_m)

    def displacement(self) -> float:
        """Slave displacement since the lock, from the absolute master displacement."""
        m = self.pos.item(self.index)
        if self.exact:
            try:
                n = (round(m * self.cpu_m) - self.lock_counts) * self.num // self.den
                x: float = n / self.cpu_s
            except (OverflowError, ValueError):  # a master beyond any sensible travel
                raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "gear overflow") from None
            self.slave_counts = n
            return x
        return (m - self.lock_pos) * self.num / self.den

    def velocity(self) -> float:
        return self.ratio * self.vel.item(self.index)

    def acceleration(self, dt: float) -> float:
        v = self.vel.item(self.index)
        if self.acc is not None:
            a = self.acc.item(self.index)
        else:  # actual feedback carries no acceleration: difference its velocity
            a = (v - self.v_prev) / dt
        self.v_prev = v
        return self.ratio * a


class CatchUp:
    """A velocity ramp from the inherited velocity to the moving target the masters set.

    :meth:`step` returns True when the slave has caught up (the gear then locks);
    ``position`` is the displacement since :meth:`start`.
    """

    def __init__(self) -> None:
        self.position = 0.0
        self.velocity = 0.0
        self.acceleration = 0.0

    def start(self, velocity: float, acceleration: float) -> None:
        self.position = 0.0
        self.velocity = velocity
        self.acceleration = acceleration

    def step(self, target_v: float, target_a: float, dt: float) -> bool:
        raise NotImplementedError

    def judge(self, target_v: float) -> None:
        """Raise MotionError if the ramp from where it starts to ``target_v`` cannot be
        planned (checked when the gear is built, so a refused gear changes nothing)."""


class RateRamp(CatchUp):
    """Trapezoidal velocity profile: the velocity moves toward the target by at most
    ``accel`` x dt per cycle while speeding up, ``decel`` x dt while slowing down or
    reversing; caught up when the remaining gap fits in one cycle."""

    def __init__(self, accel: float, decel: float | None = None) -> None:
        super().__init__()
        decel = accel if decel is None else decel
        for name, value in (("acceleration", accel), ("deceleration", decel)):
            if not math.isfinite(value) or value <= 0.0:
                raise MotionError(
                    ErrorCode.PARAMETER_OUT_OF_RANGE, f"catch-up {name} must be > 0, got {value}"
                )
        self.accel = accel
        self.decel = decel

    def step(self, target_v: float, target_a: float, dt: float) -> bool:
        v0 = self.velocity
        speeding_up = abs(target_v) > abs(v0) and target_v * v0 >= 0.0
        dv = (self.accel if speeding_up else self.decel) * dt
        gap = target_v - v0
        caught = abs(gap) <= dv
        v1 = target_v if caught else v0 + math.copysign(dv, gap)
        self.position += 0.5 * (v0 + v1) * dt
        self.velocity = v1
        self.acceleration = (v1 - v0) / dt
        return caught


class JerkRamp(CatchUp):
    """Jerk-limited catch-up: ruckig's velocity interface in closed form
    (:class:`~.scurve.SCurveProfile`, re-planned when the target moves). Caught up when the
    profile reaches the target; while the target keeps moving (an accelerating master)
    also when the velocity gap fits in one cycle and the target's acceleration is within
    one cycle's jerk of the slave's."""

    def __init__(self, dt: float, accel: float, decel: float, jerk: float) -> None:
        super().__init__()
        Limits(1.0, accel, decel, jerk).validated()
        self.accel = accel
        self.decel = decel
        self.jerk = jerk
        self._dt = dt
        self._profile = SCurveProfile(dt)
        self._target: float | None = None

    def start(self, velocity: float, acceleration: float) -> None:
        super().start(velocity, acceleration)
        lim = min(self.accel, self.decel)
        a0 = max(-lim, min(lim, acceleration))
        self._profile = SCurveProfile(self._dt, velocity, a0)
        self._target = None

    def judge(self, target_v: float) -> None:
        """Plan the first step's profile on a copy (ruckig refuses limits such as a jerk
        of 1e-300 only when it plans)."""
        prof = SCurveProfile(self._dt, self._profile.velocity, self._profile.acceleration)
        big = 2.0 * max(abs(target_v), abs(prof.velocity)) + 1.0
        prof.to_velocity(target_v, Limits(big, self.accel, self.decel, self.jerk))

    def step(self, target_v: float, target_a: float, dt: float) -> bool:
        prof = self._profile
        moving = self._target is not None and target_v != self._target
        if target_v != self._target:
            big = 2.0 * max(abs(target_v), abs(prof.velocity)) + 1.0
            prof.to_velocity(target_v, Limits(big, self.accel, self.decel, self.jerk))
            self._target = target_v
        a_prev = self.acceleration
        p0 = prof.position
        prof.step()
        self.position += prof.position - p0
        self.velocity = prof.velocity
        self.acceleration = prof.acceleration
        caught = prof.finished
        if moving and not caught:
            caught = abs(target_v - self.velocity) <= min(self.accel, self.decel) * dt and (
                abs(target_a - a_prev) <= self.jerk * dt
            )
        if caught:
            self.velocity = target_v
            self.acceleration = target_a
        return caught


def catch_up(dt: float, accel: float, decel: float, jerk: float) -> CatchUp:
    """The PLCopen catch-up of MC_GearIn / MC_CombineAxes: trapezoidal when jerk is 0."""
    if jerk == 0.0 or math.isinf(jerk):
        return RateRamp(accel, decel)
    return JerkRamp(dt, accel, decel, jerk)


class GearProcess(Process):
    """Gear the slave to one master (MAG, MC_GearIn) or two (MC_CombineAxes).

    ``ramp`` None locks at once; otherwise the slave catches up from the inherited
    ``velocity`` first. ``locked`` drives GearingLockStatus and InGear / InSync.
    """

    kind = ProcessKind.GEAR

    def __init__(
        self,
        ctx: StepContext,
        slave: Axis,
        terms: Sequence[GearTerm],
        ramp: CatchUp | None = None,
        velocity: float = 0.0,
        acceleration: float = 0.0,
        owner: Any = None,
        direction: int = 1,
    ) -> None:
        super().__init__(owner)
        if not terms:
            raise ValueError("a gear needs at least one master")
        if len(terms) == 1:
            # one master (MAG, MC_GearIn): what the general case below builds, without
            # its generators (a gear started on each of many slaves in one scan)
            term = terms[0].validated()
            self.terms: tuple[GearTerm, ...] = (term,)
            self.masters = (term.master,)
            self.combined = False
            c = _Coupling(ctx, slave, term)
            self._c = [c]
            self.single: _Coupling | None = c
        else:
            self.terms = tuple(t.validated() for t in terms)
            self.masters = tuple(dict.fromkeys(t.master for t in self.terms))
            #: two or more masters (MC_CombineAxes): MC_GearOut is refused
            self.combined = True
            self._c = [_Coupling(ctx, slave, t) for t in self.terms]
            #: the coupling of a one-master gear (None for MC_CombineAxes)
            self.single = None
        self.direction = -1 if direction < 0 else 1
        self._ramp = ramp
        #: the gear's own displacement when it locked
        self.at_lock = 0.0
        self.locked = False
        if ramp is None:
            self._lock()
        else:
            ramp.start(velocity, acceleration)
            # (the sum of the couplings' velocities, from the int 0 as sum() adds them)
            target: float = 0
            for c in self._c:
                target += c.velocity()
            ramp.judge(target)
            self.velocity = velocity
            self.acceleration = acceleration
        remember_direction(slave, self.direction)  # once nothing can refuse the gear

    @property
    def phase(self) -> GearPhase:
        return GearPhase.LOCKED if self.locked else GearPhase.CATCHING_UP

    @property
    def slave_counts(self) -> int:
        """Slave feedback counts moved since the lock (fraction ratios, one master)."""
        if self.lane is not None:
            self.lane.sync(self)
        return self._c[0].slave_counts

    @property
    def ramp(self) -> CatchUp | None:
        """The catch-up ramp (None: the gear locked at once)."""
        return self._ramp

    @property
    def reached(self) -> bool:
        """In gear: a buffered successor may start."""
        return self.locked or super().reached

    def master_shifted(self, index: int, d: float) -> None:
        for c in self._c:
            if c.index == index:
                c.shift(d)

    def _lock(self) -> None:
        self.offer_pending = True
        self.at_lock = self.position
        for c in self._c:
            c.lock()
        self.locked = True
        self.status_changed = True  # GearingLockStatus

    def step(self, ctx: StepContext, dt: float) -> None:
        c1 = self.single
        if self.locked:
            if c1 is not None and not c1.exact:
                # the hot path (one master, real ratio), inlined: no allocation, no ruckig
                i = c1.index
                m = c1.pos.item(i)
                v = c1.vel.item(i)
                self.position = self.at_lock + (m - c1.lock_pos) * c1.num / c1.den
                self.velocity = c1.ratio * v
                if c1.acc is not None:
                    self.acceleration = c1.ratio * c1.acc.item(i)
                else:
                    self.acceleration = c1.ratio * (v - c1.v_prev) / dt
                c1.v_prev = v
            elif c1 is not None:
                self.position = self.at_lock + c1.displacement()
                self.velocity = c1.velocity()
                self.acceleration = c1.acceleration(dt)
            else:
                pos = self.at_lock
                vel = acc = 0.0
                for c in self._c:
                    pos += c.displacement()
                    vel += c.velocity()
                    acc += c.acceleration(dt)
                self.position, self.velocity, self.acceleration = pos, vel, acc
            return
        ramp = self._ramp
        assert ramp is not None
        target_v = sum(c.velocity() for c in self._c)
        target_a = sum(c.acceleration(dt) for c in self._c)
        caught = ramp.step(target_v, target_a, dt)
        self.position = ramp.position
        self.velocity = ramp.velocity
        self.acceleration = ramp.acceleration
        if caught:
            self._lock()


class VelocityHold(Process):
    """Constant velocity until stopped (what MC_GearOut leaves on the slave). Continuous
    motion for PLCopen; the position is velocity x elapsed time, not a running sum."""

    kind = ProcessKind.JOG

    def __init__(self, velocity: float, owner: Any = None) -> None:
        super().__init__(owner)
        self.velocity = float(velocity)
        self._cycles = 0

    def step(self, ctx: StepContext, dt: float) -> None:
        self._cycles += 1
        self.position = self.velocity * (self._cycles * dt)
        self.acceleration = 0.0

    @property
    def reached(self) -> bool:
        return True


def active_gear(slave: Axis) -> Process | None:
    """The slave's active gear process (of any gearing instruction), if any."""
    for p in slave.processes:
        if p.active and p.kind == ProcessKind.GEAR:
            return p
    return None
