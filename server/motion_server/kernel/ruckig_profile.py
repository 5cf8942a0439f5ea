"""The jerk-limited profile through ruckig: one online update per cycle.

What :class:`~.scurve.SCurveProfile` hands the position and velocity targets its closed
forms do not cover to, and what master-driven motion plans with. Inputs are
validated before ruckig sees them (ruckig raises on bad input, a controller answers ER
instead); ``intermediate_positions`` is never set.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import ruckig

from .errors import ErrorCode, MotionError
from .limits import Limits


class Profile:
    """A ruckig trajectory advanced by exactly one cycle per :meth:`step`.

    ``position`` is the displacement from the origin where the profile was created.
    """

    def __init__(
        self, dt: float, velocity: float = 0.0, acceleration: float = 0.0, position: float = 0.0
    ) -> None:
        self._dt = dt
        self._otg = ruckig.Ruckig(1, dt)
        self._inp = ruckig.InputParameter(1)
        self._out = ruckig.OutputParameter(1)
        self._inp.current_position = [float(position)]
        self._inp.current_velocity = [float(velocity)]
        self._inp.current_acceleration = [float(acceleration)]
        self.position = float(position)
        self.velocity = float(velocity)
        self.acceleration = float(acceleration)
        self.finished = False
        self._target_position: float | None = None
        self._target_velocity = 0.0
        #: the input ruckig last planned from (None: not yet): a snapshot rebuilds the
        #: trajectory from it (see ``__getstate__``)
        self._plan: tuple[Any, ...] | None = None
        #: the trajectory ruckig computed when the target was last set (None: none yet,
        #: or restored from a snapshot), for :func:`.scurve.plan_from_ruckig`
        self.trajectory: ruckig.Trajectory | None = None

    # -- targets --------------------------------------------------------------------------
    def to_position(self, displacement: float, limits: Limits) -> None:
        """Plan to rest at ``displacement`` from the origin."""
        if not math.isfinite(displacement):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target position must be finite")
        limits = limits.validated()
        with self._planning():
            inp = self._inp
            inp.control_interface = ruckig.ControlInterface.Position
            inp.target_position = [float(displacement)]
            inp.target_velocity = [0.0]
            inp.target_acceleration = [0.0]
            self._target_position = float(displacement)
            self._apply_limits(limits, direction=displacement - self.position)

    def to_velocity(self, velocity: float, limits: Limits) -> None:
        """Ramp to a constant ``velocity`` (signed) and hold it."""
        if not math.isfinite(velocity):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "target velocity must be finite")
        limits = limits.validated()
        with self._planning():
            inp = self._inp
            inp.control_interface = ruckig.ControlInterface.Velocity
            inp.target_velocity = [float(velocity)]
            inp.target_acceleration = [0.0]
            self._target_position = None
            self._target_velocity = float(velocity)
            direction = velocity if velocity != 0.0 else self.velocity
            self._apply_limits(limits, direction=direction)

    @contextmanager
    def _planning(self) -> Iterator[None]:
        """Change the plan as one transaction: ruckig must be able to compute it (limits
        that are valid but absurd, such as an acceleration of 1e-157, make it fail); if it
        cannot, the previous plan stays and MotionError(PROFILE_FAILED) is raised."""
        inp = self._inp
        fields = (
            "control_interface",
            "target_position",
            "target_velocity",
            "target_acceleration",
            "max_velocity",
            "max_acceleration",
            "min_acceleration",
            "max_jerk",
        )
        saved = {f: getattr(inp, f) for f in fields}
        mine = (self._target_position, self._target_velocity, self.finished)
        # plan from where the profile is: once finished, step() integrates the held
        # velocity without ruckig, so ruckig's copy of the state is stale
        inp.current_position = [self.position]
        inp.current_velocity = [self.velocity]
        inp.current_acceleration = [self.acceleration]
        try:
            yield
            trajectory = ruckig.Trajectory(1)
            result = self._otg.calculate(inp, trajectory)
            if result not in (ruckig.Result.Working, ruckig.Result.Finished):
                raise MotionError(ErrorCode.PROFILE_FAILED, f"ruckig result {result}")
            self.trajectory = trajectory
        except (RuntimeError, ruckig.RuckigError) as exc:
            self._restore(saved, mine)
            raise MotionError(ErrorCode.PROFILE_FAILED, str(exc).strip()[:200]) from exc
        except MotionError:
            self._restore(saved, mine)
            raise

    def _restore(self, saved: dict[str, Any], mine: tuple[float | None, float, bool]) -> None:
        for f, value in saved.items():
            setattr(self._inp, f, value)
        self._target_position, self._target_velocity, self.finished = mine

    def _apply_limits(self, limits: Limits, direction: float) -> None:
        inp = self._inp
        inp.max_velocity = [limits.velocity]
        # ruckig bounds acceleration, not "deceleration": map them on the direction of travel.
        if direction >= 0.0:
            inp.max_acceleration = [limits.acceleration]
            inp.min_acceleration = [-limits.deceleration]
        else:
            inp.max_acceleration = [limits.deceleration]
            inp.min_acceleration = [-limits.acceleration]
        inp.max_jerk = [limits.ruckig_jerk]
        self.finished = False

    # -- stepping -------------------------------------------------------------------------
    def step(self) -> None:
        if self.finished:
            # holding a target velocity: integrate it exactly, no ruckig call needed
            self.acceleration = 0.0
            self.position += self.velocity * self._dt
            return
        try:
            result = self._otg.update(self._inp, self._out)
        except (RuntimeError, ruckig.RuckigError) as exc:  # pragma: no cover - planned before
            raise MotionError(ErrorCode.PROFILE_FAILED, str(exc)) from exc
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            raise MotionError(ErrorCode.PROFILE_FAILED, f"ruckig result {result}")
        out = self._out
        if out.new_calculation:  # planned anew from the input just passed
            self._plan = capture_input(self._inp)
        self.position = out.new_position[0]
        self.velocity = out.new_velocity[0]
        self.acceleration = out.new_acceleration[0]
        out.pass_to_input(self._inp)
        if result == ruckig.Result.Finished:
            self.finished = True
            self.acceleration = 0.0
            if self._target_position is not None:
                # Land exactly: the last sample is the target, at rest.
                self.position = self._target_position
                self.velocity = 0.0
                self._inp.current_position = [self.position]
                self._inp.current_velocity = [0.0]
            else:
                self.velocity = self._target_velocity
            self._inp.current_acceleration = [0.0]

    # -- snapshots ------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        """ruckig's objects do not pickle: keep the input and the time along the trajectory
        of the last plan, and this profile's own input (see :meth:`__setstate__`)."""
        skip = ("_otg", "_inp", "_out", "trajectory")
        state = {k: v for k, v in self.__dict__.items() if k not in skip}
        state["_inp"] = capture_input(self._inp)
        state["_time"] = float(self._out.time)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild ruckig exactly where it was: plan again from the same input (ruckig is
        deterministic: the same trajectory, bit for bit), then advance its clock to the
        saved time with one more update, so that ruckig's own copy of the current state is
        what this profile's input holds, and the next update goes on without replanning."""
        state = dict(state)
        inp_fields = state.pop("_inp")
        saved_time = state.pop("_time")
        self.__dict__.update(state)
        self.trajectory = None
        self._otg = ruckig.Ruckig(1, self._dt)
        self._out = ruckig.OutputParameter(1)
        self._inp = ruckig.InputParameter(1)
        plan = self._plan
        if plan is not None:
            first = ruckig.InputParameter(1)
            apply_input(first, plan)
            self._otg.update(first, self._out)  # plans; its clock reads one cycle
            self._out.pass_to_input(first)  # what ruckig now holds as its input
            self._out.time = time_before(saved_time, self._dt)
            self._otg.update(first, self._out)  # no new plan: the clock reaches saved_time
        apply_input(self._inp, inp_fields)

    @property
    def dt(self) -> float:
        return self._dt

    @property
    def target_position(self) -> float | None:
        return self._target_position

    @property
    def target_velocity(self) -> float:
        return self._target_velocity


