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
from typing import Any

from ...kernel import MotionError
from ...kernel.cams import CamMode, CamProcess
from ...kernel.gearing import check_master
from ...kernel.processes import Process
from ..cam_common import scaling
from ..plcopen_common import BUFFER_MODE, MCSource, MotionBlock
from ..registry import register
from ..schema import Operand, Quantity, StatusField, TagType
from .mc_gear_in import CONTINUOUS_UPDATE, MASTER, SLAVE, master_source


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

    def execute(self) -> None:
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
        mo = float(self.op["MasterOffset"])
        so = float(self.op["SlaveOffset"])
        prof = sel.profile
        periodic = sel.periodic
        slave_absolute = sel.slave_absolute and int(self.op["StartMode"]) == StartMode.ABSOLUTE
        master_absolute = sel.master_absolute

        def coupling(m: float) -> tuple[float, int]:
            """(the cam coordinate at coupling inside the range, its period index)."""
            x = (m - mo) / ms if master_absolute else prof.start - mo / ms
            if prof.start <= x <= prof.end:
                return x, 0
            if not periodic:
                raise self.out_of_range(
                    "MasterOffset",
                    f"the master ({m:g}) lies outside the non-periodic table "
                    f"[{prof.start:g}, {prof.end:g}] x MasterScaling + MasterOffset",
                )
            k = int((x - prof.start) // prof.length)
            return x - k * prof.length, k

        distance = float(self.op["MasterStartDistance"])
        x_sync = float(self.op["MasterSyncPosition"])
        if distance > 0.0 and not periodic and not prof.start <= x_sync <= prof.end:
            raise self.out_of_range(
                "MasterSyncPosition",
                f"MasterSyncPosition {x_sync:g} is outside the table "
                f"[{prof.start:g}, {prof.end:g}]",
            )

        def ramp(x0: float) -> tuple[float, float] | None:
            """The ramp-in (x_start, x_sync) ahead of the coupling point ``x0``."""
            if distance <= 0.0:
                return None
            sync = x_sync
            if periodic:
                sync += math.ceil((x0 - sync) / prof.length) * prof.length
                if sync <= x0:
                    sync += prof.length
            elif sync <= x0:
                return None  # past the sync position: coupled at once
            return max(sync - distance, x0), sync

        m_now = ctl.read_master(master.index, source)[0]
        coupling(m_now)  # judged now: a refused coupling moves nothing

        def make(v: float, a: float) -> Process:
            m = ctl.read_master(master.index, source)[0]
            x0, k0 = coupling(m)
            if slave_absolute:
                target = ss * (prof.value(x0) + k0 * prof.rise) + so
                here = slave.command_position_unwound
                origin = slave.unwound_target(target, here) - here
            else:
                origin = so
            return CamProcess(
                ctl,
                prof,
                CamMode.CONTINUOUS if periodic else CamMode.PERSISTENT,
                ss,
                ms,
                x0,
                master=master.index,
                source=source,
                master_number=master.number,
                rollover=master.config.rollover,
                origin=origin,
                ramp_in=ramp(x0),
                owner=self,
            )

        self._passes = 0
        self.begin(slave, make)
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
