"""Superimposed motion processes.

An axis's command position is its ``base`` plus the displacement of every active process
(Logix superposition: a gear, a jog, a move and a stop can run together and their
velocities add). A process that ends folds its displacement into ``base``. Instructions
keep a reference to the process they started and poll its ``state``; the kernel never
calls back into instructions.

A process steps against a :class:`~.state.StepContext` (the shared arrays), never the
controller: gears read their masters there.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

from .enums import AbortReason, ProcessKind, ProcessState
from .errors import MotionError
from .profiles import Limits, OnlineProfile, TrapezoidProfile, profile_for
from .state import StepContext
from .trapezoid import judge_ramp

# read every cycle, as module constants (see .enums)
_ACTIVE = ProcessState.ACTIVE


class Lane(Protocol):
    """A fast lane stepping processes as arrays (:mod:`.lanes`)."""

    def evict(self, p: Process) -> None: ...

    def sync(self, p: Process) -> None: ...

    def replans(self, p: Process) -> bool: ...

    def replan(self, p: Process) -> bool: ...


class Process:
    """Base: a displacement with velocity and acceleration, advanced once per cycle."""

    kind: ProcessKind = ProcessKind.MOVE
    #: axis numbers this process reads (gearing); the controller steps masters first
    masters: tuple[int, ...] = ()
    #: the fast lane stepping this process (:mod:`.lanes`); while set, ``position``,
    #: ``velocity`` and ``acceleration`` are stale until the lane evicts it
    lane: Lane | None = None
    #: the process may have entered a state a lane steps (it started, left its lane,
    #: reached its speed, locked): the kernel offers it to the lanes once, then clears it
    offer_pending: bool = True
    #: a step changed what the axis's status reads of the process (``Axis.process_bits``,
    #: ``Axis.plcopen_state``) while it stayed active: a gear locked. Composition marks
    #: the axis for the status arrays, then clears it
    status_changed: bool = False
    #: a process that takes over, seamlessly, when this one ends (a cam's Pending
    #: successor, :mod:`.cams`): composition starts it in the step this one ends
    successor: Process | None = None

    def __init__(self, owner: Any = None) -> None:
        self.owner = owner
        self.state = ProcessState.ACTIVE
        self.abort_reason = AbortReason.NONE
        self.error_code = 0
        self.position = 0.0
        self.velocity = 0.0
        self.acceleration = 0.0
        #: True for processes created by a stop (MAS, MC_Stop, MGS); StoppingStatus
        self.stopping = False
        #: absolute (unwound) command position an absolute move ends on: when it completes
        #: alone, the axis lands there exactly instead of on a rounded sum of displacements
        self.landing: float | None = None

    @property
    def active(self) -> bool:
        return self.state == _ACTIVE

    def step(self, ctx: StepContext, dt: float) -> None:
        raise NotImplementedError

    @property
    def reached(self) -> bool:
        """True once a buffered successor may start (done, at speed or in sync)."""
        return self.state == ProcessState.DONE

    def abort(self, reason: AbortReason) -> None:
        if self.lane is not None:
            self.lane.evict(self)
        if self.state == ProcessState.ACTIVE:
            self.state = ProcessState.ABORTED
            self.abort_reason = reason

    def finish(self) -> None:
        if self.state == ProcessState.ACTIVE:
            self.state = ProcessState.DONE

    def fail(self, code: int) -> None:
        """The process cannot go on: ERROR with ``code`` (the kernel ramps its velocity
        down)."""
        if self.lane is not None:
            self.lane.evict(self)
        self.state = ProcessState.ERROR
        self.error_code = int(code)

    # -- redefinitions (:mod:`.redefine`): a shift of coordinates moves nothing ----------
    def shifted(self, d: float) -> None:
        """The coordinates of the process's own axis moved by ``d`` (a redefined
        position): the absolute positions it holds follow, so that it moves the load
        exactly as before. (Displacements are relative to the axis's ``base``, which
        the redefinition moves.)"""
        if self.landing is not None:
            self.landing += d

    def master_shifted(self, index: int, d: float) -> None:
        """The coordinates of the master at array index ``index`` moved by ``d``
        (called after the arrays moved): what the process holds of that master's
        position follows. Processes without masters ignore it."""


#: builds a process from the velocity and acceleration of what it replaces
ProcessFactory = Callable[[float, float], Process]


class Pending:
    """A buffered command: started by the kernel once the axis's active motion is done."""

    def __init__(self, make: ProcessFactory, owner: object = None) -> None:
        self.make = make
        self.owner = owner
        self.process: Process | None = None
        self.cancelled = False
        #: set when the command could not start (cancelled with an error)
        self.error_code = 0


