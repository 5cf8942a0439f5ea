"""The simulated drives and feedback: how actual positions follow the command.

- Servo axes: a critically damped second-order loop that follows the command as a ramp
  across each cycle (its exact solution); the steady following error at velocity v is
  2v/ω, ω = 2π·drive_bandwidth, whatever the period. Actual positions are quantised to
  encoder counts.
- Virtual axes: actual = command.
- An axis whose drive is off coasts at its coast deceleration, and its command tracks
  the actual position.
- Feedback-only axes sample their input (a hand wheel) or a built-in signal at the start
  of the cycle.

All of it is vectorised over a group's axes; parts of at most :data:`SCALAR_PART` axes
are stepped axis by axis in Python floats instead (numpy's cost per call outweighs the
work on a few elements), with the very same operations in the same order, so both give
the same bits (``DriveModel(scalar_part=0)`` is the vectorised reference the tests
compare with). A value that is not finite, or overflows
(a command near the largest float, a feedback reading times its counts per unit beyond
it), is never propagated: the controller screens the arrays after composition and after
the drives (``AxisArrays.commands_finite``, one dot product each), :class:`DriveModel`
repairs the axes concerned (finite values, at rest) and the controller faults them
(``AxisFault.NUMERIC``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .axis import Axis
from .enums import FeedbackSignal
from .state import AxisArrays, Index, compact

#: parts of a group (drives on, drives off) this small are stepped axis by axis
SCALAR_PART = 4

# read every cycle, as module constants (see .enums)
_CONSTANT_VELOCITY = FeedbackSignal.CONSTANT_VELOCITY
_SINE = FeedbackSignal.SINE


def _rint_over(x: float, cpu: float) -> float:
    """``(x * cpu).round() / cpu`` as numpy computes it on one element: round half to
    even, the sign of a zero kept, infinities and NaN passed through."""
    v = x * cpu
    if v - v != 0.0:  # inf or NaN: numpy's round leaves them
        return v / cpu
    r = float(round(v))
    if r == 0.0:
        r = math.copysign(0.0, v)
    return r / cpu


def _sign(v: float) -> float:
    """``np.sign`` of one element (0.0 for both zeros, NaN for NaN)."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return v if v != v else 0.0


class _Partition:
    """The axes ``idx`` of a group split by drive state, each part as a slice when its
    indices are consecutive."""

    __slots__ = (
        "all",
        "decay",
        "decay_list",
        "dt",
        "limit",
        "n_off",
        "n_on",
        "n_watched",
        "off",
        "off_rows",
        "on",
        "on_rows",
        "version",
        "watch_all",
        "watched",
    )

    def __init__(self, s: AxisArrays, idx: np.ndarray, version: int) -> None:
        self.version = version
        on = s.drive_on[idx]
        on_idx = idx[on]
        off_idx = idx[~on]
        watched = on_idx[s.fe_limit[on_idx] > 0.0]
        self.all: Index = compact(idx)
        self.on: Index = compact(on_idx)
        self.off: Index = compact(off_idx)
        self.watched: Index = compact(watched)
        self.n_on, self.n_off, self.n_watched = on_idx.size, off_idx.size, watched.size
        #: the indices as Python ints, for the axis-by-axis path
        self.on_rows: list[int] = on_idx.tolist()
        self.off_rows: list[int] = off_idx.tolist()
        #: every axis that is on has a following-error limit: the check reads the
        #: drive update's own arrays
        self.watch_all = watched.size == on_idx.size
        self.limit = s.fe_limit[on_idx] if self.watch_all else s.fe_limit[watched]
        #: exp(-w dt) of the axes that are on, for the period ``dt`` (set on first use)
        self.decay = np.zeros(0)
        self.decay_list: list[float] = []
        self.dt = 0.0

    def decay_for(self, s: AxisArrays, dt: float) -> np.ndarray:
        if dt != self.dt or self.decay.size != self.n_on:
            self.decay = np.exp(-s.omega[self.on] * dt)
            self.decay_list = self.decay.tolist()
            self.dt = dt
        return self.decay

    def decay_rows(self, s: AxisArrays, dt: float) -> list[float]:
        """:meth:`decay_for` as Python floats (the same values)."""
        self.decay_for(s, dt)
        return self.decay_list


