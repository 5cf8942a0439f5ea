"""The kernel's shared state: every axis's kinematic values as arrays, in axis index order.

The hot path touches every axis each cycle (composition, the drive model, the fast lanes),
so positions, velocities and drive state live here as numpy arrays, and so do the status
words the front-ends publish (power state, fault bits and the process-derived PLCopen state
and MotionStatus bits, kept current per axis only when they may have changed: ``dirty``).

Motion processes step against this state through :class:`StepContext`: the arrays they
read and :meth:`AxisArrays.master_arrays`, the one place that says where a master's
position is read (command or actual, :class:`~.enums.MasterReference`);
:meth:`AxisArrays.read_master` reads one master through it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from .config import AxisConfig
from .enums import AxisState, AxisType, MasterReference
from .errors import ErrorCode, MotionError

#: a master's position, velocity and (command reference only) acceleration arrays
MasterArrays = tuple[np.ndarray, np.ndarray, "np.ndarray | None"]

#: indices into the axis arrays: an index array, or a slice when they are consecutive
Index = np.ndarray | slice


def compact(idx: np.ndarray) -> Index:
    """``idx`` as a slice when it is a run of consecutive indices (a view instead of a
    copy: several times cheaper to read and write than fancy indexing), else itself."""
    n = idx.size
    if n and int(idx[-1]) - int(idx[0]) == n - 1 and (n == 1 or bool((np.diff(idx) == 1).all())):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def compact_list(indices: list[int]) -> Index:
    """:func:`compact` of the indices given as a Python list (as a lane's membership
    has them): the run is recognised by comparing lists, without numpy's calls."""
    n = len(indices)
    if n:
        first = indices[0]
        if indices[-1] - first == n - 1 and indices == list(range(first, first + n)):
            return slice(first, first + n)
    return np.array(indices, dtype=np.intp)


class StepContext(Protocol):
    """What a motion process reads while it steps or starts: the kinematic arrays (unwound
    positions) and where a master is read. :class:`AxisArrays` is the kernel's; the
    controller offers the same names."""

    cmd_pos: np.ndarray
    cmd_vel: np.ndarray
    cmd_acc: np.ndarray
    act_pos: np.ndarray
    act_vel: np.ndarray
    #: feedback counts per position unit (the conversion constant) of every axis
    conversion: np.ndarray

    def master_arrays(self, reference: MasterReference) -> MasterArrays: ...

    def read_master(self, index: int, reference: MasterReference) -> tuple[float, float]: ...

    def index_of(self, number: int) -> int: ...


class Scalars:
    """Memoryviews of the per-axis arrays the scalar paths use, one element at a time.

    They share the arrays' memory (a write through either is seen by the other at once)
    and read and write Python floats (bools for ``busy``) bit for bit, at about 40 ns
    where ``ndarray.item`` costs 100 and an item assignment 75: the paths that step a few
    axes in Python (:mod:`.drive`, composition) go through them. The arrays they view
    are never replaced, only written."""

    __slots__ = (
        "act_pos",
        "act_vel",
        "act_x",
        "busy",
        "cmd_acc",
        "cmd_pos",
        "cmd_vel",
        "coast",
        "cpu",
        "drv_cmd",
        "fe_limit",
        "omega",
    )

    def __init__(self, s: AxisArrays) -> None:
        self.cmd_pos = _floats(s.cmd_pos)
        self.cmd_vel = _floats(s.cmd_vel)
        self.cmd_acc = _floats(s.cmd_acc)
        self.act_x = _floats(s.act_x)
        self.act_pos = _floats(s.act_pos)
        self.act_vel = _floats(s.act_vel)
        self.drv_cmd = _floats(s.drv_cmd)
        self.omega = _floats(s.omega)
        self.cpu = _floats(s.cpu)
        self.coast = _floats(s.coast)
        self.fe_limit = _floats(s.fe_limit)
        self.busy = s.busy.data.cast("B").cast("?")


def _floats(a: np.ndarray) -> memoryview[float]:
    """A memoryview of the float64 array ``a`` (one dimension, contiguous)."""
    return a.data.cast("B").cast("d")