class ProfiledProcess(Process):
    """A process driven by one profile: ruckig's when jerk-limited, the closed-form
    trapezoid otherwise (:func:`.profiles.profile_for`)."""

    def __init__(
        self,
        dt: float,
        limits: Limits,
        velocity: float = 0.0,
        acceleration: float = 0.0,
        owner: Any = None,
    ) -> None:
        super().__init__(owner)
        self.limits = limits.validated()
        self.profile: OnlineProfile = profile_for(self.limits, dt, velocity, acceleration)
        self.velocity = velocity
        self.acceleration = acceleration
        #: while an override scales the process (:mod:`.override`): its programmed limits
        #: and its programmed target (a jog: its velocity; a move: 1 running, 0 paused)
        self.override_nominal: tuple[Limits, float] | None = None

    def step(self, ctx: StepContext, dt: float) -> None:
        self.profile.step()
        self.position = self.profile.position
        self.velocity = self.profile.velocity
        self.acceleration = self.profile.acceleration
        self._after_step()

    def _after_step(self) -> None:
        if self.profile.finished:
            self.finish()

    def change_limits(self, limits: Limits) -> None:
        """Motion Change Dynamics: re-plan toward the same target with new limits."""
        self.change_dynamics(limits)

    def change_dynamics(self, limits: Limits, speed: float | None = None) -> None:
        """MCD: new limits and, unless None, a new speed, planned as one change. If the
        profile cannot be planned nothing changes and MotionError is raised."""
        # a member of a lane that plans (time-driven: :meth:`.lanes.ramps.PlanLane.replan`)
        # keeps its row if the new plan is still that lane's; any other leaves its lane
        lane = self.lane
        keeper = lane if lane is not None and lane.replans(self) else None
        if keeper is not None:
            keeper.sync(self)
        else:
            if lane is not None:
                lane.evict(self)
            self.offer_pending = True
        # new programmed dynamics (MCD): an override applies again at its next change
        self.override_nominal = None
        saved = dict(vars(self))
        try:
            self.limits = limits.validated()
            self._fit_profile()
            if speed is None:
                self._retarget()
            else:
                self.change_speed(speed)
        except MotionError:
            vars(self).update(saved)
            raise
        if keeper is not None and not keeper.replan(self):
            self.offer_pending = True  # (left the lane: offered again)

    def _fit_profile(self) -> None:
        """New limits may change the kind of profile (jerk-limited or trapezoidal): the
        new one starts where the old one is."""
        prof = self.profile
        if isinstance(prof, TrapezoidProfile) != self.limits.trapezoidal:
            self.profile = profile_for(
                self.limits, prof.dt, prof.velocity, prof.acceleration, prof.position
            )

    def change_speed(self, speed: float) -> None:
        raise NotImplementedError

    def _retarget(self) -> None:
        raise NotImplementedError


class JogProcess(ProfiledProcess):
    """Run at a signed velocity until stopped or superseded (MAJ, MC_MoveVelocity)."""

    kind = ProcessKind.JOG

    def __init__(
        self,
        dt: float,
        velocity_target: float,
        limits: Limits,
        velocity: float = 0.0,
        acceleration: float = 0.0,
        owner: Any = None,
    ) -> None:
        super().__init__(dt, limits, velocity, acceleration, owner)
        self.target_velocity = velocity_target
        self.at_speed = False
        self._retarget()

    def _retarget(self) -> None:
        self.profile.to_velocity(self.target_velocity, self.limits)
        self.at_speed = False

    def _after_step(self) -> None:
        # A jog never finishes by itself; "at speed" is InVelocity for PLCopen.
        if self.profile.finished and not self.at_speed:
            self.at_speed = True
            self.offer_pending = True

    def change_speed(self, speed: float) -> None:
        """Keep the direction, change the magnitude (MCD)."""
        sign = -1.0 if self.target_velocity < 0 else 1.0
        self.target_velocity = sign * abs(speed)
        self.limits = Limits(
            abs(speed) or self.limits.velocity,
            self.limits.acceleration,
            self.limits.deceleration,
            self.limits.jerk,
        )
        self._retarget()

    @property
    def reached(self) -> bool:
        return self.at_speed or super().reached


