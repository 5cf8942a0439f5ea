"""Master Driven Speed Control (MDSC): master-driven processes, and the rules.

An MDAC assigns a master axis to a slave for a motion type (All, Jog, Move); the links
(assignments, pending reassignment, link-breaking stops) live in :mod:`.mdac_links`. A
MAJ or MAM whose dynamics are in master units then runs a *master-driven* process: its
profile advances with the master's travel instead of time. Speed is in slave units per master
unit, acceleration in units per master unit², jerk in units per master unit³, so the
slave's speed is the programmed speed times the master's speed.

Decisions (where the Logix manuals leave it open):

- Lock direction is "immediate, forward only": the profile advances with the master's
  forward travel; a master moving in reverse holds the slave where it is.
- A virtual master is read at its command position, a feedback-only master at its actual
  position, whatever the MasterReference says (the manuals' rule).
- Changing the master: an MDAC All to another master while an MDAC All is in place makes
  the reassignment *pending*; the next MAJ/MAM on the slave that goes IP switches it, and
  from that scan on all master-driven motion of the slave follows the new master (the
  seed: the axis is reassigned when the new instruction goes IP). A process the new
  instruction replaces hands it its velocity, as always; one that keeps running goes on
  from its velocity, re-planned in the new master's travel toward its programmed speed
  (:meth:`MasterDrivenProcess.follow`). The change is refused while the slave moves when
  the new master is idle (ERR 97) or when the new effective speed, the programmed speeds
  × the new master's speed, is less than 5 % of the programmed speed of the motion it
  changes (ERR 103): judged from programmed values, never from the measured velocity, so
  exactly 5 % (to the resolution of REAL operands) is always allowed. A refused change
  stays pending.
- A link of a type other than All is reassigned only after a stop breaks it (ERR 105).
- A link breaks on MAS All, MGS, MASD, MGSD, a fault or a mode change on the slave, and on
  MGS, MASD, MGSD, a fault or a mode change on the master. The master-driven processes
  still running under a broken link switch to time-driven and stop (the slave ramps to
  rest at its maximum deceleration), as MGS does to master-driven axes; a change of
  master (superseded link) moves them to the new master.
"""

from __future__ import annotations

import math
from enum import IntEnum, StrEnum
from typing import Any

import ruckig

from .axis import Axis
from .enums import AxisType, MasterReference, ProcessKind
from .errors import ErrorCode, MotionError
from .processes import Process
from .profiles import Limits, apply_input, capture_input
from .state import StepContext

#: a slave moving slower than this (units/s) counts as standing still for the master change
MOVING_EPSILON = 1e-9
#: the new effective slave speed must be at least this share of the speed before a change
MIN_SPEED_SHARE = 0.05
#: relative resolution of that comparison: products of REAL (float32) operands that are
#: exactly 5 % in decimal differ from it by less than this
SHARE_TOLERANCE = 1e-6


class MotionType(IntEnum):
    """MDAC Motion Type: which single-axis motion the assignment covers."""

    ALL = 0
    JOG = 1
    MOVE = 2
    #: MATC: the time cam runs on the master's travel (kernel/cams.py)
    TIME_CAM = 3


def link_reference(master: Axis, reference: MasterReference) -> MasterReference:
    """The position an MDAC link reads: a virtual master at its command, a feedback-only
    master at its actual position, whatever the MasterReference says (the manuals' rule)."""
    if master.type == AxisType.VIRTUAL:
        return MasterReference.COMMAND
    if master.type == AxisType.FEEDBACK_ONLY:
        return MasterReference.ACTUAL
    return reference


def master_position(ctx: StepContext, master: Axis, reference: MasterReference) -> float:
    """Unwound position of the master as the link reads it."""
    return ctx.read_master(master.index, link_reference(master, reference))[0]


def master_speed(ctx: StepContext, master: Axis, reference: MasterReference) -> float:
    """The master's forward speed (units/s) as the link reads it; reverse counts as 0."""
    return max(ctx.read_master(master.index, link_reference(master, reference))[1], 0.0)