class AxisArrays:
    """Kinematic, drive and status arrays of every axis (index = position in the axis
    configuration list)."""

    def __init__(self, axes: Sequence[AxisConfig]) -> None:
        n = len(axes)
        self.size = n
        # -- kinematics (unwound positions): rows of one block, so that one dot product
        # with zeros tells whether a whole row group is finite (see ``finite``)
        self.kinematics = np.zeros((7, n))
        self.cmd_pos = self.kinematics[0]
        self.cmd_vel = self.kinematics[1]
        self.cmd_acc = self.kinematics[2]
        #: continuous drive position (unquantised)
        self.act_x = self.kinematics[3]
        #: quantised feedback
        self.act_pos = self.kinematics[4]
        self.act_vel = self.kinematics[5]
        #: the command position the drive reached at the end of its last cycle (the drive
        #: interpolates linearly from it to the new command across one cycle)
        self.drv_cmd = self.kinematics[6]
        self._commands = self.kinematics[0:3].reshape(-1)
        self._actuals = self.kinematics[3:6].reshape(-1)
        self._zeros = np.zeros(3 * n)
        self.drive_on = np.zeros(n, dtype=bool)
        # -- constants from the configuration ---------------------------------------------
        self.omega = np.array([2.0 * math.pi * max(a.drive_bandwidth, 1e-3) for a in axes])
        #: counts per unit the actual position is quantised to (encoder resolution)
        self.cpu = np.array([a.counts_per_unit for a in axes])
        self.conversion = np.array([a.conversion_constant for a in axes], dtype=float)
        self.coast = np.array([max(a.coast_deceleration, 0.0) for a in axes])
        self.fe_limit = np.array([a.following_error_limit for a in axes])
        #: rollover of rotary axes (0: linear) and the indices of the rotary ones
        self.rollover = np.array([max(a.rollover, 0.0) for a in axes])
        self.rotary_idx = np.flatnonzero(self.rollover > 0.0)
        self.types = np.array([int(a.type) for a in axes], dtype=np.int8)
        self.servo_type = self.types == AxisType.SERVO
        self._index = {a.number: i for i, a in enumerate(axes)}
        # -- status (kept by Axis; see Controller.status_arrays) ----------------------------
        self.axis_state = np.full(n, int(AxisState.AXIS_READY), dtype=np.int64)
        self.fault = np.zeros(n, dtype=np.int64)
        #: AfterStop action waiting for rest, per axis
        self.after_stop = np.zeros(n, dtype=np.int8)
        #: the axis has an active motion process
        self.busy = np.zeros(n, dtype=bool)
        #: PLCopenState and the MotionStatus bits that do not depend on the acceleration
        #: (valid for axes not in ``dirty``)
        self.plcopen_state = np.zeros(n, dtype=np.int64)
        self.motion_bits = np.zeros(n, dtype=np.int64)
        #: axes whose process-derived status may have changed since it was last derived
        self.dirty: set[int] = set(range(n))
        #: how many times an axis changed AxisState (readers compare it with what they saw)
        self.state_changes = 0
        #: how many times an axis's AxisFault bits were set (``fault`` is written only by
        #: ``Axis.fault``; readers compare the count with what they saw)
        self.fault_changes = 0
        #: the same arrays, element by element in Python floats
        self.scalars = Scalars(self)

    # -- numerics ---------------------------------------------------------------------------
    def commands_finite(self) -> bool:
        """Every command position, velocity and acceleration is finite (one dot product:
        0 x inf and 0 x NaN are NaN; ``ndarray.dot`` costs half of ``@`` on small
        arrays)."""
        return not math.isnan(self._commands.dot(self._zeros))

    def actuals_finite(self) -> bool:
        """Every actual position (continuous and quantised) and velocity is finite."""
        return not math.isnan(self._actuals.dot(self._zeros))

    # -- masters ----------------------------------------------------------------------------
    def master_arrays(self, reference: MasterReference) -> MasterArrays:
        """Where a master is read: its command (this cycle's, masters compose before their
        slaves) with its acceleration, or its actual position (the feedback sampled at the
        start of the cycle) without one (a follower differences the velocity)."""
        if reference == MasterReference.COMMAND:
            return self.cmd_pos, self.cmd_vel, self.cmd_acc
        return self.act_pos, self.act_vel, None

    def read_master(self, index: int, reference: MasterReference) -> tuple[float, float]:
        """Unwound position and velocity of the master at ``index``."""
        pos, vel, _ = self.master_arrays(reference)
        return pos.item(index), vel.item(index)

    def index_of(self, number: int) -> int:
        """Array index of the axis with AXIS_REF ``number``."""
        try:
            return self._index[number]
        except KeyError:
            raise MotionError(
                ErrorCode.AXIS_NOT_CONFIGURED, f"axis {number} is not configured"
            ) from None
