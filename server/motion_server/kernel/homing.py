"""Homing: the sequences behind MAH and MC_Home, as tables.

The Logix homing modes and sequences (MOTION-RM002 MAH, MOTION-RM003 "Homing Sequence
Types"):

- **Immediate** (any mode): the axis reads the home value at once, no motion.
- **Absolute**: the same, for an axis with absolute feedback, in Axis Ready only.
- **Passive**: no motion is commanded; something else moves the axis (a MAJ, a hand
  wheel) and the home value is assigned at the home event (:class:`PassiveHoming`).
- **Active** (:class:`HomeProcess`): the axis moves in the home direction at the home
  speed until the home event, with the phases of :data:`SEARCH` (a bidirectional
  search to a switch stops, reverses at the return speed and takes the point where the
  switch clears), then finishes as :data:`FINISH` says:

  - bidirectional (``RETURN``): to rest at the home deceleration, then a trapezoidal
    move back to the home position at the return speed ("the controller then moves the
    axis back to the Home Position at the specified Home Return Speed");
  - unidirectional (``RUN_ON``): on to the home position at the home speed when it
    lies beyond the stopping distance, in the direction of travel ("by setting a Home
    Offset greater than the deceleration distance, unidirectional motion to the Home
    Position is insured"; on a rotary axis whole turns are added); otherwise the axis
    just stops, short of the home position, and the sequence ends without reaching it
    (MAH sets no PC);
  - ``STOP`` (MC_Home to a switch or marker, PLCopen: "terminates with standstill"):
    to rest.

The home event (a switch edge or a marker, :mod:`.sensors`) is latched at its exact
position; the axis's coordinates shift there (:func:`.redefine.shift_coordinates`) so that
the latched point reads the home value, and the axis is Homed. Every phase is a plain
process (a trapezoidal jog, stop ramp or move) stepped inside the homing process, which
the fast lanes never take: homing motion is the reference path's, with lanes or not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from .axis import Axis
from .enums import (
    AbortReason,
    AxisState,
    HomeDirection,
    HomeMode,
    HomeSequence,
    ProcessKind,
    ProcessState,
)
from .errors import ErrorCode, MotionError, TransitionError
from .group import MotionGroup
from .motion import Motion
from .processes import JogProcess, MoveProcess, Process, StopRamp
from .profiles import Limits
from .redefine import shift_coordinates
from .sensors import HomeSensors, SensorEvent
from .state import StepContext


class HomeEvent(IntEnum):
    """What moves a homing sequence on: the sensors' events (same numbers as
    :class:`~.sensors.SensorEvent`) and the end of a phase's motion."""

    SWITCH_ON = 0
    SWITCH_OFF = 1
    MARKER = 2
    AT_REST = 3
    ARRIVED = 4


class HomePhase(IntEnum):
    SEEK = 0  # at the home speed in the home direction, for the first event
    BRAKE = 1  # to rest at the home deceleration, before reversing
    BACK_OFF = 2  # the other way at the return speed, until the switch clears
    FIND_MARKER = 3  # on at the same speed, until the next marker
    HOMED = 4  # the home event: the position is redefined here
    HOMED_BRAKE = 5  # to rest at the home deceleration
    RETURN = 6  # a move to the home position at the return speed
    RUN_ON = 7  # a move on to the home position at the home speed
    DONE = 8


class HomeFinish(IntEnum):
    """What an active sequence does after its home event (see the module docstring)."""

    RETURN = 0
    RUN_ON = 1
    STOP = 2


