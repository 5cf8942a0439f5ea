"""Many position cams started in one scan, planned together.

What many MAPC (Immediate) or MC_CamIn executed in the same scan hand the kernel: one
:class:`CamStart` per slave. :func:`start_position_cams` starts them with the same result
as starting each one after the other with ``Controller.start(slave, make, replace=())``
(the process, its state, the axis's status, the lane it joins, the order of everything),
but plans what they share once:

- cams with the same parameters on the same profile share what the constructor computes
  from them (the profile's value at the cam lock position, the period index, the
  enumerations): one cam is built by :class:`~.cams.CamProcess`, the others are copies of
  its attributes with their own master and owner;
- the masters' positions and velocities at the lock are read from the arrays in one
  gather;
- a slave without motion takes its cam as ``Motion.start`` does for an axis without
  motion, without the factory's calls; any other slave (one with processes, a cam
  preloaded on it) goes through ``Controller.start`` itself.

A cam that cannot start (its cam lock position outside the profile's range) raises
:class:`~.errors.MotionError` there, after the cams before it started and before the
ones after it: as the same starts one after the other would.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from .axis import Axis
from .cam_profile import CamProfile
from .cams import CamMode, CamProcess, LockDirection
from .controller import Controller
from .enums import MasterReference, ProcessKind
from .processes import Process, ProcessFactory


class CamStart(NamedTuple):
    """One position cam locked at once on ``slave`` (MAPC Immediate, MC_CamIn without a
    ramp-in): the :class:`~.cams.CamProcess` arguments of such a cam. (A named tuple:
    many are made in one scan, and a frozen dataclass costs five times as much.)"""

    slave: Axis
    master: Axis
    profile: CamProfile
    mode: CamMode
    scale: float
    master_scaling: float
    cam_lock: float
    source: MasterReference = MasterReference.COMMAND
    origin: float = 0.0
    kind: ProcessKind | None = None
    owner: Any = None

    def build(self, ctl: Controller) -> CamProcess:
        """The cam as its constructor makes it."""
        return CamProcess(
            ctl,
            self.profile,
            self.mode,
            self.scale,
            self.master_scaling,
            self.cam_lock,
            master=self.master.index,
            source=self.source,
            master_number=self.master.number,
            lock=LockDirection.IMMEDIATE,
            rollover=self.master.config.rollover,
            origin=self.origin,
            kind=self.kind,
            owner=self.owner,
        )


def _shared(c: CamStart) -> tuple[Any, ...]:
    """What cams built alike share (everything but the master and the owner)."""
    return (
        id(c.profile),
        c.mode,
        c.scale,
        c.master_scaling,
        c.cam_lock,
        c.source,
        c.origin,
        c.kind,
        c.master.config.rollover,
    )


def _factory(ctl: Controller, c: CamStart) -> ProcessFactory:
    def make(v: float, a: float) -> Process:
        return c.build(ctl)

    return make


def start_position_cams(ctl: Controller, starts: Sequence[CamStart]) -> list[CamProcess]:
    """Start the cams of ``starts`` in order (see the module docstring); returns them."""
    motion = ctl.motion
    s = motion.s
    out: list[CamProcess] = []
    by_source: dict[MasterReference, tuple[list[float], list[float]]] = {}
    for src in {c.source for c in starts}:
        pos, vel, _ = ctl.master_arrays(src)
        idx = np.array([c.master.index for c in starts], dtype=np.intp)
        by_source[src] = (pos[idx].tolist(), vel[idx].tolist())
    #: the attributes of the first cam built for each set of shared parameters, as its
    #: constructor left them (before the start offers it to a lane)
    templates: dict[tuple[Any, ...], dict[str, Any]] = {}
    busy = s.scalars.busy
    dirty = s.dirty
    for j, c in enumerate(starts):
        ax = c.slave
        if ax.processes or ax.preloaded_cams:
            # not an axis without motion: the start's own path, the cam built as usual
            started = ctl.start(ax, _factory(ctl, c), replace=())
            assert isinstance(started, CamProcess)
            out.append(started)
            continue
        key = _shared(c)
        template = templates.get(key)
        if template is None:
            p = c.build(ctl)  # raises as the constructor does
            templates[key] = dict(p.__dict__)
        else:
            # the constructor's result for this master: what it read from the master
            # (its position as the lock, its velocity) and the master and owner
            m_pos, m_vel = by_source[c.source]
            m = m_pos[j]
            d = dict(template)
            d["owner"] = c.owner
            d["index"] = c.master.index
            d["masters"] = (c.master.number,)
            d["m_prev"] = d["m0"] = d["m_eff"] = m
            d["v_prev"] = m_vel[j]
            p = CamProcess.__new__(CamProcess)
            p.__dict__ = d
        # Motion.start for an axis without motion (``replace=()``: a buffered command
        # stays; a cam is never scaled by an override)
        motion.lanes[ax.group].dirty = True
        ax.processes.append(p)
        motion.order_dirty = True
        busy[ax.index] = True
        dirty.add(ax.index)
        motion.offer(ax)
        out.append(p)
    return out
