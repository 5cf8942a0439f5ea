"""MC_CamIn: engage a cam between a master and a slave (PLCopen Part 1 v2.0).

The slave follows the profile of a selection (MC_CamTableSelect's CamTableID) as a
function of the master's set value (MasterValueSource 0) or actual position (1). The
scalings divide the master and multiply the slave (Beckhoff MC3, Delta and Rockwell's
convention; docs/semantics.md):

    master absolute:  x = (master - MasterOffset) / MasterScaling
    master relative:  x = start + (master - master at coupling - MasterOffset) / MasterScaling
    slave absolute:   slave = SlaveScaling x F(x) + SlaveOffset
    slave relative:   slave = slave at coupling + SlaveScaling x (F(x) - F(x at coupling))
                              + SlaveOffset

with F the profile, repeated for a periodic selection (each period adds its rise, so the
slave moves on continuously) and held at the end values outside the range otherwise
(unlocked; the master coming back drives the slave again). MasterAbsolute and
SlaveAbsolute come from the selection; StartMode 1 (relative) makes the slave relative
whatever the selection says. Absolute coupling places the slave on the cam at once (a
jump if it is not there, as the vendors' absolute modes do; a rotary slave takes the
nearest turn).

Outputs: InSync while the slave follows the cam inside its range (continuously updated,
from set values); EndOfProfile pulses for one cycle each time the profile's end is
reached (its start, running backwards). Busy and Active until another command takes the
slave over (CommandAborted: MC_CamOut, MC_Stop, an aborting move ...). BufferMode 1 waits
for the active motion to be done or in sync.

Ramp-in (MasterStartDistance > 0): MasterSyncPosition and MasterStartDistance are in the
table's master values (CODESYS' ramp_in_dist). The slave stays where it is (Busy, not
Active) until the cam coordinate reaches MasterSyncPosition - MasterStartDistance, then
blends in (Active) along a quintic of the master's travel from rest to the cam's
position, slope and curvature at MasterSyncPosition, where it is InSync. A periodic table
ramps in to the next occurrence of MasterSyncPosition; a coupling already past the
start of the ramp blends over what is left; one past MasterSyncPosition of a non-periodic
table couples at once. The master is expected to advance the cam coordinate forward.

Errors: 13 an unknown CamTableID, a scaling that is zero, not finite or beyond +-2^31, a
non-periodic coupling whose master lies outside the table, a MasterSyncPosition outside a
non-periodic table; 8 a set-value reference to a feedback-only master; 10 a master/slave
loop; 5, 7, 20 the slave's power state, 78 stopping.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Any, NamedTuple

from ...kernel import Axis, AxisType, MotionError
from ...kernel.cam_batch import CamStart
from ...kernel.cam_profile import CamProfile
from ...kernel.cams import CamMode, CamProcess
from ...kernel.enums import MasterReference
from ...kernel.gearing import check_master
from ...kernel.processes import Process
from ..cam_common import scaling
from ..plcopen_common import BUFFER_MODE, MCSource, MotionBlock
from ..registry import register
from ..scan_pass import Batch, BatchKind, takes_motion
from ..schema import Operand, Quantity, StatusField, TagType
from .mc_gear_in import CONTINUOUS_UPDATE, MASTER, SLAVE, master_source

_FEEDBACK_ONLY = AxisType.FEEDBACK_ONLY


class _Coupling(NamedTuple):
    """What ``execute`` judged: the axes, the master's source, the selection's profile
    and flags, the scalings and offsets, the ramp-in's operands."""

    slave: Axis
    master: Axis
    source: MasterReference
    profile: CamProfile
    periodic: bool
    ss: float
    ms: float
    mo: float
    so: float
    slave_absolute: bool
    master_absolute: bool
    distance: float
    x_sync: float


class StartMode(IntEnum):
    ABSOLUTE = 0
    RELATIVE = 1


