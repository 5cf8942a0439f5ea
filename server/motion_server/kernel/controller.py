"""The controller: axes, groups and one deterministic ``step()``.

Sans-I/O: commands go in through methods, state comes out as plain values; simulated time
advances exactly one base period per step. Each group steps every ``every`` ticks with its
own coarse update period. Within a group step:

1. feedback-only axes sample their input or signal (the feedback of the cycle);
2. every axis with motion processes composes its command, masters before slaves: the
   fast lanes first (:mod:`.lanes`, motion states stepped as arrays), then the axes left
   in Python (:class:`~.motion.Motion`);
3. drives follow the command (:mod:`.drive`, vectorised);
4. following error is checked, after-stop actions (disable, shutdown) are applied once
   the axis has come to rest, and group stops note which axes have stopped.

The controller holds every piece of kernel state (:class:`~.state.AxisArrays`, the axes,
groups, lanes, MDAC links), so a snapshot of it is a snapshot of the kernel. Nothing that
goes wrong in a step ends it: a process that raises is contained by
:class:`~.motion.Motion`, a value that is not finite faults its axis
(``AxisFault.NUMERIC``), and both are recorded for the host to log
(:meth:`Controller.take_internal_errors`); the kernel itself never logs.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from contextlib import contextmanager
from operator import attrgetter
from typing import NamedTuple, cast

import numpy as np

from . import status_words
from .axis import Axis, latch_stops
from .cam_tables import CamStore, CamTableConfig
from .config import MAX_PERIOD, MIN_PERIOD, AxisConfig, GroupConfig
from .drive import DriveModel
from .enums import (
    AbortReason,
    AfterStop,
    AxisFault,
    AxisState,
    AxisType,
    HomeMode,
    MasterReference,
    ProcessKind,
    ProgrammedStopMode,
)
from .errors import ErrorCode, MotionError
from .faults import APPLIES, CAUSE_BIT, DISABLE_DRIVE, OVERTRAVEL, FaultCause, FaultInjection
from .gear_batch import Rate, start_gears
from .gearing import GearTerm
from .group import AFTER_FAST_STOP, GroupStop, MotionGroup, OperatingMode, after_stops_due
from .homing import HomeHandle, HomeProcess, HomeRequest, Homing, PassiveHoming, judge
from .jog_batch import start_jogs
from .limits import Limits, group_stop_deceleration
from .mdac_links import MasterDrivenControl
from .motion import InternalError, Motion
from .move_batch import start_moves
from .override import Override
from .power import Power, PowerEvent, require
from .power_plan import power_off_axes
from .processes import Pending, Process, ProcessFactory, StopRamp, halt_ramp
from .redefine import shift_coordinates
from .scurve import FALLBACKS
from .state import AxisArrays, Index, MasterArrays, compact
from .stop_plan import something_to_stop, stop_axes

#: a redefined position may be at most this many encoder counts from zero (float64 holds
#: every integer up to 2**53: beyond, positions could not be quantised to single counts)
MAX_POSITION_COUNTS = 2.0**53

__all__ = ["ConfigError", "Controller", "Pending", "ProcessFactory", "StatusArrays"]

#: a ramped stop mode (as a plain int: hashed in C) -> what follows the ramp
_AFTER_RAMP = {int(mode): action for mode, action in AFTER_FAST_STOP.items()}
#: an axis's programmed stop mode, read without a Python call per axis
_PROGRAMMED_STOP_MODE = attrgetter("config.programmed_stop_mode")
_CONFIG = attrgetter("config")
_AFTER_STOP = attrgetter("_after_stop")
_INDEX = attrgetter("index")
_SERVO_CONTROL_INT = int(AxisState.SERVO_CONTROL)  # (numpy compares a plain int faster)
_DECEL_BIT = 2  # MotionStatus bit 1; bit 0 (Accel) is added as a boolean
# read every cycle, as a module constant (see .enums)
_RUN = OperatingMode.RUN


class ConfigError(ValueError):
    """The kernel configuration is inconsistent (raised at construction only)."""


class StatusArrays(NamedTuple):
    """The status words of every axis, in axis index order (read-only views, valid until
    the next call into the kernel)."""

    axis_state: np.ndarray  # int(Axis.state)
    plcopen_state: np.ndarray  # int(Axis.plcopen_state)
    motion_status: np.ndarray  # Axis.motion_status
    fault: np.ndarray  # Axis.fault


def _readonly(a: np.ndarray) -> np.ndarray:
    v = a.view()
    v.flags.writeable = False
    return v


class Controller:
    def __init__(
        self,
        axes: Sequence[AxisConfig],
        groups: Sequence[GroupConfig],
        lanes: bool | None = None,
        cams: Sequence[CamTableConfig] = (),
    ) -> None:
        """``cams`` declares the cam tables (:mod:`.cam_tables`). ``lanes=False``
        composes every axis in Python (the reference the fast lanes
        are tested against); ``lanes=True`` offers the fast lanes to every group; None
        (the default) to groups of at least ``LANE_MIN_AXES`` axes, as a few axes compose
        faster in Python."""
        if not groups:
            raise ConfigError("at least one motion group is required")
        self._check_unique([a.number for a in axes], "axis number")
        self._check_unique([a.name for a in axes], "axis name")
        self._check_unique([g.number for g in groups], "group number")
        self.arrays = s = AxisArrays(axes)
        # the arrays under their historic names (front-ends and tools read them)
        self.cmd_pos, self.cmd_vel, self.cmd_acc = s.cmd_pos, s.cmd_vel, s.cmd_acc
        self.act_x, self.act_pos, self.act_vel = s.act_x, s.act_pos, s.act_vel
        self.drv_cmd, self.drive_on = s.drv_cmd, s.drive_on
        self.omega, self.cpu, self.conversion = s.omega, s.cpu, s.conversion
        self.coast, self.fe_limit = s.coast, s.fe_limit
        self.rollover, self.rotary_idx = s.rollover, s.rotary_idx
        self.axes: list[Axis] = [Axis(s, cfg, i) for i, cfg in enumerate(axes)]
        self._by_number = {a.number: a for a in self.axes}
        self._by_name = {a.name: a for a in self.axes}
        self.groups = self._build_groups(groups)
        self._groups_by_number = {g.number: g for g in self.groups}
        self.lanes_enabled = lanes is not False
        self.drive = DriveModel(s)
        self.motion = Motion(s, self.axes, self.groups, lanes)
        #: the failures :meth:`take_internal_errors` takes (a host tests it each cycle)
        self.internal_errors: Sequence[InternalError] = self.motion.internal_errors
        self.power = Power(self.motion, self.drive)
        #: MDAC master assignments (master-driven speed control)
        self.mdsc = MasterDrivenControl(self.motion)
        #: homing sensors (home switch, marker) and the homings waiting for their events
        self.homing = Homing(self.motion, self.axes, self.groups)
        #: fault causes a test bench holds on axes (:mod:`.faults`)
        self.faults = FaultInjection()
        #: cam tables and their profiles (MCCP, MC_CamTableSelect; :mod:`.cam_tables`)
        try:
            self.cams = CamStore(cams)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        self.tick = 0
        #: depth of :meth:`batch` blocks entered
        self._batched = 0
        self.mode = OperatingMode.RUN
        #: per group: its axes that are not feedback only (those a group stop stops)
        self._motion_axes = {
            g.number: [ax for ax in g.axes if ax.type != AxisType.FEEDBACK_ONLY]
            for g in self.groups
        }
        #: per group: the configurations of its motion axes and, read from them, their
        #: maximum decelerations and velocities, which a group stop's ramps need
        #: (:meth:`_group_stop_limits`)
        self._stop_limits: dict[int, tuple[list[AxisConfig], np.ndarray, np.ndarray]] = {}
        for g in self.groups:
            self._group_stop_limits(g.number)
        #: per group: its motion axes' indices as a slice when consecutive (:meth:`_group_at`),
        #: found here rather than in the stop's cycle
        self._stop_at: dict[int, Index] = {g.number: compact(g.motion_idx) for g in self.groups}
        #: per group: compose one axis in Python now (and offer it to the lanes)
        self._composers = {g.number: self._composer(g) for g in self.groups}
        #: the groups whose processes may join fast lanes (the others' lanes stay empty)
        self._laned = frozenset(g.number for g in self.groups if self.motion.offers(g.number))
        self._status_views = (
            _readonly(s.axis_state),
            _readonly(s.plcopen_state),
            _readonly(s.fault),
        )

    def _composer(self, g: MotionGroup) -> Callable[[Axis], None]:
        motion = self.motion
        dt = g.period
        if not motion.offers(g.number):
            # a group without fast lanes: nothing to offer (a call saved per axis and cycle)
            return functools.partial(motion.compose, dt=dt)

        def compose(ax: Axis) -> None:
            motion.compose(ax, dt)
            motion.offer(ax)

        return compose

    @staticmethod
    def _check_unique(values: Iterable[object], what: str) -> None:
        seen: set[object] = set()
        for v in values:
            if v in seen:
                raise ConfigError(f"duplicate {what}: {v}")
            seen.add(v)

    def _build_groups(self, groups: Sequence[GroupConfig]) -> list[MotionGroup]:
        for g in groups:
            if not MIN_PERIOD - 1e-12 <= g.coarse_update_period <= MAX_PERIOD + 1e-12:
                raise ConfigError(
                    f"group {g.name}: coarse_update_period {g.coarse_update_period} s is outside "
                    f"[{MIN_PERIOD}, {MAX_PERIOD}]"
                )
        self.period = min(g.coarse_update_period for g in groups)
        built: list[MotionGroup] = []
        seen: dict[int, str] = {}
        for g in groups:
            every = round(g.coarse_update_period / self.period)
            if abs(every * self.period - g.coarse_update_period) > 1e-9:
                raise ConfigError(
                    f"group {g.name}: period {g.coarse_update_period} s is not a multiple of "
                    f"the fastest group period {self.period} s"
                )
            members = []
            for num in g.axes:
                if num not in self._by_number:
                    raise ConfigError(f"group {g.name}: axis {num} is not configured")
                if num in seen:
                    raise ConfigError(f"axis {num} is in groups {seen[num]} and {g.name}")
                seen[num] = g.name
                ax = self._by_number[num]
                ax.group = g.number
                ax.period = g.coarse_update_period
                members.append(ax)
            built.append(MotionGroup(g, members, every))
        orphans = [a.name for a in self.axes if a.number not in seen]
        if orphans:
            raise ConfigError(f"axes not in any motion group: {', '.join(orphans)}")
        return built

    # -- look-up ----------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.tick * self.period

    @property
    def profile_fallbacks(self) -> int:
        """Jerk-limited velocity targets the closed form left to ruckig (:mod:`.scurve`),
        counted in this OS process since it started (the scan runs one controller)."""
        return FALLBACKS.count

    def axis(self, ref: int | str) -> Axis:
        ax = self._by_number.get(ref) if isinstance(ref, int) else self._by_name.get(ref)
        if ax is None:
            raise MotionError(ErrorCode.AXIS_NOT_CONFIGURED, f"axis {ref} is not configured")
        return ax

    def group(self, ref: int | str) -> MotionGroup:
        if isinstance(ref, int):
            grp = self._groups_by_number.get(ref)
        else:
            grp = next((g for g in self.groups if g.name == ref), None)
        if grp is None:
            raise MotionError(ErrorCode.GROUP_NOT_CONFIGURED, f"group {ref} is not configured")
        return grp

    def dt(self, axis: Axis) -> float:
        return axis.period

    # the step context of processes built by instructions with the controller
    def master_arrays(self, reference: MasterReference) -> MasterArrays:
        return self.arrays.master_arrays(reference)

    def read_master(self, index: int, reference: MasterReference) -> tuple[float, float]:
        return self.arrays.read_master(index, reference)

    def index_of(self, number: int) -> int:
        return self.arrays.index_of(number)

    # -- stepping ---------------------------------------------------------------------------
    def step(self) -> None:
        """Advance one base period."""
        self.tick += 1
        if self.motion.order_dirty:
            self.motion.sort()
        if self._batched:
            self._step_groups()
        else:
            with np.errstate(all="ignore"):  # non-finite values are checked, not warned about
                self._step_groups()
        self.mdsc.update()

    def _step_groups(self) -> None:
        """Step the groups whose period ends at this tick."""
        for g in self.groups:
            if self.tick % g.every == 0:
                self._step_group(g)

    @contextmanager
    def batch(self) -> Iterator[None]:
        """Steps taken inside share one numpy error state (non-finite values are screened,
        not warned about), set once: set by each step on its own, entering and leaving it
        costs as much as a small group's drive update."""
        with np.errstate(all="ignore"):
            self._batched += 1
            try:
                yield
            finally:
                self._batched -= 1

    def run(self, cycles: int) -> None:
        with self.batch():
            for _ in range(cycles):
                self.step()

    def _step_group(self, g: MotionGroup) -> None:
        dt = g.period
        g.cycles += 1
        s = self.arrays
        motion = self.motion
        for ax in g.feedback_axes:
            problem = self.drive.sample_feedback(ax, g.time, dt)
            if problem is not None:
                self._numeric_fault(ax, "feedback", problem)
        lanes = motion.lanes[g.number]
        if lanes.dirty or lanes.joined or lanes.handed or lanes.followed:
            lanes.rebuild(s, self.axes)
        compose = self._composers[g.number]
        if g.number in self._laned:
            lanes.step(s, dt, compose)
        for ax in lanes.python_order:
            # (Axis.processes without the property's call: an axis composed in Python
            # has no stop row, see lanes.group)
            if ax._processes or ax.buffered is not None or ax.stop_rows is not None:
                compose(ax)
        if not s.commands_finite():
            for i in self.drive.repair_commands(g.idx):
                self._numeric_fault(self.axes[i], "command", "the composed command is not finite")
        beyond = self.drive.follow(g.servo_idx, dt, servo=True)
        self.drive.follow(g.virtual_idx, dt, servo=False)
        if not s.actuals_finite():
            repaired = self.drive.repair_actuals(g.idx)
            for i in repaired:
                self._numeric_fault(self.axes[i], "drive model", "the drive state is not finite")
            beyond = [i for i in beyond if i not in repaired]  # held at their command
        for i in beyond:
            self.fault(self.axes[i], AxisFault.POSITION_ERROR)
        if g.number in self.homing.groups:
            self.homing.update(g.number)
        if self.faults.limits:
            self._overtravel(g)
        if g.after_stops:
            due, g.after_stops = after_stops_due(s, g, dt)
            if len(due) > 1 and self.lanes_enabled:
                self._after_stops(due)
            else:
                for ax in due:
                    action, ax.after_stop = ax.after_stop, AfterStop.NOTHING
                    if ax.state != AxisState.SERVO_CONTROL:
                        continue  # (leaving Servo Control drops the action; kept for safety)
                    event = (
                        PowerEvent.STOPPED_DISABLE
                        if action == AfterStop.DISABLE
                        else PowerEvent.STOPPED_SHUTDOWN
                    )
                    self.power.fire(ax, event)
        if g.stops:
            for stop in g.stops:
                stop.update(s)
            g.stops = [stop for stop in g.stops if not stop.complete]

    def _after_stops(self, due: list[Axis]) -> None:
        """The after-stop actions of ``due`` (axes of one group come to rest after a
        fast disable or shutdown), the drives off in two batches
        (:func:`.power_plan.power_off_axes`): each axis's event concerns it alone, so
        the order of the axes does not matter."""
        actions = list(map(_AFTER_STOP, due))
        first = actions[0]
        idx = np.fromiter(map(_INDEX, due), np.intp, len(due))
        if (
            actions.count(first) == len(actions)
            and (self.arrays.axis_state[idx] == _SERVO_CONTROL_INT).all()
        ):
            # one action for all, every axis in Servo Control (a group come to rest):
            # the drives off in one batch, which drops the action as Power._enter does
            disabling = first == AfterStop.DISABLE
            power_off_axes(
                self.motion,
                due,
                AxisState.AXIS_READY if disabling else AxisState.AXIS_SHUTDOWN,
                PowerEvent.STOPPED_DISABLE if disabling else PowerEvent.STOPPED_SHUTDOWN,
                self.drive.switched,
                idx=idx,
            )
            return
        disable: list[Axis] = []
        shutdown: list[Axis] = []
        for ax in due:
            action = ax.after_stop
            ax.after_stop = AfterStop.NOTHING
            if ax.state == AxisState.SERVO_CONTROL:
                (disable if action == AfterStop.DISABLE else shutdown).append(ax)
        switched = self.drive.switched
        power_off_axes(
            self.motion, disable, AxisState.AXIS_READY, PowerEvent.STOPPED_DISABLE, switched
        )
        power_off_axes(
            self.motion, shutdown, AxisState.AXIS_SHUTDOWN, PowerEvent.STOPPED_SHUTDOWN, switched
        )

    def _numeric_fault(self, ax: Axis, where: str, problem: str) -> None:
        self.motion.internal_errors.append((ax.name, where, FloatingPointError(problem)))
        self.fault(ax, AxisFault.NUMERIC)

    def take_internal_errors(self) -> list[InternalError]:
        """Unexpected failures since the last call, for the host to log: (axis name, what
        failed (a process's repr, "feedback", "command", "drive model"), the exception).
        The process concerned ended with ERR ``INTERNAL_ERROR`` (its axis ramped to rest);
        a value that was not finite faulted its axis (``AxisFault.NUMERIC``)."""
        errors = self.motion.internal_errors
        out = errors.copy()
        errors.clear()
        return out

    # -- status -----------------------------------------------------------------------------
    def status_arrays(self) -> StatusArrays:
        """AxisState, PLCopenState, MotionStatus and AxisFault of every axis as integer
        arrays (axis index order), equal to the axes' properties at any moment between
        kernel calls. Costs Python work only for axes whose processes, power state or
        latches changed since the last call, and a few array operations. The first
        three arrays are read-only views of the kernel's own (valid until the next call
        into the kernel); MotionStatus is computed afresh."""
        s = self.arrays
        if s.dirty:
            status_words.derive(s, self.axes)
        # the Accel and Decel bits: the sign of velocity x acceleration (Axis.motion_status)
        prod = s.cmd_vel * s.cmd_acc
        status = s.motion_bits + (prod > 0.0)
        status += (prod < 0.0) * _DECEL_BIT
        return StatusArrays(
            self._status_views[0], self._status_views[1], status, self._status_views[2]
        )

    # -- power ------------------------------------------------------------------------------
    def servo_on(self, ax: Axis) -> None:
        """MSO / MC_Power on."""
        self.power.fire(ax, PowerEvent.SERVO_ON)

    def servo_off(self, ax: Axis) -> None:
        """MSF / MC_Power off / hard disable: drive off at once, the axis coasts."""
        self.power.fire(ax, PowerEvent.SERVO_OFF)

    def fault(self, ax: Axis, bits: int) -> None:
        ax.fault |= int(bits)
        self.power.fire(ax, PowerEvent.FAULT)

    def fault_axes(self, axes: Iterable[Axis], bits: int) -> None:
        """:meth:`fault` on each of ``axes`` in order with the same ``bits``, in one pass
        (:meth:`Power.fire_all <.power.Power.fire_all>`): a watchdog faulting its group."""
        self.power.fire_all(axes, PowerEvent.FAULT, set_bits=bits)

    def fault_reset_axes(self, axes: Iterable[Axis]) -> None:
        """:meth:`fault_reset` on each of ``axes`` in order, in one pass while no injected
        Disable Drive cause is held (one held faults its axis again: axis by axis then)."""
        if self.faults.held:
            for ax in axes:
                self.fault_reset(ax)
            return
        self.power.fire_all(axes, PowerEvent.FAULT_RESET, clear=True)

    def shutdown_reset_axes(self, axes: Iterable[Axis]) -> None:
        """:meth:`shutdown_reset` on each of ``axes`` in order, in one pass (MGSR), as
        :meth:`fault_reset_axes`."""
        if self.faults.held:
            for ax in axes:
                self.shutdown_reset(ax)
            return
        self.power.fire_all(axes, PowerEvent.SHUTDOWN_RESET, clear=True)

    def fault_reset(self, ax: Axis) -> None:
        """MAFR / MC_Reset: clear faults; a faulted axis returns to Axis Ready. An injected
        Disable Drive cause still held faults it again at once (:mod:`.faults`)."""
        ax.fault = 0
        self.power.fire(ax, PowerEvent.FAULT_RESET)
        self._reassert(ax)

    def shutdown(self, ax: Axis) -> None:
        """MASD: Axis Shutdown at once; the drive is off and the axis coasts.

        The axis's MDAC links break (as slave and as master), and every process on another
        axis that follows it (master-driven motion, gearing) is released: see
        :meth:`release_followers`.
        """
        self._shutdown(ax, None)

    def _shutdown(self, ax: Axis, followers: dict[int, list[Axis]] | None) -> None:
        """:meth:`shutdown`; ``followers``: :meth:`Motion.followers
        <.motion.Motion.followers>` taken before a series of shutdowns (a group stop)."""
        self.mdsc.break_axis(ax, AbortReason.SHUTDOWN)
        self.power.fire(ax, PowerEvent.SHUTDOWN)
        among = None if followers is None else followers.get(ax.number, [])
        self.motion.release_followers(ax, AbortReason.SHUTDOWN, among)

    def shutdown_reset(self, ax: Axis) -> None:
        """MASR: from Axis Shutdown (or faulted) to Axis Ready, faults cleared."""
        ax.fault = 0
        self.power.fire(ax, PowerEvent.SHUTDOWN_RESET)
        self._reassert(ax)

    def group_shutdown(self, ref: int | str) -> MotionGroup:
        """MGSD: every axis of the group (feedback-only ones too) to Axis Shutdown, one
        after the other in the group's order. With the lanes, when every driven axis is
        in Servo Control, no MDAC link is left to break and the feedback-only axes come
        after the driven ones, the driven axes are shut down as one batch, as a Hard
        Shutdown group stop shuts them down (:meth:`_power_off`: the same result, each
        axis's followers released before the next axis), then the feedback-only ones.
        Otherwise, with the lanes, the axes that read each master are found once for all
        the shutdowns (:meth:`Motion.followers <.motion.Motion.followers>`), not by a
        search of every axis for each axis shut down (1,024 axes: 0.6 s)."""
        g = self.group(ref)
        if not self.lanes_enabled:
            for ax in g.axes:
                self.shutdown(ax)
            return g
        axes = self._motion_axes[g.number]
        rest: Sequence[Axis] = g.axes
        if (
            axes
            and not self.mdsc.linked
            and g.axes[: len(axes)] == axes
            and self._all_in_servo_control(g)
        ):
            self._power_off(g, ProgrammedStopMode.HARD_SHUTDOWN)
            rest = g.axes[len(axes) :]
        if rest:
            followers = self.motion.followers()
            for ax in rest:
                self._shutdown(ax, followers)
        return g

    def group_shutdown_reset(self, ref: int | str) -> MotionGroup:
        """MGSR: every axis of the group from Axis Shutdown (or faulted) to Axis Ready."""
        g = self.group(ref)
        self.shutdown_reset_axes(g.axes)
        return g

    def release_followers(self, master: Axis, reason: AbortReason) -> None:
        """Release every process on another axis that reads ``master``: a shut-down master
        no longer drives anything (see :meth:`release`)."""
        self.motion.release_followers(master, reason)

    def release(self, ax: Axis, processes: Collection[Process], reason: AbortReason) -> None:
        """Switch ``processes`` of ``ax`` to a time-driven stop at its maximum deceleration
        (see :meth:`Motion.release <.motion.Motion.release>`)."""
        self.motion.release(ax, processes, reason)

    # -- injected faults --------------------------------------------------------------------
    def inject(self, ax: Axis, cause: FaultCause, held: bool) -> None:
        """Hold (``held``) or remove a fault cause on ``ax``, as a test bench makes a drive,
        an encoder or a limit switch fail (:mod:`.faults`). Holding it faults the axis at
        once; removing it lets MAFR / MC_Reset clear the fault. MotionError
        ``WRONG_AXIS_TYPE`` for a cause the axis type does not have."""
        cause = FaultCause(cause)
        if cause not in APPLIES[ax.type]:
            raise MotionError(
                ErrorCode.WRONG_AXIS_TYPE,
                f"{ax.name} is a {ax.type.name.lower()} axis: no {cause.name.lower()} fault",
            )
        faults = self.faults
        if not held:
            if faults.holds(ax.index, cause):
                faults.release(ax.index, cause)
            return
        if faults.holds(ax.index, cause):
            return
        limit = float(self.act_pos[ax.index]) if cause in OVERTRAVEL else None
        faults.hold(ax.index, cause, limit)
        bit = CAUSE_BIT[cause]
        if cause in DISABLE_DRIVE or ax.state != AxisState.SERVO_CONTROL:
            self.fault(ax, bit)
        else:
            self.fault_stop(ax, bit)

    def fault_stop(self, ax: Axis, bits: int) -> None:
        """A fault whose action is Stop Planner (an overtravel): the fault bits are set,
        every process is replaced by a ramp to rest at the maximum deceleration, and the
        axis stays in Servo Control with its drive on (PLCopen ErrorStop)."""
        ax.fault |= int(bits)
        if ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        if not any(p.active for p in ax.processes):
            return
        self.mdsc.break_slave(ax, AbortReason.FAULTED)
        dt = ax.period
        decel = ax.config.max_deceleration

        def make(v: float, a: float) -> Process:
            return StopRamp(dt, decel, 0.0, v, a)

        self.motion.start(ax, make, replace=None, reason=AbortReason.FAULTED)

    def _reassert(self, ax: Axis) -> None:
        """After a reset: the Disable Drive causes still held fault the axis again."""
        if self.faults.held:
            bits = self.faults.disable_drive_bits(ax.index)
            if bits:
                self.fault(ax, bits)

    def _overtravel(self, g: MotionGroup) -> None:
        """Axes of ``g`` beyond an injected limit: back inside ends the cause; motion
        further beyond ends the processes that drive it (ERR ``OVERTRAVEL``), ramps the
        axis to rest and sets the fault again."""
        s = self.arrays
        faults = self.faults
        for (i, cause), limit in list(faults.limits.items()):
            ax = self.axes[i]
            if ax.group != g.number:
                continue
            d = OVERTRAVEL[cause]
            if (s.act_pos.item(i) - limit) * d < 0.0:
                faults.release(i, cause)
            elif s.cmd_vel.item(i) * d > 0.0 and ax.drive_enabled:
                self.motion.settle(ax)
                further = [
                    p
                    for p in ax.processes
                    if p.active and p.kind != ProcessKind.STOP and p.velocity * d > 0.0
                ]
                if further:
                    self.motion.fail(ax, further, ErrorCode.OVERTRAVEL)
                    ax.fault |= int(CAUSE_BIT[cause])

    # -- operating mode ---------------------------------------------------------------------
    def set_mode(self, mode: OperatingMode) -> list[GroupStop]:
        """Change the operating mode. Leaving RUN breaks every MDAC link and runs the
        programmed stop of every group; the returned handles tell when they are done."""
        if mode == self.mode:
            return []
        self.mode = mode
        if self.mdsc.linked:  # (no link, no pending reassignment: nothing to break)
            self.mdsc.break_all(AbortReason.STOPPED)
        if mode == OperatingMode.RUN:
            return []
        return [self.group_stop(g.number) for g in self.groups]

    @property
    def run_mode(self) -> bool:
        return self.mode == _RUN

    # -- motion -----------------------------------------------------------------------------
    def require_motion(self, ax: Axis) -> None:
        """Preconditions of every motion command, as a controller checks them."""
        require(ax, PowerEvent.MOTION)
        if ax.fault:  # in Servo Control: a Stop Planner fault (an overtravel) not reset
            raise MotionError(ErrorCode.AXIS_FAULTED, f"{ax.name} is faulted")

    def settle(self, ax: Axis) -> None:
        """Bring ``ax``'s processes up to date and take it out of the fast lanes."""
        self.motion.settle(ax)

    def coupling_changed(self) -> None:
        """Call after adding or removing a process that has masters."""
        self.motion.coupling_changed()

    def would_cycle(self, slave: int, masters: Collection[int]) -> bool:
        """True if making ``slave`` follow ``masters`` closes a loop of master/slave links."""
        return self.motion.would_cycle(slave, masters)

    def start(
        self,
        ax: Axis,
        make: ProcessFactory,
        replace: Collection[ProcessKind] | None = (),
        reason: AbortReason = AbortReason.SUPERSEDED,
    ) -> Process:
        """Start a process built by ``make(v, a)`` (see :meth:`Motion.start
        <.motion.Motion.start>`)."""
        return self.motion.start(ax, make, replace, reason)

    def start_jogs(
        self,
        axes: Sequence[Axis],
        targets: Sequence[float],
        limits: Limits,
        owners: Sequence[object] | None = None,
        replace: Collection[ProcessKind] | None = (ProcessKind.JOG,),
    ) -> list[Process]:
        """Jogs on many axes in one call (MAJ or MC_MoveVelocity executed on N axes in
        one scan): ``start`` of ``JogProcess(period, targets[k], limits, v, a,
        owners[k])`` replacing the jog of ``axes[k]`` (``replace``: the kinds replaced,
        None for every process), for every k in order, the same state, for less work per
        axis (:func:`.jog_batch.start_jogs`)."""
        return start_jogs(self.motion, axes, targets, limits, owners, replace)

    def start_moves(
        self,
        axes: Sequence[Axis],
        distances: Sequence[float],
        limits: Limits,
        owners: Sequence[object] | None = None,
        landings: Sequence[float | None] | None = None,
        replace: Collection[ProcessKind] | None = (ProcessKind.MOVE,),
    ) -> list[Process]:
        """Moves on many axes in one call (MAM, MC_MoveAbsolute or MC_MoveRelative
        executed on N axes in one scan): ``start`` of ``MoveProcess(period,
        distances[k], limits, v, a, owners[k], landings[k])`` replacing the move of
        ``axes[k]`` (``replace``: the kinds replaced, None for every process), for every
        k in order, the same state, for less work per axis
        (:func:`.move_batch.start_moves`)."""
        return start_moves(self.motion, axes, distances, limits, owners, landings, replace)

    def start_gears(
        self,
        slaves: Sequence[Axis],
        terms: Sequence[GearTerm],
        clutch_rates: Sequence[Rate],
        owners: Sequence[object] | None = None,
        directions: Sequence[int] | None = None,
        replace: Collection[ProcessKind] | None = (ProcessKind.GEAR,),
    ) -> list[Process]:
        """Gears on many slaves in one call (MAG or MC_GearIn executed on N slaves in one
        scan): ``start`` of ``GearProcess(ctl, slaves[k], (terms[k],), ramp, v, a,
        owners[k], directions[k])`` replacing the gear of ``slaves[k]`` (``replace``: the
        kinds replaced, None for every process), ``ramp`` a ``RateRamp(clutch_rates[k])``
        (a pair: ``RateRamp(acceleration, deceleration)``; None: no clutch, locked at
        once), for every k in order, the same state, for less work per slave
        (:func:`.gear_batch.start_gears`)."""
        return start_gears(self.motion, slaves, terms, clutch_rates, owners, directions, replace)

    def set_override(self, ax: Axis, factors: Override) -> None:
        """Scale the axis's moves and jogs (see :meth:`Motion.set_override
        <.motion.Motion.set_override>`)."""
        self.motion.set_override(ax, factors)

    def buffer(self, ax: Axis, make: ProcessFactory, owner: object = None) -> Pending:
        """Queue ``make`` to start when the axis's active motion is done (PLCopen buffered)."""
        return self.motion.buffer(ax, make, owner)

    def abort(self, ax: Axis, reason: AbortReason) -> None:
        """End every process on the axis at once (no ramp): disable, shutdown, fault."""
        self.motion.abort(ax, reason)

    def stop(
        self,
        ax: Axis,
        kinds: Collection[ProcessKind] | None,
        deceleration: float,
        jerk: float = 0.0,
        owner: object = None,
        bounded: bool = False,
    ) -> StopRamp:
        """Replace the matching processes by one ramp from their velocity to rest.
        ``bounded``: from beyond the Maximum Speed the ramp is steeper, so that it ends
        within the time a stop from the Maximum Speed at ``deceleration`` needs (a group
        stop, see :func:`.limits.group_stop_deceleration`)."""
        dt = ax.period
        vmax = ax.config.max_velocity

        def make(v: float, a: float) -> Process:
            d = group_stop_deceleration(v, deceleration, vmax) if bounded else deceleration
            return StopRamp(dt, d, jerk, v, a, owner=owner)

        if deceleration <= 0.0 or not math.isfinite(deceleration):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "deceleration must be > 0")
        if kinds is None and ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        if kinds is None:
            # a stop of all motion breaks the axis's MDAC links as slave (MAS All)
            self.mdsc.break_slave(ax, AbortReason.STOPPED)
        ramp = self.motion.start(ax, make, replace=kinds, reason=AbortReason.STOPPED)
        assert isinstance(ramp, StopRamp)
        return ramp

    def stop_many(
        self,
        axes: Sequence[Axis],
        decelerations: Sequence[float],
        owners: Sequence[object],
        halt: bool = False,
    ) -> list[StopRamp]:
        """``stop(axes[k], None, decelerations[k], owner=owners[k])`` for every k in
        order (MAS stopping all motion, executed on many axes in one scan): the same
        ramps, the same state. When the axes are distinct, of one group with fast lanes,
        in Servo Control, each with something to stop and no cam preloaded, and no MDAC
        link exists, their ramps are planned as one batch (:func:`.stop_plan.stop_axes`,
        the group stop's, without its bound at the Maximum Speed) and each ramp's object
        made for its owner; else, or if the batch would refuse one, one by one (which
        raises where the loop raises).

        ``halt``: the halts of MC_Halt instead (aborting mode, no jerk), each
        ``start(axes[k], lambda v, a: StopRamp(period, decelerations[k], 0.0, v, a,
        owners[k], stopping=False), replace=None)``: the processes replaced are
        superseded, not stopped, and the axis is not Stopping."""
        n = len(axes)
        if len(decelerations) != n or len(owners) != n:
            raise ValueError("one deceleration and one owner per axis")
        if n and self._stops_as_batch(axes, decelerations):
            group = axes[0].group
            at = {ax.index: k for k, ax in enumerate(self._motion_axes[group])}
            # in group order (the ramps of distinct axes do not depend on each other)
            order = sorted(range(n), key=lambda k: at[axes[k].index])
            batch = [axes[k] for k in order]
            dec = np.array([decelerations[k] for k in order], dtype=float)
            unbounded = np.full(n, math.inf)
            reason = AbortReason.SUPERSEDED if halt else AbortReason.STOPPED
            if stop_axes(
                self.motion, batch, None, reason, maxima=(dec, unbounded), stopping=not halt
            ):
                ramps: list[StopRamp] = [cast(StopRamp, None)] * n
                for k in order:
                    r = axes[k].processes[0]  # (a row of the stop lane: its object made)
                    assert isinstance(r, StopRamp)
                    r.owner = owners[k]
                    ramps[k] = r
                return ramps
        if halt:
            return [
                self._halt(ax, d, o) for ax, d, o in zip(axes, decelerations, owners, strict=True)
            ]
        return [
            self.stop(ax, None, d, owner=o)
            for ax, d, o in zip(axes, decelerations, owners, strict=True)
        ]

    def _halt(self, ax: Axis, deceleration: float, owner: object) -> StopRamp:
        """MC_Halt's trapezoidal halt of ``ax`` (aborting mode): a ramp to rest that
        replaces every process, the axis not Stopping."""
        ramp = self.motion.start(ax, halt_ramp(ax.period, deceleration, 0.0, owner), None)
        assert isinstance(ramp, StopRamp)
        return ramp

    def _stops_as_batch(self, axes: Sequence[Axis], decelerations: Sequence[float]) -> bool:
        """:meth:`stop_many` can plan these stops as one batch (see there)."""
        if not self.lanes_enabled or self.mdsc.linked:
            return False
        group = axes[0].group
        if len({ax.index for ax in axes}) != len(axes) or any(ax.group != group for ax in axes):
            return False
        if not all(d > 0.0 and math.isfinite(d) for d in decelerations):
            return False
        return all(
            ax.state == AxisState.SERVO_CONTROL
            and ax.type != AxisType.FEEDBACK_ONLY
            and something_to_stop(ax)
            and not ax.preloaded_cams
            for ax in axes
        )

    def group_stop(
        self, ref: int | str, forced: ProgrammedStopMode | None = None, owner: object = None
    ) -> GroupStop:
        """Stop every axis of a group by its programmed stop mode, or by ``forced`` (MGS).

        - Fast Stop: decelerate at the axis maximum deceleration, stay in Servo Control.
        - Fast Disable / Fast Shutdown: the same ramp, then (once the drive has settled)
          Axis Ready / Axis Shutdown with the drive off.
        - Hard Disable / Hard Shutdown: drive off at once, the axis coasts at its coast
          deceleration (Axis Ready / Axis Shutdown).

        Ramps are always trapezoidal (no jerk limit) and time-driven, whatever the profile
        and speed units of the motion they replace. Every MDAC link with an axis of the
        group as slave or master breaks and pending reassignments are cleared; the MDAC's
        AC stays set until the slave has stopped.
        """
        g = self.group(ref)
        handle = GroupStop(g, owner)
        if not self.lanes_enabled:
            return self._group_stop_by_axis(g, forced, handle)
        if self.mdsc.linked:
            for ax in g.axes:
                self.mdsc.break_axis(ax, AbortReason.STOPPED, hold_active=True)
        # the ramps of consecutive axes are planned together (:mod:`.stop_plan`), in axis
        # order: a shutdown, which releases the followers of its axis, comes after the
        # ramps of the axes before it, as it does axis by axis
        actions = self._all_ramping(g, forced)
        if actions is not None:
            # the common case: every axis ramps
            axes = self._motion_axes[g.number]
            maxima = self._group_stop_limits(g.number)
            at = self._group_at(g)
            if stop_axes(self.motion, axes, owner, idx=g.motion_idx, maxima=maxima, at=at):
                latch_stops(self.arrays, axes, g.motion_idx, actions, handle)
                g.after_stops = True
            else:
                self._ramp_to_rest(g, list(zip(axes, actions, strict=True)), handle)
            g.stops.append(handle)
            return handle
        hard = self._all_hard(g, forced)
        if hard is not None:
            # every axis in Servo Control, all Hard Disable or all Hard Shutdown
            self._power_off(g, hard)
            for ax in self._motion_axes[g.number]:
                ax.stop_latch = handle
            g.stops.append(handle)
            return handle
        ramping: list[tuple[Axis, AfterStop]] = []
        # who reads each master, found once for all the shutdowns of this stop
        followers: dict[int, list[Axis]] | None = None
        for ax in g.axes:
            if ax.type == AxisType.FEEDBACK_ONLY:
                continue
            mode = ax.programmed_stop_mode if forced is None else forced
            shuts = mode == ProgrammedStopMode.HARD_SHUTDOWN or (
                mode == ProgrammedStopMode.FAST_SHUTDOWN and ax.state != AxisState.SERVO_CONTROL
            )
            if shuts and followers is None:
                followers = self.motion.followers()
            if mode == ProgrammedStopMode.HARD_SHUTDOWN:
                self._ramp_to_rest(g, ramping, handle)
                self._shutdown(ax, followers)
            elif mode == ProgrammedStopMode.HARD_DISABLE:
                self._ramp_to_rest(g, ramping, handle)
                self.servo_off(ax)
            elif ax.state == AxisState.SERVO_CONTROL:
                ramping.append((ax, AFTER_FAST_STOP[mode]))
                continue  # latched with its ramp
            elif mode == ProgrammedStopMode.FAST_SHUTDOWN:
                self._ramp_to_rest(g, ramping, handle)
                self._shutdown(ax, followers)
            # StoppingStatus until the axis is at rest (coasting axes have no ramp)
            ax.stop_latch = handle
        self._ramp_to_rest(g, ramping, handle)
        g.stops.append(handle)
        return handle

    def _group_stop_limits(self, group: int) -> tuple[np.ndarray, np.ndarray]:
        """The maximum deceleration and velocity of each motion axis of ``group`` as
        arrays, read when the controller is built and again only when an axis's
        configuration changed (a limit written at run time replaces the configuration:
        :mod:`.appl_limits`); checked with one comparison of the configurations."""
        axes = self._motion_axes[group]
        configs = list(map(_CONFIG, axes))
        kept = getattr(self, "_stop_limits", {}).get(group)
        if kept is None or kept[0] != configs:
            kept = (
                configs,
                np.array([c.max_deceleration for c in configs], dtype=float),
                np.array([c.max_velocity for c in configs], dtype=float),
            )
            if not hasattr(self, "_stop_limits"):
                self._stop_limits = {}  # (a controller restored from older state)
            self._stop_limits[group] = kept
        return kept[1], kept[2]

    def _group_at(self, g: MotionGroup) -> Index:
        """The array indices of ``g``'s driven axes as :func:`.state.compact` gives them
        (a slice when consecutive: views instead of copies), found once per group."""
        kept: dict[int, Index] | None = getattr(self, "_stop_at", None)
        if kept is None:
            kept = {}  # (a controller restored from older state)
            self._stop_at = kept
        at = kept.get(g.number)
        if at is None:
            at = kept[g.number] = compact(g.motion_idx)
        return at

    def _all_in_servo_control(self, g: MotionGroup) -> bool:
        """Every driven axis of ``g`` is in Servo Control (one array comparison)."""
        return bool((self.arrays.axis_state[self._group_at(g)] == _SERVO_CONTROL_INT).all())

    def _all_ramping(
        self, g: MotionGroup, forced: ProgrammedStopMode | None
    ) -> list[AfterStop] | None:
        """If every driven axis of ``g`` is in Servo Control and stops with a ramp
        (Fast Stop, Fast Disable, Fast Shutdown): the action after the stop of each
        (``_motion_axes`` order), found with array operations; else None (the axes are
        then sorted one by one)."""
        forced_action = None if forced is None else _AFTER_RAMP.get(int(forced))
        if forced is not None and forced_action is None:
            return None  # (a forced Hard Disable or Hard Shutdown: no state to read)
        if not self._all_in_servo_control(g):
            return None
        axes = self._motion_axes[g.number]
        if forced_action is not None:
            return [forced_action] * len(axes)
        modes = list(map(_PROGRAMMED_STOP_MODE, axes))
        if modes and modes.count(modes[0]) == len(modes):
            # one programmed mode for all (the usual configuration): judged once
            action = _AFTER_RAMP.get(int(modes[0]))
            return None if action is None else [action] * len(axes)
        actions = [_AFTER_RAMP.get(int(mode)) for mode in modes]
        if None in actions:
            return None
        return cast(list[AfterStop], actions)

    def _all_hard(
        self, g: MotionGroup, forced: ProgrammedStopMode | None
    ) -> ProgrammedStopMode | None:
        """Hard Disable or Hard Shutdown if that is the mode of every driven axis of
        ``g`` and all are in Servo Control (and, for a shutdown, no MDAC link is left to
        break); else None."""
        axes = self._motion_axes[g.number]
        if not axes or not self._all_in_servo_control(g):
            return None
        if forced is None:
            modes = {int(ax.config.programmed_stop_mode) for ax in axes}
            if len(modes) != 1:
                return None
            mode = ProgrammedStopMode(modes.pop())
        else:
            mode = ProgrammedStopMode(forced)
        if mode == ProgrammedStopMode.HARD_DISABLE:
            return mode
        if mode == ProgrammedStopMode.HARD_SHUTDOWN and not self.mdsc.linked:
            return mode
        return None

    def _power_off(self, g: MotionGroup, mode: ProgrammedStopMode) -> None:
        """Every driven axis of ``g`` off at once (:func:`.power_plan.power_off_axes`),
        in axis order: Hard Disable (:meth:`servo_off` of each) or Hard Shutdown
        (:meth:`shutdown` of each: its followers are released before the next axis)."""
        axes = self._motion_axes[g.number]
        motion = self.motion
        if mode == ProgrammedStopMode.HARD_DISABLE:
            power_off_axes(
                motion,
                axes,
                AxisState.AXIS_READY,
                PowerEvent.SERVO_OFF,
                self.drive.switched,
                idx=g.motion_idx,
            )
            return
        # who reads each master, found (before any axis is shut down) only if the axes
        # are shut down one by one: the batch knows its followers without it
        followers: dict[int, list[Axis]] = {}

        def prepare() -> None:
            followers.update(motion.followers())

        def release(ax: Axis) -> None:
            motion.release_followers(ax, AbortReason.SHUTDOWN, followers.get(ax.number, []))

        power_off_axes(
            motion,
            axes,
            AxisState.AXIS_SHUTDOWN,
            PowerEvent.SHUTDOWN,
            self.drive.switched,
            release,
            releasing=True,
            prepare=prepare,
            maxima=self._group_stop_limits(g.number),
            idx=g.motion_idx,
        )

    def _group_stop_by_axis(
        self, g: MotionGroup, forced: ProgrammedStopMode | None, handle: GroupStop
    ) -> GroupStop:
        """:meth:`group_stop` one axis after the other: the reference the planned path
        is tested against (``Controller(lanes=False)``). An axis in Servo Control with
        nothing to stop (no process, nothing buffered, no cam preloaded: at rest) gets no
        ramp, only its latch and its action after the stop: a ramp from rest would be
        done at once and move nothing."""
        owner = handle.owner
        for ax in g.axes:
            self.mdsc.break_axis(ax, AbortReason.STOPPED, hold_active=True)
        for ax in g.axes:
            if ax.type == AxisType.FEEDBACK_ONLY:
                continue
            mode = ax.programmed_stop_mode if forced is None else forced
            if mode == ProgrammedStopMode.HARD_SHUTDOWN:
                self.shutdown(ax)
            elif mode == ProgrammedStopMode.HARD_DISABLE:
                self.servo_off(ax)
            elif ax.state == AxisState.SERVO_CONTROL:
                if something_to_stop(ax):
                    self.stop(ax, None, ax.config.max_deceleration, 0.0, owner, bounded=True)
                ax.after_stop = AFTER_FAST_STOP[mode]
                g.after_stops = True
            elif mode == ProgrammedStopMode.FAST_SHUTDOWN:
                self.shutdown(ax)
            ax.stop_latch = handle
        g.stops.append(handle)
        return handle

    def _ramp_to_rest(
        self, g: MotionGroup, ramping: list[tuple[Axis, AfterStop]], handle: GroupStop
    ) -> None:
        """The group stop ramps of the axes in ``ramping`` (in Servo Control, with the
        action after their stop), then empty the list: planned as one batch
        (:func:`.stop_plan.stop_axes`), or axis by axis when the batch would refuse one
        (then this raises where :meth:`_group_stop_by_axis` raises)."""
        if not ramping:
            return
        axes = [ax for ax, _ in ramping]
        owner = handle.owner
        idx = np.array([ax.index for ax in axes], dtype=np.intp)
        if not stop_axes(self.motion, axes, owner, idx=idx):
            for ax, action in ramping:
                if something_to_stop(ax):
                    self.stop(ax, None, ax.config.max_deceleration, 0.0, owner, bounded=True)
                ax.after_stop = action
                g.after_stops = True
                ax.stop_latch = handle
        else:
            latch_stops(self.arrays, axes, idx, [action for _, action in ramping], handle)
            g.after_stops = True
        ramping.clear()

    def group_stopping(self, ax: Axis) -> bool:
        """True while a group stop (MGS, leaving run mode) is bringing ``ax``'s group to
        rest."""
        g = self._groups_by_number[ax.group]
        return any(not s.complete for s in g.stops)

    def set_feedback_input(self, ax: Axis, position: float) -> None:
        """Hand-wheel reading of a feedback-only axis (taken at the next cycle)."""
        if not math.isfinite(position):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "feedback input must be finite")
        ax.feedback_input = float(position)

    # -- positions and homing -------------------------------------------------------------
    def redefine_position(
        self, ax: Axis, position: float, relative: bool = False, actual: bool = True
    ) -> float:
        """MRP / MC_SetPosition: the axis's actual (or command) position becomes
        ``position`` (``relative``: moves by it); the other moves with it, keeping the
        following error, and nothing moves (:mod:`.redefine`). Returns the shift."""
        require(ax, PowerEvent.REDEFINE)
        position = float(position)
        rollover = ax.config.rollover
        if not math.isfinite(position):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "position must be finite")
        if not relative and rollover > 0.0 and not 0.0 <= position < rollover:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"{ax.name} is rotary: an absolute position must be in [0, {rollover:g})",
            )
        here = ax.actual_position if actual else ax.command_position
        d = position if relative else position - here
        self._judge_shift(ax, d)
        exact = None if relative or rollover > 0.0 else position
        if actual:
            shift_coordinates(self.motion, ax, d, actual=exact)
        else:
            shift_coordinates(self.motion, ax, d, command=exact)
        return d

    def _judge_shift(self, ax: Axis, d: float) -> None:
        """A shift that would take a position beyond 2**53 counts is refused (ERR 13)."""
        i = ax.index
        cpu = max(float(self.cpu[i]), float(self.conversion[i]))
        reach = max(abs(float(self.cmd_pos[i]) + d), abs(float(self.act_x[i]) + d))
        if not (math.isfinite(d) and reach * cpu <= MAX_POSITION_COUNTS):
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"{ax.name}: the redefined position would lie beyond 2**53 counts",
            )

    def home(self, ax: Axis, req: HomeRequest, owner: object = None) -> HomeHandle | None:
        """Start a homing (MAH, MC_Home; :mod:`.homing`). Immediate and absolute homing
        is done at once (returns None); passive homing returns the watch waiting for its
        event, active homing its process, which replaces all motion on the axis
        (inheriting its velocity). Refused with MotionError before anything changes."""
        mode = req.mode
        if mode == HomeMode.ABSOLUTE:
            require(ax, PowerEvent.ABSOLUTE_HOME)
        elif mode == HomeMode.ACTIVE and not req.immediate:
            require(ax, PowerEvent.MOTION)
            if ax.stopping:
                raise MotionError(
                    ErrorCode.NOT_ALLOWED_WHILE_STOPPING, f"{ax.name} is stopping: homing refused"
                )
        else:
            require(ax, PowerEvent.REDEFINE)
        sensors = self.homing.sensors.get(ax.index)
        judge(ax, req, sensors)
        d = req.value - ax.actual_position
        if req.immediate:
            self._judge_shift(ax, d)
        if (mode != HomeMode.ACTIVE or req.immediate) and ax.active(ProcessKind.HOME):
            # an active sequence in progress is superseded: it ramps to rest
            self.stop(ax, (ProcessKind.HOME,), ax.config.max_deceleration)
        if req.immediate:
            self.homing.cancel(ax, AbortReason.SUPERSEDED)
            exact = req.value if ax.config.rollover <= 0.0 else None
            shift_coordinates(self.motion, ax, d, actual=exact)
            ax.homed = True
            return None
        if mode == HomeMode.PASSIVE:
            watch = PassiveHoming(ax, req, owner)
            self.homing.track(ax, watch)
            ax.homed = False
            return watch
        engaged = sensors is not None and sensors.engaged(self.homing.raw(ax))

        def make(v: float, a: float) -> Process:
            return HomeProcess(ax, req, engaged, v, a, owner=owner)

        proc = self.motion.start(ax, make, replace=None)
        assert isinstance(proc, HomeProcess)
        # "all other motion in process is canceled" (MAH): master-driven links too
        self.mdsc.break_slave(ax, AbortReason.SUPERSEDED)
        self.homing.track(ax, proc)
        ax.homed = False
        return proc

    def cancel_homing(self, ax: Axis) -> bool:
        """End a passive homing waiting on ``ax`` (MAS Home); True if there was one."""
        armed = ax.homing_armed is not None
        self.homing.cancel(ax, AbortReason.STOPPED)
        return armed

    def set_following_error_limit(self, ax: Axis, limit: float) -> None:
        """The position error that faults the axis (0: no limit), from now on (while the
        monitoring is on: :meth:`set_lag_monitoring`)."""
        if not (math.isfinite(limit) and limit >= 0.0):
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE, f"following error limit {limit!r} must be >= 0"
            )
        ax.lag_limit = float(limit)
        self._watch_lag(ax)

    def set_lag_monitoring(self, ax: Axis, on: bool) -> None:
        """Switch the following error monitoring on or off (the limit is kept). On needs a
        limit above 0 (MotionError 13)."""
        if on and not ax.lag_limit > 0.0:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"{ax.name} has no following error limit to monitor (MaxPositionLag is 0)",
            )
        ax.lag_monitoring = bool(on)
        self._watch_lag(ax)

    def _watch_lag(self, ax: Axis) -> None:
        self.fe_limit[ax.index] = ax.lag_limit if ax.lag_monitoring else 0.0
        self.drive.switched()  # the drive's partitions cache the limits