P, E = HomePhase, HomeEvent
_SWITCH_BACK = {(P.SEEK, E.SWITCH_ON): P.BRAKE, (P.BRAKE, E.AT_REST): P.BACK_OFF}
#: the search of the active sequences, per (sequence, bidirectional)
SEARCH: dict[tuple[HomeSequence, bool], dict[tuple[HomePhase, HomeEvent], HomePhase]] = {
    (HomeSequence.SWITCH, True): {**_SWITCH_BACK, (P.BACK_OFF, E.SWITCH_OFF): P.HOMED},
    (HomeSequence.SWITCH, False): {(P.SEEK, E.SWITCH_ON): P.HOMED},
    (HomeSequence.MARKER, True): {(P.SEEK, E.MARKER): P.HOMED},
    (HomeSequence.MARKER, False): {(P.SEEK, E.MARKER): P.HOMED},
    (HomeSequence.SWITCH_THEN_MARKER, True): {
        **_SWITCH_BACK,
        (P.BACK_OFF, E.SWITCH_OFF): P.FIND_MARKER,
        (P.FIND_MARKER, E.MARKER): P.HOMED,
    },
    (HomeSequence.SWITCH_THEN_MARKER, False): {
        (P.SEEK, E.SWITCH_ON): P.FIND_MARKER,
        (P.FIND_MARKER, E.MARKER): P.HOMED,
    },
}
#: passive homing: the same events, no motion (the axis is moved by something else)
PASSIVE: dict[HomeSequence, dict[tuple[HomePhase, HomeEvent], HomePhase]] = {
    HomeSequence.SWITCH: {(P.SEEK, E.SWITCH_ON): P.HOMED},
    HomeSequence.MARKER: {(P.SEEK, E.MARKER): P.HOMED},
    HomeSequence.SWITCH_THEN_MARKER: {
        (P.SEEK, E.SWITCH_ON): P.FIND_MARKER,
        (P.FIND_MARKER, E.MARKER): P.HOMED,
    },
}
#: after the home event; RUN_ON goes to HOMED_BRAKE instead when there is no room
FINISH: dict[HomeFinish, dict[tuple[HomePhase, HomeEvent], HomePhase]] = {
    HomeFinish.RETURN: {(P.HOMED_BRAKE, E.AT_REST): P.RETURN, (P.RETURN, E.ARRIVED): P.DONE},
    HomeFinish.RUN_ON: {(P.HOMED_BRAKE, E.AT_REST): P.DONE, (P.RUN_ON, E.ARRIVED): P.DONE},
    HomeFinish.STOP: {(P.HOMED_BRAKE, E.AT_REST): P.DONE},
}
#: the sensor event each waiting phase listens for
_SENSED = {E.SWITCH_ON, E.SWITCH_OFF, E.MARKER}
del P, E


@dataclass(frozen=True)
class HomeRequest:
    """One homing: mode, sequence and direction; ``value`` is what the axis reads at the
    home event (or at once), ``target`` where RETURN and RUN_ON end; speeds in units/s,
    rates in units/s²."""

    mode: HomeMode
    sequence: HomeSequence
    direction: HomeDirection
    value: float
    target: float
    finish: HomeFinish
    speed: float = 0.0
    return_speed: float = 0.0
    acceleration: float = 0.0
    deceleration: float = 0.0

    @property
    def immediate(self) -> bool:
        return self.sequence == HomeSequence.IMMEDIATE or self.mode == HomeMode.ABSOLUTE


def configured(
    ax: Axis, value: float | None = None, finish: HomeFinish | None = None
) -> HomeRequest:
    """The homing the axis's configuration describes (MAH). ``value`` replaces the home
    value (home_position - home_offset), the target following it by home_offset
    (MC_Home's Position); ``finish`` replaces the one the direction implies."""
    cfg = ax.config
    if value is None:
        value = cfg.home_position - cfg.home_offset
    if finish is None:
        finish = HomeFinish.RETURN if cfg.home_direction.bidirectional else HomeFinish.RUN_ON
    return HomeRequest(
        cfg.home_mode,
        cfg.home_sequence,
        cfg.home_direction,
        value,
        value + cfg.home_offset,
        finish,
        cfg.home_speed,
        cfg.home_return_speed,
        cfg.home_acceleration or cfg.max_acceleration,
        cfg.home_deceleration or cfg.max_deceleration,
    )


def judge(ax: Axis, req: HomeRequest, sensors: HomeSensors | None) -> None:
    """Raise MotionError (13) for a sequence the axis cannot run: a sensor it lacks, a
    speed or rate that is not positive, a home value outside [0, rollover) on a rotary
    axis."""

    def refuse(message: str) -> MotionError:
        return MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"{ax.name}: {message}")

    rollover = ax.config.rollover
    for name, v in (("home value", req.value), ("home target", req.target)):
        if not math.isfinite(v) or (rollover > 0.0 and not 0.0 <= v < rollover):
            where = f"in [0, {rollover:g})" if rollover > 0.0 else "finite"
            raise refuse(f"{name} {v!r} must be {where}")
    if req.immediate:
        return
    seq = req.sequence
    needs_switch = seq in (HomeSequence.SWITCH, HomeSequence.SWITCH_THEN_MARKER)
    needs_marker = seq in (HomeSequence.MARKER, HomeSequence.SWITCH_THEN_MARKER)
    if needs_switch and (sensors is None or not sensors.has_switch):
        raise refuse("no home switch is configured (home_switch)")
    if needs_marker and (sensors is None or not sensors.has_marker):
        raise refuse("no encoder marker is configured (marker_interval)")
    if req.mode != HomeMode.ACTIVE:
        return
    rates = [("home_speed", req.speed), ("home_acceleration", req.acceleration)]
    rates.append(("home_deceleration", req.deceleration))
    if req.direction.bidirectional and (needs_switch or req.finish == HomeFinish.RETURN):
        rates.append(("home_return_speed", req.return_speed))
    for name, v in rates:
        if not (math.isfinite(v) and v > 0.0):
            raise refuse(f"{name} must be > 0 for an active homing sequence, got {v!r}")


