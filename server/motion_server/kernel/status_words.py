"""The cached status words (``AxisArrays.plcopen_state`` and ``motion_bits``) derived again
for the axes marked ``dirty``: axis by axis through the properties, or, for many axes at
once, as arrays for those without motion processes.

A group stop marks every axis of its group twice: when it starts (each axis's ramp is a
row of the stop lane, or the axis is at rest, held by the stop's latch) and when the axes
come to rest. Neither has a process to ask, so their words follow from the power state,
the fault bits and three flags: Stopping (a latch held, or a ramp in the stop lane's
rows), Homed, and no homing waiting. Taken together as arrays they cost a few array
operations instead of the properties' Python for each axis (256 axes: about 300 µs of
the cycle that publishes the stop)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .axis import Axis
from .enums import AxisState, MotionStatusBit, PLCopenState
from .state import AxisArrays

#: fewer dirty axes than this are derived one by one (the arrays' fixed cost is larger)
AS_ARRAYS = 24

_STOPPING_BIT = 1 << MotionStatusBit.STOPPING
_HOMED_BIT = 1 << MotionStatusBit.HOMED
_FAULTED = int(AxisState.AXIS_FAULTED)
_SERVO = int(AxisState.SERVO_CONTROL)
_ERRORSTOP = int(PLCopenState.ERRORSTOP)
_DISABLED = int(PLCopenState.DISABLED)
_STOPPING = int(PLCopenState.STOPPING)
_STANDSTILL = int(PLCopenState.STANDSTILL)


def derive(s: AxisArrays, axes: Sequence[Axis]) -> None:
    """Derive the words of every axis in ``s.dirty`` and clear it."""
    dirty = s.dirty
    if len(dirty) < AS_ARRAYS:
        for i in dirty:
            ax = axes[i]
            s.plcopen_state[i] = int(ax.plcopen_state)
            s.motion_bits[i] = ax.process_bits()
        dirty.clear()
        return
    idx: list[int] = []
    stopping: list[bool] = []
    homed: list[bool] = []
    for i in dirty:
        ax = axes[i]
        if ax._processes or ax.preloaded_cams or ax._homing_armed is not None:
            s.plcopen_state[i] = int(ax.plcopen_state)
            s.motion_bits[i] = ax.process_bits()
        else:
            # no process: Stopping is the latch, or a ramp still a row of the stop lane
            # (Axis.process_bits and Axis.stopping, without making the ramp)
            idx.append(i)
            stopping.append(ax._stop_latch is not None or ax.stop_rows is not None)
            homed.append(ax._homed)
    dirty.clear()
    if not idx:
        return
    at = np.array(idx, dtype=np.intp)
    stop = np.array(stopping, dtype=bool)
    state = s.axis_state[at]
    # Axis.plcopen_state for an axis without processes, in the same order of tests
    plc = np.where(stop, _STOPPING, _STANDSTILL)
    plc[s.fault[at] != 0] = _ERRORSTOP
    plc[state != _SERVO] = _DISABLED
    plc[state == _FAULTED] = _ERRORSTOP
    s.plcopen_state[at] = plc
    s.motion_bits[at] = stop * _STOPPING_BIT + np.array(homed, dtype=bool) * _HOMED_BIT
