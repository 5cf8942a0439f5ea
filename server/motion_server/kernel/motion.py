"""Motion processes on axes: starting, buffering, retiring and releasing them, composing an
axis's command from them, and the order in which axes compose (masters before slaves).

Every change to an axis's processes goes through :class:`Motion`, which keeps the axis's
shared status current (``Axis.motion_changed``) and its fast lane membership right
(:meth:`Motion.settle` before a change, :meth:`Motion.offer` after). A process whose step
fails is contained here: a :class:`MotionError` ends it with its code, any other
exception with ``INTERNAL_ERROR`` (recorded for the host to log), and a process that
fails while moving hands its velocity to a stop ramp.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from itertools import chain
from operator import attrgetter

from .axis import Axis
from .enums import AbortReason, ProcessKind, ProcessState
from .errors import ErrorCode, MotionError
from .group import MotionGroup
from .lanes import GroupLanes
from .override import Override, apply, overridable
from .processes import Pending, Process, ProcessFactory, StopRamp
from .state import AxisArrays

# members read every cycle, as module constants (see .enums)
_ACTIVE = ProcessState.ACTIVE
_MASTERS = attrgetter("masters")
_OWN_PROCESSES = attrgetter("_processes")
_DONE = ProcessState.DONE
_ERROR = ProcessState.ERROR

#: (axis name, what failed, the exception): an unexpected failure the host should log
InternalError = tuple[str, str, BaseException]


def _rounding_apart(x: float, y: float) -> bool:
    """True when ``x`` and ``y`` differ by no more than accumulated rounding."""
    return abs(x - y) <= 1e-9 * max(1.0, abs(y))


#: the smallest group whose processes join the fast lanes by default: with fewer axes the
#: lanes' numpy calls cost more than composing in Python (bench/fast_clock.py, the demo)
LANE_MIN_AXES = 8


class Motion:
    """The processes of every axis of a controller."""

    #: per group: its order (the list object) and each axis index's place in it (a class
    #: default for state saved before it existed)
    _positions: dict[int, tuple[list[Axis], dict[int, int]]] | None = None

    def __init__(
        self,
        arrays: AxisArrays,
        axes: Sequence[Axis],
        groups: Sequence[MotionGroup],
        lanes: bool | None,
    ) -> None:
        self.s = arrays
        self.axes = list(axes)
        self._by_number = {a.number: a for a in axes}
        self.groups = list(groups)
        self.lanes_enabled = lanes is not False
        self.lanes = {g.number: GroupLanes(g) for g in groups}
        #: groups whose processes may join the fast lanes (``Controller``'s ``lanes``): by
        #: default not a group of a few axes, which composes faster in Python
        minimum = LANE_MIN_AXES if lanes is None else 1
        self._offer_to = {
            n: lane
            for n, lane in self.lanes.items()
            if lanes is not False and len(lane.group.axes) >= minimum
        }
        #: masters and slaves changed: the composition order is recomputed at the next step
        self.order_dirty = True
        self._positions: dict[int, tuple[list[Axis], dict[int, int]]] | None = {}
        #: unexpected failures since the host last took them
        self.internal_errors: list[InternalError] = []

    def axis(self, number: int) -> Axis:
        ax = self._by_number.get(number)
        if ax is None:
            raise MotionError(ErrorCode.AXIS_NOT_CONFIGURED, f"axis {number} is not configured")
        return ax

    # -- lanes and order ----------------------------------------------------------------------
    def settle(self, ax: Axis) -> None:
        """Bring ``ax``'s processes up to date and take it out of the fast lanes: call
        before reading or changing its processes outside a step. It rejoins a lane once
        it is in a lane's state again (:meth:`offer`)."""
        for p in ax.processes:
            if p.lane is not None:
                p.lane.evict(p)

    def lanes_for(self, ax: Axis) -> GroupLanes | None:
        """The lanes ``ax``'s new process may join now: its group's, if they take
        processes and its drive is on (what :meth:`offer` asks besides the process)."""
        lanes = self._offer_to.get(ax.group)
        if lanes is None or not self.s.drive_on.item(ax.index):
            return None
        return lanes

    def offers(self, group: int) -> bool:
        """Processes of ``group`` may join its fast lanes."""
        return group in self._offer_to

    def offer(self, ax: Axis) -> None:
        """After a change or a composition: one active process on a driven axis, with
        nothing buffered, may go to a fast lane, if something happened to it since it was
        last offered (``Process.offer_pending``)."""
        # (the property's call saved: no stop row here unless its ramp is to be made)
        procs = ax._processes if ax.stop_rows is None else ax.processes
        if len(procs) == 1 and ax.buffered is None:
            p = procs[0]
            if p.offer_pending and p.lane is None and p.state is ProcessState.ACTIVE:
                lanes = self._offer_to.get(ax.group)
                if lanes is not None and self.s.drive_on.item(ax.index):
                    p.offer_pending = False
                    lanes.offer(ax, p)

    def coupling_changed(self) -> None:
        """Call after adding or removing a process that has masters."""
        self.order_dirty = True

    def sort(self) -> None:
        """Order each group's axes so that masters compose before their slaves."""
        for g in self.groups:
            if not any(map(_MASTERS, chain.from_iterable(map(_OWN_PROCESSES, g.axes)))):
                # no process of the group reads a master (a group stopped, or at rest):
                # every axis is placed where it stands, which the loop below gives, read
                # in C-level passes (an axis whose ramp is a stop row has no process);
                # the list kept when it holds that order already (what the lanes derived
                # from it stays valid)
                if g.order != g.axes:
                    g.order = list(g.axes)
                self.lanes[g.number].dirty = True
                continue
            order: list[Axis] = []
            placed: set[int] = set()
            for ax in g.axes:
                # a ramp still in the stop lane's rows reads no master (not made for this)
                procs = ax.processes if ax.stop_rows is None else ()
                if not procs or (len(procs) == 1 and not procs[0].masters):
                    # reads no master: where _visit would place it, without the call
                    if ax.index not in placed:
                        order.append(ax)
                        placed.add(ax.index)
                else:
                    self._visit(ax, g.number, order, placed, ())
            g.order = order
            self.lanes[g.number].dirty = True
        self.order_dirty = False

    def _order_holds(self, ax: Axis, p: Process) -> bool:
        """The group's composition order stays valid with ``p`` (new on ``ax``, which had
        no process) reading its masters: every master in the group already composes
        before ``ax``. Adding those links breaks no other (a gear started on a slave
        listed after its master: no new sort of the whole group)."""
        group = self.lanes[ax.group].group
        order = group.order
        positions = self._positions
        if positions is None:
            positions = self._positions = {}
        cached = positions.get(ax.group)
        if cached is None or cached[0] is not order:
            cached = (order, {a.index: k for k, a in enumerate(order)})
            positions[ax.group] = cached
        at = cached[1]
        here = at.get(ax.index)
        if here is None:
            return False
        for m in p.masters:
            master = self._by_number.get(m)
            if master is not None and master.group == ax.group:
                before = at.get(master.index)
                if before is None or before >= here:
                    return False
        return True

    def _visit(
        self, ax: Axis, group: int, order: list[Axis], placed: set[int], path: tuple[int, ...]
    ) -> None:
        if ax.index in placed or ax.number in path:
            return
        for p in ax.processes:
            for m in p.masters:
                master = self._by_number.get(m)
                if master is not None and master.group == group:
                    self._visit(master, group, order, placed, (*path, ax.number))
        order.append(ax)
        placed.add(ax.index)

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

    # -- commands -------------------------------------------------------------------------
    def retire(
        self, ax: Axis, kinds: Collection[ProcessKind] | None, reason: AbortReason
    ) -> tuple[float, float]:
        """Abort matching processes, fold them into ``base``; return their velocity and
        acceleration so that a successor can inherit them."""
        self.settle(ax)
        if ax.preloaded_cams:
            for p in ax.preloaded_cams:
                if kinds is None or p.kind in kinds:
                    p.abort(reason)
            ax.preloaded_cams = [p for p in ax.preloaded_cams if p.active]
            ax.motion_changed()
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
            # (a process that read no master leaves the composition order valid)
            if any(p.masters for p in ax.processes if not p.active):
                self.coupling_changed()
            ax.processes = keep
        ax.motion_changed()
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
        # (the property's call saved: no stop row here unless its ramp is to be made)
        procs = ax._processes if ax.stop_rows is None else ax.processes
        if not procs and not ax.preloaded_cams:
            # the common case of an axis without motion, without the calls: nothing to
            # settle, inherit or retire
            p = make(0.0, 0.0)
            if not ax.override.neutral and overridable(p):
                apply(p, ax.override)
            self.start_from_rest(ax, procs, p, replace)
            return p
        if not procs:
            self.lanes[ax.group].dirty = True
        self.settle(ax)
        matching = [p for p in ax.processes if p.active and (replace is None or p.kind in replace)]
        p = make(
            sum((q.velocity for q in matching), 0.0), sum((q.acceleration for q in matching), 0.0)
        )
        if not ax.override.neutral and overridable(p):
            apply(p, ax.override)  # started under an override: scaled from the start
        self.retire(ax, replace, reason)
        if replace is None and ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        ax.processes.append(p)
        if p.masters:
            self.coupling_changed()
        ax.motion_changed()
        self.offer(ax)
        return p

    def start_from_rest(
        self,
        ax: Axis,
        procs: list[Process],
        p: Process,
        replace: Collection[ProcessKind] | None,
    ) -> None:
        """The rest of :meth:`start` on an axis without motion (``procs``, its empty
        process list, no preloaded cam), once ``p`` is built (and scaled by the axis's
        override): ``p`` becomes its process and is offered to the lanes."""
        if replace is None and ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        procs.append(p)
        if p.masters and not self.order_dirty and not self._order_holds(ax, p):
            self.order_dirty = True
        # Axis.motion_changed: busy if the new process is active
        active = p.state is _ACTIVE
        i = ax.index
        self.s.scalars.busy[i] = active
        self.s.dirty.add(i)
        # Motion.offer of the axis's only process, without the call
        if active and ax.buffered is None and p.offer_pending and p.lane is None:
            lanes = self._offer_to.get(ax.group)
            if lanes is not None and self.s.drive_on.item(i):
                p.offer_pending = False
                lanes.offer(ax, p)
        if p.lane is None:
            # an axis without motion may be a master its lane followers read as
            # constant: composed in Python now, they are levelled again (in a lane,
            # the lane's admission marked what its rebuild needs)
            self.lanes[ax.group].dirty = True

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

    def set_override(self, ax: Axis, factors: Override) -> None:
        """Set the axis's override (:mod:`.override`): its running moves and jogs are
        re-planned from where they are with the new factors; the same factors again
        change nothing. If a process cannot be planned with them, those already
        re-planned go back to the old factors and MotionError is raised."""
        old = ax.override
        if factors == old:
            return
        self.settle(ax)
        done: list[Process] = []
        try:
            for p in ax.processes:
                if overridable(p):
                    apply(p, factors)
                    done.append(p)
        except MotionError:
            for p in done:
                apply(p, old)
            raise
        ax.override = factors
        ax.motion_changed()
        self.offer(ax)

    def abort(self, ax: Axis, reason: AbortReason) -> None:
        """End every process on the axis at once (no ramp): disable, shutdown, fault."""
        self.retire(ax, None, reason)
        if ax.buffered is not None:
            ax.buffered.cancelled = True
            ax.buffered = None
        ax.stop_latch = None

    def release(self, ax: Axis, processes: Collection[Process], reason: AbortReason) -> None:
        """Switch ``processes`` of ``ax`` to a time-driven stop, as a controller does when a
        slave loses its master: they are aborted with ``reason`` and the axis decelerates
        their velocity to rest at its maximum deceleration (trapezoidal, StoppingStatus
        set), keeping its power state; its other processes go on. An axis whose drive is
        off simply coasts."""
        self._end_in_ramp(ax, processes, lambda p: p.abort(reason))

    def fail(self, ax: Axis, processes: Collection[Process], code: int) -> None:
        """End ``processes`` of ``ax`` with the error ``code`` (their owners report it);
        the axis ramps their velocity to rest at its maximum deceleration, as when a
        process fails in its step."""
        self._end_in_ramp(ax, processes, lambda p: p.fail(code))

    def _end_in_ramp(
        self, ax: Axis, processes: Collection[Process], end: Callable[[Process], None]
    ) -> None:
        """End ``processes`` of ``ax`` still running with ``end`` (abort or fail), fold
        their positions into the base and ramp their summed velocity to rest at the
        axis's maximum deceleration (the drive on), its other processes going on."""
        hit = [p for p in processes if p.active and p in ax.processes]
        if not hit:
            return
        self.settle(ax)
        v = sum(p.velocity for p in hit)
        for p in hit:
            end(p)
            ax.base += p.position
        ax.processes = [p for p in ax.processes if p.active]
        self.coupling_changed()
        if self.s.drive_on[ax.index] and v != 0.0:
            ax.processes.append(StopRamp(ax.period, ax.config.max_deceleration, 0.0, v))
        ax.motion_changed()
        self.offer(ax)

    def release_followers(
        self, master: Axis, reason: AbortReason, among: Sequence[Axis] | None = None
    ) -> None:
        """Release every process on another axis that reads ``master`` (its ``masters``):
        a shut-down master no longer drives anything (see :meth:`release`). ``among``:
        the only axes that may have such a process, in axis order (:meth:`followers`);
        by default every axis is searched."""
        for ax in self.axes if among is None else among:
            if ax is not master:
                hit = [p for p in ax.processes if p.active and master.number in p.masters]
                self.release(ax, hit, reason)

    def followers(self) -> dict[int, list[Axis]]:
        """Master axis number -> the axes (in axis order) with a process that reads it:
        for shutting down many masters in a row (a group stop) without searching every
        axis for each (no process that reads a master starts meanwhile)."""
        out: dict[int, list[Axis]] = {}
        for ax in self.axes:
            seen: set[int] = set()
            for p in ax.processes:
                for m in p.masters:
                    if m not in seen:
                        seen.add(m)
                        out.setdefault(m, []).append(ax)
        return out

    # -- composition ----------------------------------------------------------------------
    def compose(self, ax: Axis, dt: float) -> None:
        """Step ``ax``'s processes and sum them into its command (Logix superposition)."""
        s = self.s
        active = _ACTIVE
        # (the property's call saved on this hot path: see Axis.processes)
        procs = ax._processes if ax.stop_rows is None else ax.processes
        failed_moving: list[Process] = []
        for p in procs:
            if p.state is active:
                before = (p.position, p.velocity, p.acceleration)
                try:
                    p.step(s, dt)
                except MotionError as exc:
                    p.fail(exc.code)
                except Exception as exc:  # a bug or a library failing: contained here
                    p.position, p.velocity, p.acceleration = before
                    p.fail(ErrorCode.INTERNAL_ERROR)
                    self.internal_errors.append((ax.name, repr(p), exc))
                if p.state is _ERROR and p.velocity != 0.0:
                    failed_moving.append(p)
                elif p.state is not active:
                    succ = p.successor
                    if succ is not None and succ.state is active:
                        # a cam's Pending successor takes over where it ended, stepped in
                        # this same cycle (appended: this loop reaches it)
                        p.successor = None
                        procs.append(succ)
        for p in failed_moving:
            # a process that fails while moving hands its velocity to a stop ramp at the
            # axis maximum deceleration: an error never makes a velocity step
            ramp = StopRamp(dt, ax.config.max_deceleration, 0.0, p.velocity)
            ramp.step(s, dt)
            procs.append(ramp)
        i = ax.index
        if len(procs) == 1 and procs[0].state is active and ax.buffered is None:
            # the common case, one running process: no lists, no sums
            p = procs[0]
            r = s.scalars
            r.cmd_pos[i] = ax.base + p.position
            r.cmd_vel[i] = p.velocity
            r.cmd_acc[i] = p.acceleration
            # what Axis.motion_changed(True) does, except that the status is marked stale
            # only when the step changed it: the process is still the same, still active
            r.busy[i] = True
            if p.status_changed:
                p.status_changed = False
                s.dirty.add(i)
            return
        keep: list[Process] = []
        landing: float | None = None
        for p in procs:
            if p.state is active:
                keep.append(p)
            else:
                ax.base += p.position
                if p.state == _DONE and p.landing is not None:
                    landing = p.landing
        ax.processes = keep
        if landing is not None and not keep and _rounding_apart(ax.base, landing):
            ax.base = landing  # an absolute move ends exactly on its target
        pos = vel = acc = 0.0
        for p in keep:
            pos += p.position
            vel += p.velocity
            acc += p.acceleration
        s.cmd_pos[i] = ax.base + pos
        s.cmd_vel[i] = vel
        s.cmd_acc[i] = acc
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
                except Exception as exc:  # contained as a failing step is
                    pend.error_code = int(ErrorCode.INTERNAL_ERROR)
                    pend.cancelled = True
                    self.internal_errors.append((ax.name, f"buffered start {pend.make!r}", exc))
        ax.motion_changed()