class DriveModel:
    def __init__(self, arrays: AxisArrays, scalar_part: int = SCALAR_PART) -> None:
        self.s = arrays
        self.scalar_part = scalar_part
        #: bumped whenever a drive switches on or off; the per-group on/off index
        #: partitions below are recomputed only then (fancy indexing costs on small groups)
        self._version = 0
        self._partitions: dict[int, _Partition] = {}

    def __getstate__(self) -> dict[str, Any]:
        # the partition cache is keyed by object identity, which a copy does not keep
        return {k: v for k, v in self.__dict__.items() if k != "_partitions"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._partitions = {}

    def switched(self) -> None:
        """A drive switched on or off."""
        self._version += 1

    def _partition(self, idx: np.ndarray) -> _Partition:
        """``idx`` split by drive state (recomputed only when a drive switched)."""
        cached = self._partitions.get(id(idx))
        if cached is None or cached.version != self._version:
            cached = _Partition(self.s, idx, self._version)
            self._partitions[id(idx)] = cached
        return cached

    # -- numerics -----------------------------------------------------------------------
    def repair_commands(self, idx: np.ndarray) -> list[int]:
        """Axes of ``idx`` whose composed command is not finite, set back to the last
        command the drive followed, at rest. (Screen with ``commands_finite`` first.)"""
        s = self.s
        ok = np.isfinite(s.cmd_pos[idx]) & np.isfinite(s.cmd_vel[idx]) & np.isfinite(s.cmd_acc[idx])
        bad = idx[~ok]
        s.cmd_pos[bad] = s.drv_cmd[bad]
        s.cmd_vel[bad] = 0.0
        s.cmd_acc[bad] = 0.0
        return [int(i) for i in bad]

    def repair_actuals(self, idx: np.ndarray) -> list[int]:
        """Axes of ``idx`` whose drive state is not finite (the drive overflowed), held at
        their command, at rest: within the positions whose encoder count is a finite
        number, so that the axis does not overflow again. (Screen with
        ``actuals_finite`` first.)"""
        s = self.s
        ok = np.isfinite(s.act_x[idx]) & np.isfinite(s.act_pos[idx]) & np.isfinite(s.act_vel[idx])
        bad = idx[~ok]
        reach = 0.5 * np.finfo(float).max / s.cpu[bad]
        here = s.drv_cmd[bad]
        here = np.where(np.isfinite(here), np.clip(here, -reach, reach), 0.0)
        here = np.round(here * s.cpu[bad]) / s.cpu[bad]
        for a in (s.act_x, s.act_pos, s.cmd_pos, s.drv_cmd):
            a[bad] = here
        for a in (s.act_vel, s.cmd_vel, s.cmd_acc):
            a[bad] = 0.0
        return [int(i) for i in bad]

    # -- drives ---------------------------------------------------------------------------
    def follow(self, idx: np.ndarray, dt: float, servo: bool) -> list[int]:
        """One cycle of the drives of ``idx`` (all servo or all virtual). Returns the servo
        axes whose following error now exceeds their limit (to be faulted)."""
        if idx.size == 0:
            return []
        s = self.s
        beyond: list[int] = []
        part = self._partition(idx)
        on_idx, off_idx = part.on, part.off
        small = self.scalar_part
        if part.n_on and part.n_on <= small:
            beyond = self._follow_rows(part, dt, servo)
        elif part.n_on:
            if servo:
                # x'' + 2w x' + w^2 x = w^2 c(t), c(t) the command ramp from the last
                # cycle's command c0 to the new one c1 (slope v). Its exact solution: the
                # steady tracking point c(t) - 2v/w plus a decaying (A + Bt) e^(-wt).
                c0 = s.drv_cmd[on_idx]
                c1 = s.cmd_pos[on_idx]
                w = s.omega[on_idx]
                slope = (c1 - c0) / dt
                lag = 2.0 * slope / w
                e0 = s.act_x[on_idx] - (c0 - lag)
                de0 = s.act_vel[on_idx] - slope
                decay = part.decay_for(s, dt)  # np.exp(-w * dt), constant per axis
                b = de0 + w * e0
                x = c1 - lag + (e0 + b * dt) * decay
                s.act_x[on_idx] = x
                s.act_vel[on_idx] = slope + (de0 - w * b * dt) * decay
                cpu = s.cpu[on_idx]
                q = (x * cpu).round() / cpu
                s.act_pos[on_idx] = q
                if part.n_watched:
                    beyond = self._following_errors(part, c1, q)
            else:
                s.act_x[on_idx] = s.cmd_pos[on_idx]
                s.act_pos[on_idx] = s.cmd_pos[on_idx]
                s.act_vel[on_idx] = s.cmd_vel[on_idx]
        if part.n_off and part.n_off <= small:
            self._coast_rows(part.off_rows, dt, servo)
        elif part.n_off:
            v0 = s.act_vel[off_idx]
            step = s.coast[off_idx] * dt
            speed = np.maximum(np.abs(v0) - step, 0.0)
            # a remnant below rounding of the per-cycle decrement is rest, not motion
            speed[speed <= 1e-9 * step] = 0.0
            v1 = np.sign(v0) * speed
            x = s.act_x[off_idx] + 0.5 * (v0 + v1) * dt
            if servo:
                cpu = s.cpu[off_idx]
                q = (x * cpu).round() / cpu
            else:
                q = x
            s.act_x[off_idx] = x
            s.act_vel[off_idx] = v1
            s.act_pos[off_idx] = q
            # with the drive off the command tracks the actual position
            s.cmd_pos[off_idx] = q
            s.cmd_vel[off_idx] = v1
            s.cmd_acc[off_idx] = 0.0
        # the command the drives followed (the rows' loops keep it for their own axes)
        if part.n_on > small or part.n_off > small:
            s.drv_cmd[part.all] = s.cmd_pos[part.all]
        return beyond

    def _follow_rows(self, part: _Partition, dt: float, servo: bool) -> list[int]:
        """The drives that are on, axis by axis (the vectorised branch of :meth:`follow`
        written out for one element, on the arrays' scalar views)."""
        r = self.s.scalars
        act_x, act_vel, act_pos = r.act_x, r.act_vel, r.act_pos
        cmd_pos, drv_cmd = r.cmd_pos, r.drv_cmd
        beyond: list[int] = []
        if not servo:
            cmd_vel = r.cmd_vel
            for i in part.on_rows:
                c = cmd_pos[i]
                act_x[i] = c
                act_pos[i] = c
                act_vel[i] = cmd_vel[i]
                drv_cmd[i] = c
            return beyond
        decay = part.decay_rows(self.s, dt)
        omega, cpu, fe_limit = r.omega, r.cpu, r.fe_limit
        for k, i in enumerate(part.on_rows):
            c0 = drv_cmd[i]
            c1 = cmd_pos[i]
            drv_cmd[i] = c1
            w = omega[i]
            slope = (c1 - c0) / dt
            lag = 2.0 * slope / w
            e0 = act_x[i] - (c0 - lag)
            de0 = act_vel[i] - slope
            d = decay[k]
            b = de0 + w * e0
            x = c1 - lag + (e0 + b * dt) * d
            act_x[i] = x
            act_vel[i] = slope + (de0 - w * b * dt) * d
            q = _rint_over(x, cpu[i])
            act_pos[i] = q
            limit = fe_limit[i]
            if limit > 0.0 and abs(c1 - q) > limit:
                beyond.append(i)
        return beyond

    def _coast_rows(self, rows: list[int], dt: float, servo: bool) -> None:
        """The drives that are off, axis by axis (see :meth:`follow`)."""
        r = self.s.scalars
        act_x, act_vel, act_pos, coast, cpu = r.act_x, r.act_vel, r.act_pos, r.coast, r.cpu
        cmd_pos, cmd_vel, cmd_acc, drv_cmd = r.cmd_pos, r.cmd_vel, r.cmd_acc, r.drv_cmd
        for i in rows:
            v0 = act_vel[i]
            if v0 == 0.0 and coast[i] >= 0.0:
                # at rest: what the lines below compute for a velocity of +-0 and a
                # coast rate that is not NaN (v1 = +0.0, x = act_x + 0.0), in fewer steps
                x = act_x[i] + 0.0
                q = _rint_over(x, cpu[i]) if servo else x
                act_x[i] = x
                act_vel[i] = 0.0
                act_pos[i] = q
                cmd_pos[i] = q
                cmd_vel[i] = 0.0
                cmd_acc[i] = 0.0
                drv_cmd[i] = q
                continue
            step = coast[i] * dt
            speed = abs(v0) - step
            if not speed > 0.0 and speed == speed:  # np.maximum(speed, 0.0)
                speed = 0.0
            if speed <= 1e-9 * step:
                speed = 0.0
            v1 = _sign(v0) * speed
            x = act_x[i] + 0.5 * (v0 + v1) * dt
            q = _rint_over(x, cpu[i]) if servo else x
            act_x[i] = x
            act_vel[i] = v1
            act_pos[i] = q
            cmd_pos[i] = q
            cmd_vel[i] = v1
            cmd_acc[i] = 0.0
            drv_cmd[i] = q

    def _following_errors(self, part: _Partition, c1: np.ndarray, q: np.ndarray) -> list[int]:
        """Axes whose |command - actual| exceeds their following error limit, from the
        servo update's command ``c1`` and new actual ``q`` of the axes that are on."""
        if part.watch_all:
            over = np.abs(c1 - q) > part.limit
            rows_of = part.on
        else:
            s = self.s
            w = part.watched
            over = np.abs(s.cmd_pos[w] - s.act_pos[w]) > part.limit
            rows_of = w
        if not np.count_nonzero(over):
            return []
        rows = np.flatnonzero(over)
        if isinstance(rows_of, slice):
            return [int(rows_of.start + r) for r in rows]
        return [int(rows_of[r]) for r in rows]

    # -- feedback -------------------------------------------------------------------------
    def sample_feedback(self, ax: Axis, time: float, dt: float) -> str | None:
        """The feedback of a feedback-only axis for this cycle. Returns why the sample
        cannot be taken (not finite in counts), leaving the last sample and no velocity."""
        cfg = ax.config
        r = self.s.scalars
        i = ax.index
        old = r.act_x[i]
        # the signal and the input are raw readings: the axis reads them plus the offset
        # its redefinitions added (Axis.position_offset)
        offset = ax.position_offset
        signal = cfg.feedback_signal
        if signal == _CONSTANT_VELOCITY:
            new = cfg.signal_velocity * time
        elif signal == _SINE:
            new = cfg.signal_amplitude * math.sin(2.0 * math.pi * cfg.signal_frequency * time)
        elif cfg.rollover > 0.0:  # cfg.rotary, without the property call
            # the input is a wrapped reading: unwind it against the last sample
            delta = math.remainder(ax.feedback_input - ax.wrap(old - offset), cfg.rollover)
            new = old - offset + delta
        else:
            new = ax.feedback_input
        if offset:
            new += offset
        cpu = r.cpu[i]
        counts = new * cpu
        if not math.isfinite(counts):
            r.act_vel[i] = r.cmd_vel[i] = 0.0
            return f"feedback sample {new!r} x {cpu:g} counts/unit is not a finite count"
        q = round(counts) / cpu
        v = (q - r.act_pos[i]) / dt
        r.act_vel[i] = v
        r.act_x[i] = new
        r.act_pos[i] = q
        r.cmd_pos[i] = q
        r.cmd_vel[i] = v
        return None