#: master travel (master units) a master-driven profile may take, at most: ruckig's
#: offline planner loses its precision and raises near 1e12; 1e9 mm of master travel is
#: more than eleven days of a master at 1 m/s
MAX_MASTER_TRAVEL = 1e9
#: the bound a profile planned inside the kernel (a change of master, a re-plan) is held
#: to: wider than the operands' bound, so that motion judged at its start is not refused
#: later for a ratio it inherits, yet short of where ruckig raises
PLANNER_TRAVEL = 1e11


class Dynamic(StrEnum):
    """The quantity of a master-driven profile that makes it unplannable."""

    SPEED = "speed"
    DISTANCE = "distance"
    ACCELERATION = "acceleration"
    DECELERATION = "deceleration"
    JERK = "jerk"


class MasterProfileError(MotionError):
    """A master-driven profile that cannot be planned: ERR 13, with the quantity at fault
    (the instruction names the operand that gave it)."""

    def __init__(self, quantity: Dynamic, message: str) -> None:
        self.quantity = quantity
        super().__init__(ErrorCode.PARAMETER_OUT_OF_RANGE, message)


def judge_master_profile(
    limits: Limits,
    ratio: float,
    velocity: float | None,
    position: float | None,
    bound: float = MAX_MASTER_TRAVEL,
) -> None:
    """Refuse, before ruckig sees them, dynamics whose profile would take more than
    ``bound`` of master travel (ruckig raises on such inputs: an
    AccelRate of 1e-30 per master unit², a move at 1e-30 per master unit). The travel is
    bounded from above by a feasible profile: brake from the current ``ratio``, then ramp
    (and cruise) to the target; the largest share names the quantity at fault."""
    limits = limits.validated()
    acc, dec = limits.acceleration, limits.deceleration
    terms = dict.fromkeys(Dynamic, 0.0)
    if position is None:
        target = float(velocity or 0.0)
        if ratio * target < 0.0:  # reverse: brake to 0, then ramp up the other way
            terms[Dynamic.DECELERATION] = abs(ratio) / dec
            terms[Dynamic.ACCELERATION] = abs(target) / acc
        elif abs(target) >= abs(ratio):
            terms[Dynamic.ACCELERATION] = (abs(target) - abs(ratio)) / acc
        else:
            terms[Dynamic.DECELERATION] = (abs(ratio) - abs(target)) / dec
    else:
        rate = min(acc, dec)
        slow = Dynamic.ACCELERATION if acc <= dec else Dynamic.DECELERATION
        terms[Dynamic.DECELERATION] = abs(ratio) / dec
        way = abs(position) + ratio * ratio / (2.0 * dec)
        v = limits.velocity
        if way * rate <= v * v:
            terms[slow] += 2.0 * math.sqrt(way / rate)
        else:
            # a way longer than any profile may travel is the distance's fault, else the
            # speed's (too slow to cover it)
            cruise = Dynamic.DISTANCE if abs(position) > bound else Dynamic.SPEED
            terms[cruise] = way / v
            terms[slow] += v / rate
    if not limits.trapezoidal:
        terms[Dynamic.JERK] = 4.0 * max(acc, dec) / limits.jerk
    total = sum(terms.values())
    if math.isfinite(total) and total <= bound:
        return
    worst = max(terms, key=lambda q: terms[q])
    raise MasterProfileError(
        worst,
        f"the {worst.value} makes the master-driven profile take {total:g} master units "
        f"(at most {bound:g})",
    )