class HomeProcess(Process):
    """An active homing sequence on one axis (see the module docstring). Each phase's
    motion is a plain process stepped here; ``position`` is the displacement of the
    phases so far plus the current one's."""

    kind = ProcessKind.HOME

    def __init__(
        self,
        ax: Axis,
        req: HomeRequest,
        engaged: bool,
        velocity: float = 0.0,
        acceleration: float = 0.0,
        owner: Any = None,
    ) -> None:
        super().__init__(owner)
        self.req = req
        self._ax = ax
        self._dt = ax.period
        self._sign = req.direction.sign
        self._home = Limits(req.speed, req.acceleration, req.deceleration).validated()
        self._table = {
            **SEARCH[(req.sequence, req.direction.bidirectional)],
            **FINISH[req.finish],
        }
        #: the sequence ended on the home position (MAH's PC)
        self.at_home = False
        self._folded = 0.0
        self.velocity = velocity
        self.acceleration = acceleration
        self.stage: Process
        self.phase = HomePhase.SEEK
        if engaged and self._table.get((HomePhase.SEEK, HomeEvent.SWITCH_ON)) == HomePhase.BRAKE:
            # bidirectional and already on the switch: straight to backing off it
            self._enter(HomePhase.BRAKE)
        else:
            self.stage = JogProcess(
                self._dt, self._sign * req.speed, self._home, velocity, acceleration
            )

    # -- events ---------------------------------------------------------------------------
    def awaits(self) -> SensorEvent | None:
        """The sensor event the current phase waits for (None: none)."""
        for (phase, event), _ in self._table.items():
            if phase == self.phase and event in _SENSED:
                return SensorEvent(int(event))
        return None

    def sense(self, event: SensorEvent) -> bool:
        """The awaited sensor ``event`` happened; True when it is the home event (the
        caller redefines the position, then calls :meth:`homed`)."""
        nxt = self._next(HomeEvent(int(event)))
        if nxt == HomePhase.HOMED:
            self.phase = nxt
            return True
        self._enter(nxt)
        return False

    def homed(self) -> None:
        """The position is redefined at the home event: finish as the request says."""
        req = self.req
        if req.finish == HomeFinish.RUN_ON:
            distance = self._run_on_distance()
            if distance is not None:
                self._fold()
                self.landing = self._command_now() + distance
                self.stage = MoveProcess(
                    self._dt, distance, self._home, self.velocity, self.acceleration,
                    landing=self.landing,
                )  # fmt: skip
                self.phase = HomePhase.RUN_ON
                return
        self._enter(HomePhase.HOMED_BRAKE)

    def _run_on_distance(self) -> float | None:
        """Signed distance from the command position to the home position in the
        direction of travel, if it is beyond the stopping distance (whole turns added on
        a rotary axis), else None."""
        ax, s = self._ax, self._sign
        stop = self.velocity * self.velocity / (2.0 * self._home.deceleration)
        ahead = s * (self.req.target - ax.wrap(self._command_now()))
        rollover = ax.config.rollover
        if rollover > 0.0:
            ahead %= rollover
            while ahead < stop:
                ahead += rollover
        return s * ahead if ahead >= stop else None

    def _command_now(self) -> float:
        """The axis's unwound command as this process leaves it (inside a step the
        arrays still hold the last cycle's)."""
        others = sum(p.position for p in self._ax.processes if p.active and p is not self)
        return self._ax.base + others + self.position

    def _next(self, event: HomeEvent) -> HomePhase:
        nxt = self._table.get((self.phase, event))
        if nxt is None:
            raise TransitionError("homing sequence", self.phase, event)
        return nxt

    def _fold(self) -> None:
        self._folded += self.stage.position

    def _enter(self, phase: HomePhase) -> None:
        """Begin ``phase``'s motion from the current velocity and acceleration."""
        req, dt, v, a = self.req, self._dt, self.velocity, self.acceleration
        self.phase = phase
        if phase == HomePhase.FIND_MARKER:
            return  # on at the same speed: the same jog
        if phase == HomePhase.DONE:
            self.finish()
            return
        if hasattr(self, "stage"):
            self._fold()
        if phase in (HomePhase.BRAKE, HomePhase.HOMED_BRAKE):
            self.stage = StopRamp(dt, req.deceleration, 0.0, v, stopping=False)
        elif phase == HomePhase.BACK_OFF:
            back = Limits(req.return_speed, req.acceleration, req.deceleration)
            self.stage = JogProcess(dt, -self._sign * req.return_speed, back, v, a)
        elif phase == HomePhase.RETURN:
            here = self._command_now()
            self.landing = self._ax.unwound_target(req.target, here)
            distance = self.landing - here
            back = Limits(req.return_speed, req.acceleration, req.deceleration)
            self.stage = MoveProcess(dt, distance, back, v, a, landing=self.landing)
        else:  # pragma: no cover - every phase with motion is listed above
            raise TransitionError("homing sequence", self.phase, HomeEvent.ARRIVED)

    # -- motion ---------------------------------------------------------------------------
    def step(self, ctx: StepContext, dt: float) -> None:
        self._settle_stage()
        if not self.active:
            return
        stage = self.stage
        stage.step(ctx, dt)
        self.position = self._folded + stage.position
        self.velocity = stage.velocity
        self.acceleration = stage.acceleration
        self._settle_stage()

    def _settle_stage(self) -> None:
        """A phase whose motion ended moves the sequence on (perhaps to its end)."""
        while (
            self.active and self.phase != HomePhase.HOMED and self.stage.state == ProcessState.DONE
        ):
            event = HomeEvent.AT_REST if isinstance(self.stage, StopRamp) else HomeEvent.ARRIVED
            if (self.phase, event) not in self._table:
                return  # a jog that reached its speed is not DONE; nothing else ends here
            nxt = self._next(event)
            if nxt == HomePhase.DONE:
                self.at_home = self.phase in (HomePhase.RETURN, HomePhase.RUN_ON)
            # at rest: the next phase starts from rest (a ramp's last step leaves its
            # deceleration as the acceleration of the cycle)
            self.velocity = self.acceleration = 0.0
            self._enter(nxt)

    def shifted(self, d: float) -> None:
        super().shifted(d)
        stage = getattr(self, "stage", None)
        if stage is not None and stage.landing is not None:
            stage.landing += d


