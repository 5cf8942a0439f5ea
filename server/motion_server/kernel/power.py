"""The power state of an axis (Logix AxisState) as a table: state x event -> next state, or
the error code that refuses the event.

Commands (MSO, MSF, MAFR, MASD, MASR and their PLCopen and group forms), faults and the
after-stop actions of a group stop are events; so are the preconditions every motion
command, every MDAC, every redefined position and passive homing, and absolute homing
check (:attr:`PowerEvent.MOTION`, :attr:`PowerEvent.ASSIGN`, :attr:`PowerEvent.REDEFINE`,
:attr:`PowerEvent.ABSOLUTE_HOME`), which never change the state: they are written here
once. A pair missing from the table
is a bug: :class:`~.errors.TransitionError`.

Leaving Servo Control aborts the axis's processes (no ramp) with the event's reason,
cancels a buffered command, releases a Stopping latch and drops a waiting after-stop
action; entering it starts the command where the axis is, at rest. A transition to the
same state does nothing, except a fault on a faulted axis and a shutdown of a shut-down
one (:data:`REAPPLIED`), which end again whatever was started on the axis since. The
event that last changed the state stays on the axis (``Axis.power_event``): MC_Power
reads it to tell a reset (:data:`RESETS`) from a deliberate disable.
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import IntEnum

import numpy as np

from .axis import Axis
from .drive import DriveModel
from .enums import AbortReason, AfterStop, AxisState, AxisType, PLCopenState
from .errors import ErrorCode, MotionError, TransitionError
from .motion import Motion


class PowerEvent(IntEnum):
    SERVO_ON = 0  # MSO, MC_Power Enable rising
    SERVO_OFF = 1  # MSF, MC_Power Enable falling, hard disable
    FAULT = 2  # a fault bit was raised
    FAULT_RESET = 3  # MAFR, MC_Reset
    SHUTDOWN = 4  # MASD, MGSD, hard or fast shutdown
    SHUTDOWN_RESET = 5  # MASR, MGSR
    STOPPED_DISABLE = 6  # a fast disable's ramp reached rest
    STOPPED_SHUTDOWN = 7  # a fast shutdown's ramp reached rest
    MOTION = 8  # precondition of every motion command
    ASSIGN = 9  # precondition of naming the axis in an MDAC (slave or master)
    REDEFINE = 10  # precondition of a redefined position and of passive homing
    ABSOLUTE_HOME = 11  # precondition of absolute homing (servo loop disabled)


R, S, F, D = (
    AxisState.AXIS_READY,
    AxisState.SERVO_CONTROL,
    AxisState.AXIS_FAULTED,
    AxisState.AXIS_SHUTDOWN,
)
E = PowerEvent
#: (state, event) -> next state, or the error code that refuses the event
TRANSITIONS: dict[tuple[AxisState, PowerEvent], AxisState | ErrorCode] = {
    (R, E.SERVO_ON): S,
    (S, E.SERVO_ON): S,
    (F, E.SERVO_ON): ErrorCode.AXIS_FAULTED,
    (D, E.SERVO_ON): ErrorCode.SHUTDOWN_STATE,
    (R, E.SERVO_OFF): R,
    (S, E.SERVO_OFF): R,
    (F, E.SERVO_OFF): F,
    (D, E.SERVO_OFF): D,
    (R, E.FAULT): F,
    (S, E.FAULT): F,
    (F, E.FAULT): F,
    (D, E.FAULT): D,  # shut down stays shut down (the fault bits are kept)
    (R, E.FAULT_RESET): R,
    (S, E.FAULT_RESET): S,
    (F, E.FAULT_RESET): R,
    (D, E.FAULT_RESET): D,
    (R, E.SHUTDOWN): D,
    (S, E.SHUTDOWN): D,
    (F, E.SHUTDOWN): D,
    (D, E.SHUTDOWN): D,
    (R, E.SHUTDOWN_RESET): R,
    (S, E.SHUTDOWN_RESET): S,
    (F, E.SHUTDOWN_RESET): R,
    (D, E.SHUTDOWN_RESET): R,
    # an after-stop action waits only in Servo Control (leaving it drops the action)
    (S, E.STOPPED_DISABLE): R,
    (S, E.STOPPED_SHUTDOWN): D,
    (R, E.MOTION): ErrorCode.SERVO_OFF_STATE,
    (S, E.MOTION): S,
    (F, E.MOTION): ErrorCode.AXIS_FAULTED,
    (D, E.MOTION): ErrorCode.SHUTDOWN_STATE,
    (R, E.ASSIGN): R,
    (S, E.ASSIGN): S,
    (F, E.ASSIGN): ErrorCode.AXIS_FAULTED,
    (D, E.ASSIGN): ErrorCode.SHUTDOWN_STATE,
    (R, E.REDEFINE): R,
    (S, E.REDEFINE): S,
    (F, E.REDEFINE): ErrorCode.AXIS_FAULTED,
    (D, E.REDEFINE): ErrorCode.SHUTDOWN_STATE,
    (R, E.ABSOLUTE_HOME): R,
    (S, E.ABSOLUTE_HOME): ErrorCode.SERVO_ON_STATE,
    (F, E.ABSOLUTE_HOME): ErrorCode.AXIS_FAULTED,
    (D, E.ABSOLUTE_HOME): ErrorCode.SHUTDOWN_STATE,
}
#: self-transitions that apply the event again (abort, drop the latch)
REAPPLIED = frozenset({(F, E.FAULT), (D, E.SHUTDOWN)})
del R, S, F, D, E

#: events that bring an axis back to Axis Ready by a reset (MAFR, MC_Reset, MASR, MGSR): an
#: MC_Power whose Enable is held re-enables the axis after them (PLCopen: "As long as
#: 'Enable' is true, power is being enabled"), but not after a deliberate disable (MSF, a
#: stop's disable action, Enable falling on another block)
RESETS = frozenset({PowerEvent.FAULT_RESET, PowerEvent.SHUTDOWN_RESET})

#: events a feedback-only axis refuses whatever its state (it has no drive)
NEEDS_DRIVE = frozenset({PowerEvent.SERVO_ON, PowerEvent.MOTION})

#: the reason the processes of an axis end with when an event takes it out of Servo Control
ABORT_REASON: dict[PowerEvent, AbortReason] = {
    PowerEvent.SERVO_OFF: AbortReason.DISABLED,
    PowerEvent.FAULT: AbortReason.FAULTED,
    PowerEvent.SHUTDOWN: AbortReason.SHUTDOWN,
    PowerEvent.STOPPED_DISABLE: AbortReason.DISABLED,
    PowerEvent.STOPPED_SHUTDOWN: AbortReason.SHUTDOWN,
}

_REFUSAL_TEXT: dict[ErrorCode, str] = {
    ErrorCode.WRONG_AXIS_TYPE: "{} is feedback only",
    ErrorCode.SHUTDOWN_STATE: "{} is shut down",
    ErrorCode.AXIS_FAULTED: "{} is faulted",
    ErrorCode.SERVO_OFF_STATE: "{} is not in Servo Control",
    ErrorCode.SERVO_ON_STATE: "{} is in Servo Control: disable it first",
}


def next_state(ax: Axis, event: PowerEvent) -> AxisState:
    """The state ``event`` takes ``ax`` to; MotionError when the event is refused."""
    if event in NEEDS_DRIVE and ax.type == AxisType.FEEDBACK_ONLY:
        code = ErrorCode.WRONG_AXIS_TYPE
    else:
        nxt = TRANSITIONS.get((ax.state, event))
        if nxt is None:
            raise TransitionError(f"axis {ax.name} power", ax.state, event)
        if isinstance(nxt, AxisState):
            return nxt
        code = nxt
    raise MotionError(code, _REFUSAL_TEXT[code].format(ax.name))


def require(ax: Axis, event: PowerEvent) -> None:
    """Raise the error that refuses ``event`` on ``ax``, if any (a precondition)."""
    next_state(ax, event)


class Power:
    """Applies power events to axes: their processes and drives follow."""

    def __init__(self, motion: Motion, drive: DriveModel) -> None:
        self._motion = motion
        self._drive = drive

    def fire(self, ax: Axis, event: PowerEvent) -> None:
        """Apply ``event`` (MotionError if the table refuses it)."""
        state = next_state(ax, event)
        if state != ax.state or (state, event) in REAPPLIED:
            ax.power_event = int(event)
            self._enter(ax, state, ABORT_REASON.get(event, AbortReason.NONE))

    def fire_all(
        self,
        axes: Iterable[Axis],
        event: PowerEvent,
        *,
        set_bits: int | None = None,
        clear: bool = False,
    ) -> None:
        """For each of ``axes`` in order: its AxisFault bits ``|= set_bits`` (if given) or
        cleared (``clear``), then :meth:`fire` ``event``: exactly what the per-axis calls leave, in
        one pass. A whole group faulted or reset at once (a watchdog's latch) costs a few
        array writes and a short loop of attribute stores instead of a full :meth:`fire`
        per axis.

        An axis with nothing to abort (no process, no stop row, no preloaded cam, nothing
        buffered) that does not enter Servo Control is done inline: its Python attributes
        at once, its array cells (fault, power state, after-stop action, busy, drive on)
        and the counters in one vectorised write. Any other axis goes through :meth:`fire`
        (its processes' owners may be told), the inline axes before it written first, so
        every observer sees the same order as the per-axis calls; a refusal raises there,
        as it would axis by axis, the axes before it done. ``event`` must not be one a
        feedback-only axis refuses (:data:`NEEDS_DRIVE`): FAULT, FAULT_RESET, SHUTDOWN,
        SHUTDOWN_RESET, SERVO_OFF and the after-stop events are meant.
        """
        if event in NEEDS_DRIVE:
            raise ValueError(f"{event.name} depends on the axis type: fire it axis by axis")
        s = self._motion.s
        bits = 0 if set_bits is None else int(set_bits)
        write_fault = clear or set_bits is not None
        ev = int(event)
        nothing = AfterStop.NOTHING
        # power state -> True: the event takes an axis without processes there to
        # ``target`` inline, False: it changes nothing; a state missing (a refusal, or
        # entering Servo Control, where the command is set at rest, or a second target)
        # goes through fire
        enter: dict[AxisState, bool] = {}
        target: AxisState | None = None
        for state in AxisState:
            nxt = TRANSITIONS.get((state, event))
            if isinstance(nxt, AxisState):
                if nxt == state and (nxt, event) not in REAPPLIED:
                    enter[state] = False
                elif nxt != AxisState.SERVO_CONTROL and target in (None, nxt):
                    target = nxt
                    enter[state] = True
        to = AxisState.AXIS_READY if target is None else target  # (unused when None)
        # inline axes not yet written to the arrays: those the event changes nothing on
        # (their fault bits only) and those that enter ``target``
        same: list[int] = []
        entered: list[int] = []
        homed: list[int] = []  # those of ``entered`` with Homed or HomingStatus
        to_plcopen = (
            PLCopenState.ERRORSTOP if to == AxisState.AXIS_FAULTED else PLCopenState.DISABLED
        )

        def flush() -> None:
            if same or entered:
                idx = np.array(same + entered, dtype=np.intp)
                if write_fault:
                    if clear:
                        s.fault[idx] = 0
                    else:
                        s.fault[idx] |= bits
                    s.fault_changes += len(idx)
                s.dirty.update(same)
                same.clear()
            if entered:
                idx = np.array(entered, dtype=np.intp)
                # their status words derived here, not marked dirty (what status_arrays
                # would find: no process, no latch, a state other than Servo Control;
                # a homed axis is left to it)
                s.plcopen_state[idx] = int(to_plcopen)
                s.motion_bits[idx] = 0
                s.dirty.difference_update(entered)
                s.dirty.update(homed)
                homed.clear()
                s.busy[idx] = False
                s.after_stop[idx] = int(nothing)
                s.axis_state[idx] = int(to)
                s.state_changes += len(entered)
                drive_on = s.drive_on
                was_on = int(np.count_nonzero(drive_on))
                drive_on[idx] = False
                # one switch per drive that went off (an axis named twice switches once)
                for _ in range(was_on - int(np.count_nonzero(drive_on))):
                    self._drive.switched()
                entered.clear()

        for ax in axes:
            changes = enter.get(ax._state)
            if changes is False:
                same.append(ax.index)
                continue
            if changes and not (
                ax._processes
                or ax.stop_rows is not None
                or ax.preloaded_cams
                or ax.buffered is not None
            ):
                # what _enter does to an axis without processes: abort (busy False), drop
                # the stop latch and the after-stop action, the new state, drive off (the
                # arrays in flush)
                ax.power_event = ev
                ax._stop_latch = None
                ax._after_stop = nothing
                ax._state = to
                entered.append(ax.index)
                if ax._homed or ax._homing_armed is not None:
                    homed.append(ax.index)
                continue
            flush()
            if write_fault:
                ax.fault = 0 if clear else ax.fault | bits
            self.fire(ax, event)
        flush()

    def _enter(self, ax: Axis, state: AxisState, reason: AbortReason) -> None:
        if state != AxisState.SERVO_CONTROL:
            self._motion.abort(ax, reason)
            ax.after_stop = AfterStop.NOTHING
        ax.state = state
        s = self._motion.s
        on = state == AxisState.SERVO_CONTROL and ax.type != AxisType.FEEDBACK_ONLY
        i = ax.index
        if on and not s.drive_on[i]:
            # the command starts where the axis is, at rest
            ax.base = float(s.act_pos[i])
            s.cmd_pos[i] = ax.base
            s.drv_cmd[i] = ax.base
            s.cmd_vel[i] = 0.0
            s.cmd_acc[i] = 0.0
        if bool(s.drive_on[i]) != on:
            self._drive.switched()
        s.drive_on[i] = on
