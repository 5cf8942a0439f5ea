"""The scan's copy of every tag value, brought up to date after each cycle.

What changes how often decides how a slot is filled:

- configuration (axis and group numbers, member lists, versions): once;
- the axis arrays (positions, velocities, following error): for every axis at once,
  from the kernel's numpy arrays;
- the axis status words (AxisState, PLCopenState, MotionStatus, AxisFault): every
  cycle, for every axis at once, from the kernel's status arrays (which cost Python work
  only for the axes whose processes or power changed);
- group states, diagnostics, the clock's counters and the watchdogs' states: every
  cycle, value by value;
- instruction outputs: only of the instances whose outputs changed in the cycle (their
  output dictionaries note it: :class:`~motion_server.instructions.base.Outputs`);
- writable tags (operands, triggers, cam points, hand-wheel inputs, clock commands,
  heartbeats): when written (:meth:`ImageFiller.refresh`), and in
  :meth:`ImageFiller.fill_all`; the fault injection bits also when the kernel ends a cause
  itself (an overtravel left behind).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..image.layout import ImageLayout
from ..tagmap.axis_faults import INJECT_CAUSES
from ..tagmap.image import (
    AXIS_ARRAYS,
    AXIS_FAULT_WORDS,
    AXIS_STATUS,
    Getter,
    TagImage,
    is_static,
)
from ..tagmap.model import Folder, Tag

#: folders whose writable tags change only when a client writes them (a cam table of
#: 1,000 points is 3,000 values nobody else changes; a watchdog's Heartbeat and Reset); the
#: Clock's command tags the scan changes itself (a snapshot command done, a communication
#: fault over) it refreshes when it changes them (``Scan._clock_commands``)
_WRITTEN_ONLY = frozenset({Folder.INSTRUCTIONS, Folder.CAMS, Folder.CLOCK, Folder.SAFETY})
_POSITIONS = frozenset({"ActualPosition", "CommandPosition"})
#: axis fields filled for every axis at once
_VECTORS = frozenset({*AXIS_ARRAYS, *AXIS_STATUS, *AXIS_FAULT_WORDS})


class ImageFiller:
    """Keeps ``values`` (one float64 per slot of ``layout``) equal to what ``image``'s
    getters read, at a cost proportional to what changed."""

    def __init__(self, image: TagImage, layout: ImageLayout) -> None:
        self.image = image
        self.layout = layout
        system = image.system
        ctl = system.ctl
        self.values = np.zeros(layout.size)
        #: the same memory, stored to value by value where only a few slots change
        self._cells = self.values.data.cast("B").cast("d")
        self._all: list[tuple[int, Getter]] = []
        self._each_cycle: list[tuple[int, Getter]] = []
        by_field: dict[str, tuple[list[int], list[int]]] = {}
        self._outputs: dict[str, list[tuple[str, int]]] = {}
        #: axis index -> the slots of its fault injection bits (and their getters)
        self._injects: dict[int, list[tuple[int, Getter]]] = {}
        for slot, tag in enumerate(layout.tags):
            get = image.getter(tag.name)
            self._all.append((slot, get))
            if is_static(tag) or (tag.writable and tag.folder in _WRITTEN_ONLY):
                continue
            if tag.field in INJECT_CAUSES and tag.folder == Folder.AXES:
                index = ctl.axis(tag.owner).index
                self._injects.setdefault(index, []).append((slot, get))
                continue
            if tag.folder == Folder.AXES and tag.field in _VECTORS:
                slots, axes = by_field.setdefault(tag.field, ([], []))
                slots.append(slot)
                axes.append(ctl.axis(tag.owner).index)
            elif tag.folder == Folder.INSTRUCTIONS:
                self._outputs.setdefault(tag.owner, []).append((tag.field, slot))
            else:
                self._each_cycle.append((slot, get))
        #: (field, slots, axes): the kernel array of ``field`` goes to ``slots``; a slice
        #: when the layout gave the field one run of slots in axis order (it does for
        #: every axis of the site), else index arrays
        self._arrays: list[tuple[str, slice | np.ndarray, np.ndarray | None]] = []
        n = len(ctl.axes)
        for field, (slots, axes) in by_field.items():
            run = slots == list(range(slots[0], slots[0] + n)) and axes == list(range(n))
            if run:
                self._arrays.append((field, slice(slots[0], slots[0] + n), None))
            else:
                self._arrays.append(
                    (field, np.array(slots, dtype=np.intp), np.array(axes, dtype=np.intp))
                )
        self._status = any(
            field in AXIS_STATUS or field in AXIS_FAULT_WORDS for field, _, _ in self._arrays
        )
        #: ``AxisArrays.fault_changes`` when the fault words were last computed
        self._fault_seen: int | None = None
        self._kernel = ctl.arrays
        #: rotary axes: positions are published wrapped (as ``Axis.wrap`` reads them), at
        #: these offsets from the start of a position field's run of slots
        self._rot = ctl.rotary_idx
        self._rollover = ctl.rollover[self._rot]
        self._each_slots = np.array([s for s, _ in self._each_cycle], dtype=np.intp)
        self._each_get = [g for _, g in self._each_cycle]
        self._instances = system.instances
        self._changed = system.changed_outputs
        self._faults = ctl.faults

    def fill_all(self) -> None:
        """Every slot from its getter (at start, after a restore)."""
        values = self.values
        for slot, get in self._all:
            values[slot] = get()
        self._changed.clear()
        self._faults.changed.clear()
        self._fault_seen = None

    def fill(self) -> None:
        """After a cycle: what may have changed."""
        values = self.values
        ctl = self.image.system.ctl
        status = ctl.status_arrays() if self._status else None
        faults_now = self._kernel.fault_changes
        fault_words = status is not None and self._fault_seen != faults_now
        if fault_words:
            self._fault_seen = faults_now
        for field, slots, axes in self._arrays:
            if field in AXIS_FAULT_WORDS:
                if fault_words:
                    assert status is not None
                    array = AXIS_FAULT_WORDS[field](status.fault)
                    values[slots] = array if axes is None else array[axes]
                continue
            if status is not None and field in AXIS_STATUS:
                array = getattr(status, AXIS_STATUS[field])
                values[slots] = array if axes is None else array[axes]
                continue
            if axes is None and field in _POSITIONS:
                assert isinstance(slots, slice)
                raw = ctl.act_pos if field == "ActualPosition" else ctl.cmd_pos
                values[slots] = raw
                if self._rot.size:  # fmod, then + rollover below 0: what Axis.wrap does
                    w = np.fmod(raw[self._rot], self._rollover)
                    values[slots.start + self._rot] = np.where(w < 0.0, w + self._rollover, w)
                continue
            array = AXIS_ARRAYS[field](ctl)
            values[slots] = array if axes is None else array[axes]
        if self._each_get:
            values[self._each_slots] = [get() for get in self._each_get]
        faults = self._faults.changed
        if faults:
            for index in faults:
                for slot, get in self._injects.get(index, ()):
                    values[slot] = get()
            faults.clear()
        changed = self._changed
        if changed:
            instances = self._instances
            outputs = self._outputs
            cells = self._cells  # a store through a memoryview: 40 ns, numpy's 100
            for name in changed:
                out = instances[name].outputs
                for key, slot in outputs.get(name, ()):
                    cells[slot] = out[key]
            changed.clear()

    def refresh(self, tags: Iterable[Tag]) -> None:
        """After writes: the written tags' slots."""
        values = self.values
        slot = self.layout.slot
        image = self.image
        for tag in tags:
            values[slot(tag)] = image.getter(tag.name)()
