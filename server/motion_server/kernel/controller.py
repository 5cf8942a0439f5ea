"""The controller: axes, groups and one deterministic ``step()``.

Sans-I/O: commands go in through methods, state comes out as plain values; simulated time
advances exactly one base period per step. Each group steps every ``every`` ticks with its
own coarse update period. Within a group step:

1. feedback-only axes sample their input or signal (the feedback of the cycle);
2. every axis with motion processes composes its command, masters before slaves;
3. drives follow the command (vectorised): a critically damped second-order loop for servo
   axes (the command interpolated linearly across the cycle, as a drive does), actual =
   command for virtual axes, coasting at the coast deceleration for axes whose drive is
   off; actual positions are quantised to encoder counts;
4. following error is checked, and after-stop actions (disable, shutdown) are applied
   once the axis has come to rest.

Axes in a steady state (a jog at speed, a locked real-ratio gear) are composed as arrays
in step 2 (:mod:`.lanes`); whatever touches an axis's motion first calls :meth:`settle`.
``Controller.mdsc`` holds the MDAC links (:mod:`.mdac_links`, :mod:`.master_driven`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Iterable, Sequence

import numpy as np

from .axis import Axis
from .config import MAX_PERIOD, MIN_PERIOD, AxisConfig, GroupConfig
from .enums import (
    AbortReason,
    AfterStop,
    AxisFault,
    AxisState,
    AxisType,
    FeedbackSignal,
    ProcessKind,
    ProcessState,
    ProgrammedStopMode,
)
from .errors import ErrorCode, MotionError
from .group import AFTER_FAST_STOP, GroupStop, MotionGroup, OperatingMode
from .lanes import GroupLanes
from .mdac_links import MasterDrivenControl
from .processes import Process, StopRamp

ProcessFactory = Callable[[float, float], Process]


def _rounding_apart(x: float, y: float) -> bool:
    """True when ``x`` and ``y`` differ by no more than accumulated rounding."""
    return abs(x - y) <= 1e-9 * max(1.0, abs(y))


class ConfigError(ValueError):
    """The kernel configuration is inconsistent (raised at construction only)."""


class Pending:
    """A buffered command: started by the kernel once the axis's active motion is done."""

    def __init__(self, make: ProcessFactory, owner: object = None) -> None:
        self.make = make
        self.owner = owner
        self.process: Process | None = None
        self.cancelled = False
        #: set when the command could not start (cancelled with an error)
        self.error_code = 0