class PassiveHoming:
    """A passive homing waiting for its home event (:data:`PASSIVE`); ``state`` is ACTIVE
    until the event (DONE) or a cancellation (ABORTED)."""

    def __init__(self, ax: Axis, req: HomeRequest, owner: Any = None) -> None:
        self.ax = ax
        self.req = req
        self.owner = owner
        self.state = ProcessState.ACTIVE
        self.abort_reason = AbortReason.NONE
        self.error_code = 0
        self.phase = HomePhase.SEEK
        self._table = PASSIVE[req.sequence]
        self.at_home = False

    @property
    def active(self) -> bool:
        return self.state == ProcessState.ACTIVE

    def awaits(self) -> SensorEvent | None:
        for (phase, event), _ in self._table.items():
            if phase == self.phase:
                return SensorEvent(int(event))
        return None

    def sense(self, event: SensorEvent) -> bool:
        nxt = self._table.get((self.phase, HomeEvent(int(event))))
        if nxt is None:
            raise TransitionError("passive homing", self.phase, HomeEvent(int(event)))
        self.phase = nxt
        return nxt == HomePhase.HOMED

    def homed(self) -> None:
        self.phase = HomePhase.DONE
        self.at_home = True
        self.state = ProcessState.DONE

    def abort(self, reason: AbortReason) -> None:
        if self.state == ProcessState.ACTIVE:
            self.state = ProcessState.ABORTED
            self.abort_reason = reason


