"""A controller with its instruction instances: one call runs one PLC scan.

An exception inside one instance (a bug, never an operand: operands are judged) is
contained there: the instance shows the internal error (Logix ER, PLCopen Error, code
1005), the axes its axis operands name are stopped at their maximum deceleration, and the
scan goes on for every other instance. The host drains :attr:`MotionSystem.internal_errors`
and logs each one with its traceback.
"""

from __future__ import annotations

from operator import attrgetter
from typing import Any

from ..kernel import Controller, MotionError, ProcessState
from ..kernel.processes import Process
from .base import Instruction
from .registry import instruction_type
from .scan_pass import scan_pass

_ACTIVE = ProcessState.ACTIVE
_STATE = attrgetter("state")


class MotionSystem:
    """The kernel plus named instruction instances, scanned in a fixed order.

    ``cycle()``: every instance latches and executes on its trigger edge, the kernel
    steps one base period, every instance updates its status from the kernel. Outside run
    mode (``Controller.set_mode``) the instances are not scanned, like a program that is
    not executed; their status still follows the kernel.

    An instance that is asleep (:meth:`Instruction.asleep`: nothing can change until an
    operand is written) is left out of both calls, so idle instances cost nothing; a write
    to its operands, or for those that follow the axis state any change of it, wakes it.
    The awake ones keep the instances' order. An instance that only waits for its
    process to end (:meth:`Instruction.parked_on`: a MAJ jogging, a MAG geared) is
    parked: each cycle, after the kernel step, its system reads that process's state, and
    wakes it when the process has left ACTIVE (it is then updated in the same cycle, as
    it would have been) or when an operand is written. So 256 jogging MAJ cost 256 reads
    of a state a cycle, not 256 scans and updates. ``sleep=False`` calls every instance
    every cycle (the reference the sleeping and the parking are tested against).

    The instances that fire in one scan hand their axis commands to the kernel together
    where their types allow it (:mod:`.scan_pass`: MAJ's jogs, MAG's gears, MAPC's cams,
    the stops of MAS and MC_Stop, the halts of MC_Halt, MC_MoveVelocity's jogs), with the
    result of scanning them one by one; ``batch=False`` scans every instance alone (the
    reference the batches are tested against).
    """

    #: rising edges handed to the kernel in batches (a class default, so that a system
    #: from a snapshot taken before the batches has it too)
    batch: bool = True

    def __init__(self, ctl: Controller, sleep: bool = True, batch: bool = True) -> None:
        self.ctl = ctl
        self.sleep = sleep
        self.batch = batch
        self.instances: dict[str, Instruction] = {}
        #: the instances called this cycle, in the instances' order
        self._awake: list[Instruction] = []
        #: instances whose operands were written since they were last called
        self._woken: set[Instruction] = set()
        #: instances parked on their running process (:meth:`Instruction.parked_on`)
        self._parked: dict[Instruction, Process] = {}
        #: those of them woken too when an attribute of it falls (``PARKED_WATCH``)
        self._watched: dict[Instruction, str] = {}
        self._state_watchers: list[Instruction] = []
        self._states_seen = -1
        self._wired = 0
        #: names of the instances whose outputs changed since the host last looked
        self.changed_outputs: set[str] = set()
        #: (instance name, exception) of instances that raised, for the host to log
        self.internal_errors: list[tuple[str, BaseException]] = []

    def __setstate__(self, state: dict[str, Any]) -> None:
        state.setdefault("_parked", {})  # (a snapshot of a system that parked none)
        state.setdefault("_watched", {})
        self.__dict__.update(state)

    def add(self, type_name: str, name: str, defaults: dict[str, Any] | None = None) -> Instruction:
        if name in self.instances:
            raise ValueError(f"duplicate instruction instance {name!r}")
        inst = instruction_type(type_name)(name, self.ctl, defaults)
        self.adopt(inst)
        return inst

    def adopt(self, inst: Instruction) -> None:
        """Add a built instance (``add`` builds it from the catalog)."""
        if inst.name in self.instances:
            raise ValueError(f"duplicate instruction instance {inst.name!r}")
        self.instances[inst.name] = inst
        self._wire(inst)

    def _wire(self, inst: Instruction) -> None:
        inst.outputs.changed = self.changed_outputs
        inst.inputs.woken = self._woken
        self._woken.add(inst)  # scanned at least once: it judges for itself
        if inst.FOLLOWS_AXIS_STATE:
            self._state_watchers.append(inst)
        self.changed_outputs.add(inst.name)
        self._wired = len(self.instances)

    def __getitem__(self, name: str) -> Instruction:
        return self.instances[name]

    def cycle(self, count: int = 1) -> None:
        ctl = self.ctl
        for _ in range(count):
            self.scan_instructions()
            ctl.step()
            # (first: an instance written or woken since the scan leaves the parked ones)
            awake = self._wake()
            ended = self._unpark_ended() if self._parked else None
            for inst in awake:
                try:
                    inst.update()
                except Exception as exc:
                    self._contain(inst, exc)
            if self.sleep:
                self._rest(awake)
            if ended:
                self._woken.update(ended)  # (scanned from the next cycle on)

    def _rest(self, awake: list[Instruction]) -> None:
        """After the update: the instances of ``awake`` that are asleep leave the
        awake list, those that only wait on their process are parked."""
        keep: list[Instruction] = []
        parked = self._parked
        for inst in awake:
            if inst.asleep():
                continue
            p = inst.parked_on()
            if p is None:
                keep.append(inst)
            else:
                parked[inst] = p
                if inst.PARKED_WATCH is not None:
                    self._watched[inst] = inst.PARKED_WATCH
        if len(keep) != len(awake):
            self._awake = keep

    def _unpark_ended(self) -> list[Instruction]:
        """Update the parked instances whose process left ACTIVE (in this cycle's scan
        or step), or whose watched attribute of it fell, here rather than among the
        awake ones (each writes only its own outputs: the order does not matter).
        Returns those that are not asleep after it, to wake once this cycle's update is
        over (a group stop ending 256 jogs: no other pass over them)."""
        parked = self._parked
        watched = self._watched
        states = list(map(_STATE, parked.values()))  # (no Python call per process)
        fallen = [i for i, name in watched.items() if not getattr(parked[i], name)]
        if states.count(_ACTIVE) == len(states) and not fallen:
            return []
        ended = [inst for inst, p in parked.items() if p.state is not _ACTIVE]
        ended += [inst for inst in fallen if parked[inst].state is _ACTIVE]
        awake: list[Instruction] = []
        for inst in ended:
            del parked[inst]
            watched.pop(inst, None)
            try:
                if not inst.end_parked():
                    awake.append(inst)
            except Exception as exc:
                self._contain(inst, exc)
                awake.append(inst)
        return awake

    def scan_instructions(self) -> None:
        """The first half of :meth:`cycle`, before the kernel steps: in run mode, every
        awake instance scanned (trigger edges, operands latched and judged, commands),
        the commands of a batch handed to the kernel together."""
        if self.ctl.run_mode:
            scan_pass(self._wake(), self._contain, self.batch)

    def awake(self) -> list[Instruction]:
        """The instances the next cycle calls (all of them with ``sleep=False``)."""
        return list(self._wake())

    def parked(self) -> list[Instruction]:
        """The instances parked on their running process, in the instances' order."""
        self._wake()
        return [inst for inst in self.instances.values() if inst in self._parked]

    def _wake(self) -> list[Instruction]:
        """The awake instances, with those woken since the last call merged in (in order)."""
        woken = self._woken
        if len(self.instances) != self._wired:  # put in ``instances`` without adopt()
            for inst in self.instances.values():
                if inst.inputs.woken is not woken:
                    self._wire(inst)
            self._wired = len(self.instances)
        changes = self.ctl.arrays.state_changes
        if changes != self._states_seen:
            self._states_seen = changes
            woken.update(self._state_watchers)
        if woken:
            if self.sleep:
                parked = self._parked
                if parked:
                    watched = self._watched
                    for inst in woken:
                        parked.pop(inst, None)
                        watched.pop(inst, None)
                woken.update(self._awake)
                self._awake = [inst for inst in self.instances.values() if inst in woken]
            else:
                self._awake = list(self.instances.values())
            woken.clear()
        return self._awake

    def _contain(self, inst: Instruction, exc: Exception) -> None:
        """``inst`` raised: the internal error on it, its axes stopped, noted for the host."""
        self.internal_errors.append((inst.name, exc))
        try:
            inst.fail_internal()
        except Exception as again:  # a broken state table: still report the first one
            self.internal_errors.append((inst.name, again))
        ctl = self.ctl
        for ax in inst.commanded_axes():
            if ax.drive_enabled and any(p.active for p in ax.processes):
                try:
                    ctl.stop(ax, None, ax.config.max_deceleration, bounded=True)
                except MotionError:
                    continue