class Controller:
    def __init__(
        self, axes: Sequence[AxisConfig], groups: Sequence[GroupConfig], lanes: bool = True
    ) -> None:
        """``lanes=False`` composes every axis in Python (the reference the fast lanes
        are tested against)."""
        if not groups:
            raise ConfigError("at least one motion group is required")
        self._check_unique([a.number for a in axes], "axis number")
        self._check_unique([a.name for a in axes], "axis name")
        self._check_unique([g.number for g in groups], "group number")
        n = len(axes)
        self.cmd_pos = np.zeros(n)
        self.cmd_vel = np.zeros(n)
        self.cmd_acc = np.zeros(n)
        self.act_x = np.zeros(n)  # continuous drive position (unquantised)
        self.act_pos = np.zeros(n)  # quantised feedback
        self.act_vel = np.zeros(n)
        #: the command position the drive reached at the end of its last cycle (the drive
        #: interpolates linearly from it to the new command across one cycle)
        self.drv_cmd = np.zeros(n)
        self.drive_on = np.zeros(n, dtype=bool)
        #: bumped whenever a drive switches on or off; the per-group on/off index
        #: partitions below are recomputed only then (fancy indexing costs on small groups)
        self._drive_version = 0
        self._partitions: dict[int, tuple[int, np.ndarray, np.ndarray, np.ndarray]] = {}
        self.omega = np.array([2.0 * math.pi * max(a.drive_bandwidth, 1e-3) for a in axes])
        self.cpu = np.array([a.counts_per_unit for a in axes])
        self.coast = np.array([max(a.coast_deceleration, 0.0) for a in axes])
        self.fe_limit = np.array([a.following_error_limit for a in axes])
        #: rollover of rotary axes (0: linear) and the indices of the rotary ones
        self.rollover = np.array([max(a.rollover, 0.0) for a in axes])
        self.rotary_idx = np.flatnonzero(self.rollover > 0.0)
        self.axes: list[Axis] = [Axis(self, cfg, i) for i, cfg in enumerate(axes)]
        self._by_number = {a.number: a for a in self.axes}
        self._by_name = {a.name: a for a in self.axes}

        periods = [g.coarse_update_period for g in groups]
        for g in groups:
            if not MIN_PERIOD - 1e-12 <= g.coarse_update_period <= MAX_PERIOD + 1e-12:
                raise ConfigError(
                    f"group {g.name}: coarse_update_period {g.coarse_update_period} s is outside "
                    f"[{MIN_PERIOD}, {MAX_PERIOD}]"
                )
        self.period = min(periods)
        self.groups: list[MotionGroup] = []
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
                members.append(ax)
            self.groups.append(MotionGroup(g, members, every))
        orphans = [a.name for a in self.axes if a.number not in seen]
        if orphans:
            raise ConfigError(f"axes not in any motion group: {', '.join(orphans)}")
        self._groups_by_number = {g.number: g for g in self.groups}
        self.lanes_enabled = lanes
        self._lanes = {g.number: GroupLanes(g) for g in self.groups}
        self.tick = 0
        self._order_dirty = True
        self.mode = OperatingMode.RUN
        #: MDAC master assignments (master-driven speed control)
        self.mdsc = MasterDrivenControl(self)

    @staticmethod
    def _check_unique(values: Iterable[object], what: str) -> None:
        seen: set[object] = set()
        for v in values:
            if v in seen:
                raise ConfigError(f"duplicate {what}: {v}")
            seen.add(v)

    # -- look-up ----------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.tick * self.period

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
        return self._groups_by_number[axis.group].period

    # -- stepping ---------------------------------------------------------------------------
    def step(self) -> None:
        """Advance one base period."""
        self.tick += 1
        if self._order_dirty:
            self._sort_groups()
        for g in self.groups:
            if self.tick % g.every == 0:
                self._step_group(g)
        self.mdsc.update()

    def run(self, cycles: int) -> None:
        for _ in range(cycles):
            self.step()

    def _step_group(self, g: MotionGroup) -> None:
        dt = g.period
        g.cycles += 1
        for ax in g.feedback_axes:
            self._sample_feedback(ax, g, dt)
        lanes = self._lanes[g.number]
        if lanes.dirty:
            lanes.rebuild(self)
        lanes.step(self, dt)
        fast = self.lanes_enabled
        for ax in lanes.python_order:
            if ax.processes or ax.buffered is not None:
                self._compose(ax, dt)
                procs = ax.processes
                if fast and len(procs) == 1 and ax.buffered is None and procs[0].active:
                    lanes.offer(ax)
        self._drives(g.servo_idx, dt, servo=True)
        self._drives(g.virtual_idx, dt, servo=False)
        self._check_following_error(g.servo_idx)
        if g.after_stops:
            self._after_stops(g, dt)
        for s in g.stops:
            s.update()
        g.stops = [s for s in g.stops if not s.complete]

    def _after_stops(self, g: MotionGroup, dt: float) -> None:
        """Apply the after-stop actions (disable, shutdown) of axes that came to rest."""
        pending = False
        for ax in g.axes:
            if ax.after_stop == AfterStop.NOTHING:
                continue
            if any(p.active for p in ax.processes) or not self._at_standstill(ax, dt):
                pending = True
                continue
            action, ax.after_stop = ax.after_stop, AfterStop.NOTHING
            if action == AfterStop.DISABLE:
                self._power(ax, AxisState.AXIS_READY, AbortReason.DISABLED)
            else:
                self._power(ax, AxisState.AXIS_SHUTDOWN, AbortReason.SHUTDOWN)
        g.after_stops = pending

    def _at_standstill(self, ax: Axis, dt: float) -> bool:
        """The drive has settled: it moves less than one count per coarse update (a
        disable or shutdown after a fast stop waits for this, so the axis does not coast
        on the servo lag)."""
        i = ax.index
        if not self.drive_on[i] or ax.type != AxisType.SERVO:
            return True
        return bool(abs(self.act_vel[i]) * dt * self.cpu[i] < 1.0)

    def _compose(self, ax: Axis, dt: float) -> None:
        active = ProcessState.ACTIVE
        procs = ax.processes
        failed_moving: list[Process] = []
        for p in procs:
            if p.state is active:
                try:
                    p.step(self, dt)
                except MotionError as exc:
                    p.state = ProcessState.ERROR
                    p.error_code = int(exc.code)
                if p.state is ProcessState.ERROR and p.velocity != 0.0:
                    failed_moving.append(p)
        for p in failed_moving:
            # a process that fails while moving hands its velocity to a stop ramp at the
            # axis maximum deceleration: an error never makes a velocity step
            ramp = StopRamp(dt, ax.config.max_deceleration, 0.0, p.velocity)
            ramp.step(self, dt)
            procs.append(ramp)
        i = ax.index
        if len(procs) == 1 and procs[0].state is active and ax.buffered is None:
            # the common case, one running process: no lists, no sums
            p = procs[0]
            self.cmd_pos[i] = ax.base + p.position
            self.cmd_vel[i] = p.velocity
            self.cmd_acc[i] = p.acceleration
            return
        keep: list[Process] = []
        landing: float | None = None
        for p in procs:
            if p.state is active:
                keep.append(p)
            else:
                ax.base += p.position
                if p.state == ProcessState.DONE and p.landing is not None:
                    landing = p.landing
        ax.processes = keep
        if landing is not None and not keep and _rounding_apart(ax.base, landing):
            ax.base = landing  # an absolute move ends exactly on its target
        pos = vel = acc = 0.0
        for p in keep:
            pos += p.position
            vel += p.velocity
            acc += p.acceleration
        self.cmd_pos[i] = ax.base + pos
        self.cmd_vel[i] = vel
        self.cmd_acc[i] = acc
        pend = ax.buffered
        if pend is not None and all(p.reached for p in keep):
            ax.buffered = None
            if not pend.cancelled:
                try:
                    pend.process = self.start(
                        ax, pend.make, replace=None, reason=AbortReason.SUPERSEDED
                    )
                except MotionError as exc:
                    # it cannot start from where the axis is now: its owner reports it
                    pend.error_code = int(exc.code)
                    pend.cancelled = True

    def _sample_feedback(self, ax: Axis, g: MotionGroup, dt: float) -> None:
        cfg = ax.config
        i = ax.index
        old = float(self.act_x[i])
        if cfg.feedback_signal == FeedbackSignal.CONSTANT_VELOCITY:
            new = cfg.signal_velocity * g.time
        elif cfg.feedback_signal == FeedbackSignal.SINE:
            new = cfg.signal_amplitude * math.sin(2.0 * math.pi * cfg.signal_frequency * g.time)
        else:
            new = ax.feedback_input
            if cfg.rotary:
                # the input is a wrapped reading: unwind it against the last sample
                delta = math.remainder(new - ax.wrap(old), cfg.rollover)
                new = old + delta
        q = round(new * self.cpu[i]) / self.cpu[i]
        self.act_vel[i] = (q - self.act_pos[i]) / dt
        self.act_x[i] = new
        self.act_pos[i] = q
        self.cmd_pos[i] = q
        self.cmd_vel[i] = self.act_vel[i]

    def _partition(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(drive on, drive off, drive on with a following-error limit) among ``idx``."""
        cached = self._partitions.get(id(idx))
        if cached is None or cached[0] != self._drive_version:
            on = self.drive_on[idx]
            on_idx = idx[on]
            cached = (self._drive_version, on_idx, idx[~on], on_idx[self.fe_limit[on_idx] > 0.0])
            self._partitions[id(idx)] = cached
        return cached[1], cached[2], cached[3]

    def _drives(self, idx: np.ndarray, dt: float, servo: bool) -> None:
        if idx.size == 0:
            return
        on_idx, off_idx, _ = self._partition(idx)
        if on_idx.size:
            if servo:
                # x'' + 2w x' + w^2 x = w^2 c(t), c(t) the command ramp from the last
                # cycle's command c0 to the new one c1 (slope s). Its exact solution: the
                # steady tracking point c(t) - 2s/w plus a decaying (A + Bt) e^(-wt).
                c0 = self.drv_cmd[on_idx]
                c1 = self.cmd_pos[on_idx]
                w = self.omega[on_idx]
                s = (c1 - c0) / dt
                lag = 2.0 * s / w
                e0 = self.act_x[on_idx] - (c0 - lag)
                de0 = self.act_vel[on_idx] - s
                decay = np.exp(-w * dt)
                b = de0 + w * e0
                self.act_x[on_idx] = c1 - lag + (e0 + b * dt) * decay
                self.act_vel[on_idx] = s + (de0 - w * b * dt) * decay
                cpu = self.cpu[on_idx]
                self.act_pos[on_idx] = np.round(self.act_x[on_idx] * cpu) / cpu
            else:
                self.act_x[on_idx] = self.cmd_pos[on_idx]
                self.act_pos[on_idx] = self.cmd_pos[on_idx]
                self.act_vel[on_idx] = self.cmd_vel[on_idx]
        if off_idx.size:
            v0 = self.act_vel[off_idx]
            step = self.coast[off_idx] * dt
            speed = np.maximum(np.abs(v0) - step, 0.0)
            # a remnant below rounding of the per-cycle decrement is rest, not motion
            speed[speed <= 1e-9 * step] = 0.0
            v1 = np.sign(v0) * speed
            self.act_x[off_idx] += 0.5 * (v0 + v1) * dt
            self.act_vel[off_idx] = v1
            if servo:
                cpu = self.cpu[off_idx]
                self.act_pos[off_idx] = np.round(self.act_x[off_idx] * cpu) / cpu
            else:
                self.act_pos[off_idx] = self.act_x[off_idx]
            # with the drive off the command tracks the actual position
            self.cmd_pos[off_idx] = self.act_pos[off_idx]
            self.cmd_vel[off_idx] = v1
            self.cmd_acc[off_idx] = 0.0
        self.drv_cmd[idx] = self.cmd_pos[idx]

    def _check_following_error(self, idx: np.ndarray) -> None:
        if idx.size == 0:
            return
        watched = self._partition(idx)[2]
        if watched.size == 0:
            return
        err = np.abs(self.cmd_pos[watched] - self.act_pos[watched])
        bad = watched[err > self.fe_limit[watched]]
        for i in bad:
            self.fault(self.axes[int(i)], AxisFault.POSITION_ERROR)

    def _sort_groups(self) -> None:
        """Order each group's axes so that masters compose before their slaves."""
        for g in self.groups:
            order: list[Axis] = []
            for ax in g.axes:
                self._visit(ax, g.number, order, ())
            g.order = order
            self._lanes[g.number].dirty = True
        self._order_dirty = False

    def _visit(self, ax: Axis, group: int, order: list[Axis], path: tuple[int, ...]) -> None:
        if ax in order or ax.number in path:
            return
        for p in ax.processes:
            for m in p.masters:
                master = self._by_number.get(m)
                if master is not None and master.group == group:
                    self._visit(master, group, order, (*path, ax.number))
        order.append(ax)

    def settle(self, ax: Axis) -> None:
        """Bring ``ax``'s processes up to date and take it out of the fast lanes: call
        before reading or changing its processes outside :meth:`step`. It rejoins a lane
        once it is steady again."""
        for p in ax.processes:
            if p.lane is not None:
                p.lane.evict(p)

    def coupling_changed(self) -> None:
        """Call after adding or removing a process that has masters."""
        self._order_dirty = True

    def would_cycle(self, slave: int, masters: Collection[int]) -> bool:
        """True if making ``slave`` follow ``masters`` closes a loop of master/slave links."""
        frontier = list(masters)
        seen: set[int] = set()
        while frontier:
            m = frontier.pop()
            if m == slave:
                return True
            if m in seen:
                continue
            seen.add(m)
            ax = self._by_number.get(m)
            if ax is not None:
                for p in ax.processes:
                    if p.active:
                        frontier.extend(p.masters)
        return False

    # -- power ------------------------------------------------------------------------------
    def _power(self, ax: Axis, state: AxisState, reason: AbortReason) -> None:
        if state != AxisState.SERVO_CONTROL:
            self.abort(ax, reason)
            ax.after_stop = AfterStop.NOTHING
        ax.state = state
        on = state == AxisState.SERVO_CONTROL and ax.type != AxisType.FEEDBACK_ONLY
        i = ax.index
        if on and not self.drive_on[i]:
            # the command starts where the axis is, at rest
            ax.base = float(self.act_pos[i])
            self.cmd_pos[i] = ax.base
            self.drv_cmd[i] = ax.base
            self.cmd_vel[i] = 0.0
            self.cmd_acc[i] = 0.0
        if bool(self.drive_on[i]) != on:
            self._drive_version += 1
        self.drive_on[i] = on

    def servo_on(self, ax: Axis) -> None:
        """MSO / MC_Power on."""
        if ax.type == AxisType.FEEDBACK_ONLY:
            raise MotionError(ErrorCode.WRONG_AXIS_TYPE, f"{ax.name} is feedback only")
        if ax.state == AxisState.AXIS_SHUTDOWN:
            raise MotionError(ErrorCode.SHUTDOWN_STATE, f"{ax.name} is shut down")
        if ax.state == AxisState.AXIS_FAULTED:
            raise MotionError(ErrorCode.AXIS_FAULTED, f"{ax.name} is faulted")
        if ax.state != AxisState.SERVO_CONTROL:
            self._power(ax, AxisState.SERVO_CONTROL, AbortReason.NONE)

    def servo_off(self, ax: Axis) -> None:
        """MSF / MC_Power off / hard disable: drive off at once, the axis coasts."""
        if ax.state == AxisState.SERVO_CONTROL:
            self._power(ax, AxisState.AXIS_READY, AbortReason.DISABLED)

    def fault(self, ax: Axis, bits: int) -> None:
        ax.fault |= int(bits)
        if ax.state != AxisState.AXIS_SHUTDOWN:
            self._power(ax, AxisState.AXIS_FAULTED, AbortReason.FAULTED)

    def fault_reset(self, ax: Axis) -> None:
        """MAFR / MC_Reset: clear faults; a faulted axis returns to Axis Ready."""
        ax.fault = 0
        if ax.state == AxisState.AXIS_FAULTED:
            self._power(ax, AxisState.AXIS_READY, AbortReason.NONE)

    def shutdown(self, ax: Axis) -> None:
        """MASD: Axis Shutdown at once; the drive is off and the axis coasts.

        The axis's MDAC links break (as slave and as master), and every process on another
        axis that follows it (master-driven motion, gearing) is released: see
        :meth:`release_followers`.
        """
        self.mdsc.break_axis(ax, AbortReason.SHUTDOWN)
        self._power(ax, AxisState.AXIS_SHUTDOWN, AbortReason.SHUTDOWN)
        self.release_followers(ax, AbortReason.SHUTDOWN)

    def shutdown_reset(self, ax: Axis) -> None:
        """MASR: from Axis Shutdown (or faulted) to Axis Ready, faults cleared."""
        ax.fault = 0
        if ax.state in (AxisState.AXIS_SHUTDOWN, AxisState.AXIS_FAULTED):
            self._power(ax, AxisState.AXIS_READY, AbortReason.NONE)

    def group_shutdown(self, ref: int | str) -> MotionGroup:
        """MGSD: every axis of the group (feedback-only ones too) to Axis Shutdown."""
        g = self.group(ref)
        for ax in g.axes:
            self.shutdown(ax)
        return g

    def group_shutdown_reset(self, ref: int | str) -> MotionGroup:
        """MGSR: every axis of the group from Axis Shutdown (or faulted) to Axis Ready."""
        g = self.group(ref)
        for ax in g.axes:
            self.shutdown_reset(ax)
        return g

    def release_followers(self, master: Axis, reason: AbortReason) -> None:
        """Release every process on another axis that reads ``master`` (its ``masters``):
        a shut-down master no longer drives anything (see :meth:`release`)."""
        for ax in self.axes:
            if ax is not master:
                hit = [p for p in ax.processes if p.active and master.number in p.masters]
                self.release(ax, hit, reason)

    def release(self, ax: Axis, processes: Collection[Process], reason: AbortReason) -> None:
        """Switch ``processes`` of ``ax`` to a time-driven stop, as a controller does when a
        slave loses its master: they are aborted with ``reason`` and the axis decelerates
        their velocity to rest at its maximum deceleration (trapezoidal, StoppingStatus
        set), keeping its power state; its other processes go on. An axis whose drive is
        off simply coasts."""
        hit = [p for p in processes if p.active and p in ax.processes]
        if not hit:
            return
        self.settle(ax)
        v = sum(p.velocity for p in hit)
        for p in hit:
            p.abort(reason)
            ax.base += p.position
        ax.processes = [p for p in ax.processes if p.active]
        self.coupling_changed()
        if self.drive_on[ax.index] and v != 0.0:
            ax.processes.append(StopRamp(self.dt(ax), ax.config.max_deceleration, 0.0, v))

    # -- operating mode ---------------------------------------------------------------------
    def set_mode(self, mode: OperatingMode) -> list[GroupStop]:
        """Change the operating mode. Leaving RUN breaks every MDAC link and runs the
        programmed stop of every group; the returned handles tell when they are done."""
        if mode == self.mode:
            return []
        self.mode = mode
        self.mdsc.break_all(AbortReason.STOPPED)
        if mode == OperatingMode.RUN:
            return []
        return [self.group_stop(g.number) for g in self.groups]

    @property
    def run_mode(self) -> bool:
        return self.mode == OperatingMode.RUN

    # -- motion -----------------------------------------------------------------------------
    def require_motion(self, ax: Axis) -> None:
        """Preconditions of every motion command, as a controller checks them."""
        if ax.type == AxisType.FEEDBACK_ONLY:
            raise MotionError(ErrorCode.WRONG_AXIS_TYPE, f"{ax.name} is feedback only")
        if ax.state == AxisState.AXIS_SHUTDOWN:
            raise MotionError(ErrorCode.SHUTDOWN_STATE, f"{ax.name} is shut down")
        if ax.state == AxisState.AXIS_FAULTED:
            raise MotionError(ErrorCode.AXIS_FAULTED, f"{ax.name} is faulted")
        if ax.state != AxisState.SERVO_CONTROL:
            raise MotionError(ErrorCode.SERVO_OFF_STATE, f"{ax.name} is not in Servo Control")

    def _retire(
        self, ax: Axis, kinds: Collection[ProcessKind] | None, reason: AbortReason
    ) -> tuple[float, float]:
        """Abort matching processes, fold them into ``base``; return their velocity and
        acceleration so that a successor can inherit them."""
        self.settle(ax)
        v = a = 0.0
        keep: list[Process] = []
        for p in ax.processes:
            if p.active and (kinds is None or p.kind in kinds):
                p.abort(reason)
                v += p.velocity
                a += p.acceleration
            if p.active:
                keep.append(p)
            else:
                ax.base += p.position
        if len(keep) != len(ax.processes):
            ax.processes = keep
            self.coupling_changed()
        return v, a

    def start(
        self,
        ax: Axis,
        make: ProcessFactory,
        replace: Collection[ProcessKind] | None = (),
        reason: AbortReason = AbortReason.SUPERSEDED,
    ) -> Process:
        """Start a process. ``replace`` names the kinds it supersedes (``None``: all of
        them, the PLCopen aborting mode and Logix merge); the new process is built by
        ``make(v, a)`` from the velocity and acceleration of what it replaces. If ``make``
        raises, nothing has changed: the processes it would replace keep running."""
        if not ax.processes:
            # an axis without motion may be a master its lane gears read as constant
            self._lanes[ax.group].dirty = True
        self.settle(ax)
        matching = [p for p in ax.processes if p.active and (replace is None or p.kind in replace)]
        p = make(
            sum((q.velocity for q in matching), 0.0), sum((q.acceleration for q in matching), 0.0)
        )
        self._retire(ax, replace, reason)
        if replace is None and ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        ax.processes.append(p)
        if p.masters:
            self.coupling_changed()
        return p

    def buffer(self, ax: Axis, make: ProcessFactory, owner: object = None) -> Pending:
        """Queue ``make`` to start when the axis's active motion is done (PLCopen buffered)."""
        if ax.buffered is not None:
            raise MotionError(ErrorCode.BUFFER_FULL, f"{ax.name} already has a buffered command")
        self.settle(ax)
        pend = Pending(make, owner)
        if not any(p.active for p in ax.processes):
            pend.process = self.start(ax, make, replace=None)
        else:
            ax.buffered = pend
        return pend

    def abort(self, ax: Axis, reason: AbortReason) -> None:
        """End every process on the axis at once (no ramp): disable, shutdown, fault."""
        self._retire(ax, None, reason)
        if ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        ax.stop_latch = None

    def stop(
        self,
        ax: Axis,
        kinds: Collection[ProcessKind] | None,
        deceleration: float,
        jerk: float = 0.0,
        owner: object = None,
    ) -> StopRamp:
        """Replace the matching processes by one ramp from their velocity to rest."""
        dt = self.dt(ax)

        def make(v: float, a: float) -> Process:
            return StopRamp(dt, deceleration, jerk, v, a, owner=owner)

        if deceleration <= 0.0 or not math.isfinite(deceleration):
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, "deceleration must be > 0")
        if kinds is None and ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        if kinds is None:
            # a stop of all motion breaks the axis's MDAC links as slave (MAS All)
            self.mdsc.break_slave(ax, AbortReason.STOPPED)
        ramp = self.start(ax, make, replace=kinds, reason=AbortReason.STOPPED)
        assert isinstance(ramp, StopRamp)
        return ramp

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
                self.stop(ax, None, ax.config.max_deceleration, 0.0, owner)
                ax.after_stop = AFTER_FAST_STOP[mode]
                g.after_stops = True
            elif mode == ProgrammedStopMode.FAST_SHUTDOWN:
                self.shutdown(ax)
            # StoppingStatus until the axis is at rest (coasting axes have no ramp)
            ax.stop_latch = handle
        g.stops.append(handle)
        return handle

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