#: the fields of a ruckig input a profile sets (the others keep ruckig's defaults)
INPUT_FIELDS = (
    "control_interface",
    "current_position",
    "current_velocity",
    "current_acceleration",
    "target_position",
    "target_velocity",
    "target_acceleration",
    "max_velocity",
    "max_acceleration",
    "min_acceleration",
    "max_jerk",
)


def capture_input(inp: ruckig.InputParameter) -> tuple[Any, ...]:
    """The fields of ``inp`` a profile sets, as plain values (the control interface as an
    int, vectors as tuples of floats)."""
    out: list[Any] = []
    for f in INPUT_FIELDS:
        value = getattr(inp, f)
        if f == "control_interface":
            out.append(int(value.value))
        elif value is None:
            out.append(None)
        else:
            out.append(tuple(float(x) for x in value))
    return tuple(out)


def apply_input(inp: ruckig.InputParameter, fields: tuple[Any, ...]) -> None:
    """Set the fields :func:`capture_input` captured (ValueError when they do not fit)."""
    if not isinstance(fields, tuple) or len(fields) != len(INPUT_FIELDS):
        raise ValueError("a ruckig input of another shape")
    for f, value in zip(INPUT_FIELDS, fields, strict=True):
        if f == "control_interface":
            inp.control_interface = ruckig.ControlInterface(int(value))
        elif value is not None:
            vector = [float(x) for x in value]
            if len(vector) != 1:
                raise ValueError(f"ruckig {f} of {len(vector)} values")
            setattr(inp, f, vector)


def time_before(t: float, dt: float) -> float:
    """A time ``u`` with ``u + dt == t`` exactly in floating point (ruckig advances its
    clock by ``+= dt``): ``t - dt`` nudged by an ulp or two when rounding needs it."""
    u = t - dt
    for _ in range(8):
        total = u + dt
        if total == t:
            return u
        u = math.nextafter(u, math.inf if total < t else -math.inf)
    return t - dt