@register
class MC_CamIn(MotionBlock):
    TYPE = "MC_CamIn"
    DESCRIPTION = "Engage a cam: the slave follows a selected cam table of the master"
    DONE_ON_FINISH = False
    OPERANDS = (
        MASTER,
        SLAVE,
        CONTINUOUS_UPDATE,
        Operand(
            "MasterOffset",
            TagType.LREAL,
            0.0,
            quantity=Quantity.POSITION,
            description="shift of the table's master values (master units)",
        ),
        Operand(
            "SlaveOffset",
            TagType.LREAL,
            0.0,
            quantity=Quantity.POSITION,
            description="shift of the table's slave values (slave units)",
        ),
        Operand("MasterScaling", TagType.LREAL, 1.0, description="divides the master"),
        Operand("SlaveScaling", TagType.LREAL, 1.0, description="multiplies the slave"),
        Operand(
            "MasterStartDistance",
            TagType.LREAL,
            0.0,
            minimum=0.0,
            description="ramp-in distance before MasterSyncPosition (table master units; "
            "0: no ramp-in)",
        ),
        Operand(
            "MasterSyncPosition",
            TagType.LREAL,
            0.0,
            description="table master value where the ramp-in ends in sync",
        ),
        Operand(
            "StartMode",
            TagType.DINT,
            StartMode.ABSOLUTE,
            enum=StartMode,
            description="0 absolute, 1 relative",
        ),
        Operand(
            "MasterValueSource",
            TagType.DINT,
            MCSource.SET_VALUE,
            enum=MCSource,
            description="0 set value (command), 1 actual",
        ),
        Operand("CamTableID", TagType.UDINT, 0, description="from MC_CamTableSelect"),
        BUFFER_MODE,
    )
    OUTPUTS = (
        StatusField("InSync", TagType.BOOL, "the slave follows the cam inside its range"),
        StatusField("EndOfProfile", TagType.BOOL, "pulse: the profile's end was reached"),
    )

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._passes = 0

    #: rising edges in one scan (aborting, no ramp-in, the slave without motion) start
    #: their cams with one ``start_position_cams``
    BATCH = BatchKind.POSITION_CAM

    def _judged(self) -> _Coupling:
        """The checks of ``execute`` before its command, and what the cam is built from."""
        ctl = self.ctl
        slave = self.axis("Slave")
        master = self.axis("Master")
        self.check_axis(slave)
        source = master_source(int(self.op["MasterValueSource"]))
        check_master(ctl, slave, master, source)
        try:
            sel = ctl.cams.selection(int(self.op["CamTableID"]))
        except MotionError:
            raise self.out_of_range(
                "CamTableID", f"no cam table selected as {self.op['CamTableID']}"
            ) from None
        ms = scaling(self, "MasterScaling")
        ss = scaling(self, "SlaveScaling")
        prof = sel.profile
        distance = float(self.op["MasterStartDistance"])
        x_sync = float(self.op["MasterSyncPosition"])
        if distance > 0.0 and not sel.periodic and not prof.start <= x_sync <= prof.end:
            raise self.out_of_range(
                "MasterSyncPosition",
                f"MasterSyncPosition {x_sync:g} is outside the table "
                f"[{prof.start:g}, {prof.end:g}]",
            )
        return _Coupling(
            slave,
            master,
            source,
            prof,
            sel.periodic,
            ss,
            ms,
            float(self.op["MasterOffset"]),
            float(self.op["SlaveOffset"]),
            sel.slave_absolute and int(self.op["StartMode"]) == StartMode.ABSOLUTE,
            sel.master_absolute,
            distance,
            x_sync,
        )

    def _coupling(self, c: _Coupling, m: float) -> tuple[float, int]:
        """(the cam coordinate at coupling on the master's value ``m``, inside the range,
        and its period index)."""
        prof = c.profile
        x = (m - c.mo) / c.ms if c.master_absolute else prof.start - c.mo / c.ms
        if prof.start <= x <= prof.end:
            return x, 0
        if not c.periodic:
            raise self.out_of_range(
                "MasterOffset",
                f"the master ({m:g}) lies outside the non-periodic table "
                f"[{prof.start:g}, {prof.end:g}] x MasterScaling + MasterOffset",
            )
        k = int((x - prof.start) // prof.length)
        return x - k * prof.length, k

    @staticmethod
    def _origin(c: _Coupling, x0: float, k0: int) -> float:
        """The cam's origin: an absolute slave placed on the cam (the nearest turn of a
        rotary one), else the SlaveOffset."""
        if not c.slave_absolute:
            return c.so
        prof = c.profile
        target = c.ss * (prof.value(x0) + k0 * prof.rise) + c.so
        here = c.slave.command_position_unwound
        return c.slave.unwound_target(target, here) - here

    @staticmethod
    def _ramp(c: _Coupling, x0: float) -> tuple[float, float] | None:
        """The ramp-in (x_start, x_sync) ahead of the coupling point ``x0``."""
        if c.distance <= 0.0:
            return None
        prof = c.profile
        sync = c.x_sync
        if c.periodic:
            sync += math.ceil((x0 - sync) / prof.length) * prof.length
            if sync <= x0:
                sync += prof.length
        elif sync <= x0:
            return None  # past the sync position: coupled at once
        return max(sync - c.distance, x0), sync

    def execute(self) -> None:
        ctl = self.ctl
        c = self._judged()
        master = c.master
        self._coupling(c, ctl.read_master(master.index, c.source)[0])  # judged now

        def make(v: float, a: float) -> Process:
            x0, k0 = self._coupling(c, ctl.read_master(master.index, c.source)[0])
            return CamProcess(
                ctl,
                c.profile,
                CamMode.CONTINUOUS if c.periodic else CamMode.PERSISTENT,
                c.ss,
                c.ms,
                x0,
                master=master.index,
                source=c.source,
                master_number=master.number,
                rollover=master.config.rollover,
                origin=self._origin(c, x0, k0),
                ramp_in=self._ramp(c, x0),
                owner=self,
            )

        self._passes = 0
        self.begin(c.slave, make)
        self._count()

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the cam returned as a
        :class:`~...kernel.cam_batch.CamStart` for ``start_position_cams``; None (executed
        alone) for a buffered block, a ramp-in, or a slave with motion, a cam preloaded
        or a command buffered (the batch starts cams on slaves at rest, where the
        aborting mode replaces nothing). A cam whose slave is an axis of the queue, or
        whose master is a queued slave or follows one, hands the queue over first, so
        that its checks see the cams queued before it. Raises what ``execute`` raises
        before its command (the block's own scan then shows it)."""
        op = self.op
        if self.buffered() or float(op["MasterStartDistance"]) > 0.0:
            return None
        s, m = int(op["Slave"]), int(op["Master"])
        loops, reaches = batch.reaching(m, s)
        flushed = reaches or s in batch.axes
        if flushed:
            batch.flush()  # its checks see the cams queued before it (in full: ``_judged``)
        slave = self.axis("Slave")
        if (
            slave._processes
            or slave.stop_rows is not None
            or slave.preloaded_cams
            or slave.buffered is not None
        ):
            return None
        # what the checks find from the values and the selection alone (the judge's key
        # and the selection the CamTableID names): worked out once per set of them in a
        # scan pass
        ctl = self.ctl
        sel = None if flushed or key is None else ctl.cams.selections.get(int(op["CamTableID"]))
        memo = None if sel is None else (MC_CamIn, key, id(sel))
        values = None if memo is None else batch.plans.get(memo)
        if values is None:
            c = self._judged()
            if memo is not None:
                batch.plans[memo] = c[3:]
        else:
            # ``_judged``'s checks in its order, in full only where they refuse
            master = self.axis("Master")
            if not takes_motion(slave) or slave.stopping:
                self.check_axis(slave)
            source = master_source(int(op["MasterValueSource"]))
            if loops or (source == MasterReference.COMMAND and master.type is _FEEDBACK_ONLY):
                check_master(ctl, slave, master, source)
            c = _Coupling(slave, master, source, *values)
        master = c.master
        # (the master's value and the slave's position do not change until the step:
        # read now, they are what the cam's factory would read when the batch starts it)
        x0, k0 = self._coupling(c, ctl.read_master(master.index, c.source)[0])
        start = CamStart(
            slave,
            master,
            c.profile,
            CamMode.CONTINUOUS if c.periodic else CamMode.PERSISTENT,
            c.ss,
            c.ms,
            x0,
            c.source,
            self._origin(c, x0, k0),
            owner=self,
        )
        return start, (s, master.number)

    def batch_started(self, process: Process) -> None:
        self._passes = 0
        super().batch_started(process)
        self._count()

    def _count(self) -> None:
        """Count the cam on its profile's slot (Status) once it has started."""
        p = self.process
        if isinstance(p, CamProcess) and p.profile.source in self.ctl.cams.slots:
            self.ctl.cams.register(p.profile.source, p)

    def poll(self) -> None:
        waiting = self.process is None
        super().poll()
        if waiting:
            self._count()  # a buffered cam that started now

    def publish_extra(self) -> None:
        p = self.process
        in_sync = eop = False
        if isinstance(p, CamProcess) and p.active and self.outputs["Busy"]:
            if p.lane is not None:
                p.lane.sync(p)
            in_sync = p.locked
            eop = p.passes != self._passes
            self._passes = p.passes
        self.outputs["InSync"] = in_sync
        self.outputs["EndOfProfile"] = eop
        if isinstance(p, CamProcess) and p.ramp is not None and not p.ramping:
            self.outputs["Active"] = False  # waiting for the ramp-in to start