#: a passive homing waits in Axis Ready or Servo Control; these states end it
_CANCELLING = {
    AxisState.AXIS_FAULTED: AbortReason.FAULTED,
    AxisState.AXIS_SHUTDOWN: AbortReason.SHUTDOWN,
}

#: what a homing instruction follows: the process, the passive watch, or an immediate
#: homing that is done at once
HomeHandle = HomeProcess | PassiveHoming


class Homing:
    """The sensors of every axis that has one, and the homings waiting for their events.

    After the drives of a group have stepped, :meth:`update` finds each sensor axis's
    events of the cycle (from the raw position at the end of the last cycle to the one
    now) and hands the awaited ones to the axis's homing, in the order of travel.
    """

    def __init__(self, motion: Motion, axes: Sequence[Axis], groups: Sequence[MotionGroup]) -> None:
        self._motion = motion
        self.sensors: dict[int, HomeSensors] = {}
        for ax in axes:
            cfg = ax.config
            if cfg.home_switch is not None or cfg.marker_interval > 0.0:
                self.sensors[ax.index] = HomeSensors(cfg)
        self.groups: dict[int, list[Axis]] = {}
        for g in groups:
            members = [ax for ax in g.axes if ax.index in self.sensors]
            if members:
                self.groups[g.number] = members
        #: raw position of each sensor axis at the end of its last cycle (None: not yet),
        #: and at the end of the cycle before (what :meth:`marker_seen` compares)
        self._raw: dict[int, float | None] = dict.fromkeys(self.sensors)
        self._before: dict[int, float | None] = dict.fromkeys(self.sensors)
        #: the homing waiting for events, per axis index
        self.jobs: dict[int, HomeHandle] = {}

    def raw(self, ax: Axis) -> float:
        """The axis's raw position now (continuous drive position minus the offset)."""
        return self._motion.s.act_x.item(ax.index) - ax.position_offset

    def marker_seen(self, index: int) -> bool:
        """A marker was crossed in the last cycle of the axis ``index`` (the ``Marker``
        tag; worked out when read, not every cycle)."""
        r0 = self._before.get(index)
        r1 = self._raw.get(index)
        if r0 is None or r1 is None:
            return False
        return self.sensors[index].first(SensorEvent.MARKER, r0, r1) is not None

    def switch(self, ax: Axis) -> bool:
        """The home switch of ``ax`` now (the ``HomeSwitch`` tag)."""
        sensors = self.sensors.get(ax.index)
        return sensors is not None and sensors.engaged(self.raw(ax))

    def track(self, ax: Axis, job: HomeHandle) -> None:
        """``job`` waits for ``ax``'s sensor events from now on (a job it replaces is
        cancelled)."""
        self.cancel(ax, AbortReason.SUPERSEDED)
        self.jobs[ax.index] = job
        if isinstance(job, PassiveHoming):
            ax.homing_armed = job

    def cancel(self, ax: Axis, reason: AbortReason) -> None:
        """End a passive homing waiting on ``ax`` (an active one ends with its process)."""
        job = self.jobs.pop(ax.index, None)
        if isinstance(job, PassiveHoming):
            job.abort(reason)
            ax.homing_armed = None

    def update(self, group: int) -> None:
        act_x = self._motion.s.scalars.act_x
        jobs = self.jobs
        for ax in self.groups.get(group, ()):
            i = ax.index
            r1 = act_x[i] - ax.position_offset
            r0 = self._before[i] = self._raw[i]
            self._raw[i] = r1
            if r0 is None:
                continue
            job = jobs.get(i)
            if job is None:
                continue
            sensors = self.sensors[i]
            if not job.active:  # an active homing ended (done, stopped, superseded)
                del self.jobs[i]
                continue
            if ax.state in _CANCELLING:
                self.cancel(ax, _CANCELLING[ax.state])
                continue
            at = r0
            while (event := job.awaits()) is not None:
                x = sensors.first(event, at, r1)
                if x is None:
                    break
                if job.sense(event):
                    self._home_event(ax, job, x)
                    break
                at = x

    def _home_event(self, ax: Axis, job: HomeHandle, x: float) -> None:
        """The home event at raw position ``x``: the axis reads the home value there."""
        d = (job.req.value - x) - ax.position_offset
        shift_coordinates(self._motion, ax, d)
        ax.homed = True
        job.homed()
        if isinstance(job, PassiveHoming):
            self.jobs.pop(ax.index, None)
            ax.homing_armed = None