class MoveProcess(ProfiledProcess):
    """Travel a displacement and come to rest exactly there (MAM, MC_Move*)."""

    kind = ProcessKind.MOVE

    def __init__(
        self,
        dt: float,
        displacement: float,
        limits: Limits,
        velocity: float = 0.0,
        acceleration: float = 0.0,
        owner: Any = None,
        landing: float | None = None,
    ) -> None:
        super().__init__(dt, limits, velocity, acceleration, owner)
        self.displacement = displacement
        self.landing = landing
        #: MCD set the speed to 0: the move ramps to rest and waits, still in process
        self.paused = False
        self._retarget()

    def _retarget(self) -> None:
        if self.paused:
            self.profile.to_velocity(0.0, self.limits)
        else:
            self.profile.to_position(self.displacement, self.limits)

    def _after_step(self) -> None:
        if self.profile.finished and not self.paused:
            self.finish()

    def change_speed(self, speed: float) -> None:
        """MCD: a new speed toward the same target; speed 0 pauses the move."""
        self.paused = speed == 0.0
        if not self.paused:
            self.limits = Limits(
                abs(speed), self.limits.acceleration, self.limits.deceleration, self.limits.jerk
            ).validated()
        self._retarget()


class StopRamp(ProfiledProcess):
    """Decelerate an inherited velocity to zero (MAS, MC_Stop, MC_Halt, MGS, gear stop)."""

    kind = ProcessKind.STOP

    def __init__(
        self,
        dt: float,
        deceleration: float,
        jerk: float,
        velocity: float,
        acceleration: float = 0.0,
        owner: Any = None,
        stopping: bool = True,
    ) -> None:
        big = max(abs(velocity), 1e-9) * 2.0
        limits = Limits(big, deceleration, deceleration, jerk).validated()
        a0 = acceleration if jerk else 0.0
        if limits.trapezoidal:
            # stepped in closed form (below), no planner: the ramp is judged as a plan
            # would judge it (a ramp beyond the longest profile is refused)
            Process.__init__(self, owner)
            self.limits = limits
            self.profile = TrapezoidProfile(dt, velocity, a0)
            self.velocity = velocity
            self.acceleration = a0
            judge_ramp(velocity, deceleration)
        else:
            super().__init__(dt, limits, velocity, a0, owner)
            self._retarget()
        self.stopping = stopping
        if velocity == 0.0 and acceleration == 0.0:
            self.finish()

    def _retarget(self) -> None:
        self.profile.to_velocity(0.0, self.limits)

    def step(self, ctx: StepContext, dt: float) -> None:
        if not self.limits.trapezoidal:
            super().step(ctx, dt)  # jerk-limited: ruckig plans it
            return
        # Trapezoidal (every MGS stop, MAS without jerk): the velocity drops by exactly
        # deceleration x dt per cycle and reaches rest in ceil(|v| / (d dt)) cycles. Done
        # here rather than through ruckig, whose time rounding can add a cycle.
        v0 = self.velocity
        dv = self.limits.deceleration * dt
        v1 = 0.0 if abs(v0) <= dv * (1.0 + 1e-9) else v0 - math.copysign(dv, v0)
        self.position += 0.5 * (v0 + v1) * dt
        self.velocity = v1
        self.acceleration = (v1 - v0) / dt
        if v1 == 0.0:
            self.finish()

    def _after_step(self) -> None:
        if self.profile.finished:
            self.velocity = 0.0
            self.finish()


def halt_ramp(dt: float, deceleration: float, jerk: float, owner: Any) -> ProcessFactory:
    """The factory of MC_Halt's ramp: from the velocity and acceleration of what it
    replaces to rest, the axis not Stopping (``StopRamp(..., stopping=False)``)."""

    def make(v: float, a: float) -> Process:
        return StopRamp(dt, deceleration, jerk, v, a, owner=owner, stopping=False)

    return make