class MasterProfile:
    """A ruckig trajectory planned in the master-position domain (offline, sampled at the
    master travel ``s``): positions in slave units, "velocity" a ratio (units per master
    unit). Beyond its duration a velocity target continues at constant ratio and a
    position target holds."""

    def __init__(
        self, limits: Limits, ratio: float, velocity: float | None, position: float | None
    ) -> None:
        limits = limits.validated()
        if position is not None and not math.isfinite(position):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "distance must be finite")
        if velocity is not None and not math.isfinite(velocity):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "speed must be finite")
        judge_master_profile(limits, ratio, velocity, position, PLANNER_TRAVEL)
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
        if position is not None:
            # a move runs at its programmed speed: from a faster inherited ratio (or one a
            # change of master left it) it brakes down to it first, as ruckig plans it
            inp.max_velocity = [limits.velocity]
        else:
            top = abs(velocity) if velocity is not None else 0.0
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
        except (RuntimeError, ruckig.RuckigError) as exc:  # pragma: no cover - judged above
            raise MotionError(ErrorCode.PROFILE_FAILED, str(exc)) from exc
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise MotionError(ErrorCode.PROFILE_FAILED, f"ruckig result {result}")
        self.duration = float(self._traj.duration)
        self.target_position = position
        #: what the trajectory was planned from (a snapshot plans it again)
        self._input = capture_input(inp)

    def __getstate__(self) -> dict[str, Any]:
        """ruckig's trajectory does not pickle: keep its input (see :meth:`__setstate__`)."""
        return {k: v for k, v in self.__dict__.items() if k != "_traj"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Plan the trajectory again from the same input: ruckig is deterministic, the same
        trajectory bit for bit."""
        self.__dict__.update(state)
        inp = ruckig.InputParameter(1)
        apply_input(inp, self._input)
        self._traj = ruckig.Trajectory(1)
        ruckig.Ruckig(1).calculate(inp, self._traj)

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
        ctx: StepContext,
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
        self._last_master = master_position(ctx, master, reference)
        self._origin = 0.0  # position at the last (re)plan
        self._plan_travel = 0.0  # travel at the last (re)plan
        self.profile = self._plan(ratio)
        self._sample()
        self.velocity = self.ratio * master_speed(ctx, master, reference)

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
    def master_shifted(self, index: int, d: float) -> None:
        if index == self._master.index:
            self._last_master += d

    def step(self, ctx: StepContext, dt: float) -> None:
        m = master_position(ctx, self._master, self.reference)
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

    # -- the master -------------------------------------------------------------------------
    @property
    def master_axis(self) -> Axis:
        return self._master

    def master_speed(self, ctx: StepContext) -> float:
        """The forward speed of this process's master, as its link reads it."""
        return master_speed(ctx, self._master, self.reference)

    def follow(self, ctx: StepContext, master: Axis, reference: MasterReference) -> None:
        """A change of master (MDAC): from now on the profile advances with ``master``'s
        forward travel. The slave keeps its velocity: the profile is planned again from
        the ratio that velocity is of the new master's speed (0 for an idle master), toward
        the programmed speed at the programmed rates, both per master unit."""
        speed = master_speed(ctx, master, reference)
        self.master = master.number
        self.masters = (master.number,)
        self._master = master
        self.reference = reference
        self._last_master = master_position(ctx, master, reference)
        self.ratio = self.velocity / speed if speed > MOVING_EPSILON else 0.0
        self._replan()


class MasterDrivenJog(MasterDrivenProcess):
    """MAJ in master units: run at ``speed`` units per master unit until stopped."""

    kind = ProcessKind.JOG

    def __init__(
        self,
        ctx: StepContext,
        master: Axis,
        reference: MasterReference,
        speed: float,
        limits: Limits,
        ratio: float = 0.0,
        owner: Any = None,
    ) -> None:
        self.speed = speed
        super().__init__(ctx, master, reference, limits, ratio, owner)

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
        ctx: StepContext,
        master: Axis,
        reference: MasterReference,
        distance: float,
        limits: Limits,
        ratio: float = 0.0,
        owner: Any = None,
    ) -> None:
        self.distance = distance
        super().__init__(ctx, master, reference, limits, ratio, owner)

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
