"""MC_GearInPos: gearing that locks on at a master and a slave sync position.

The slave follows the master's actual position at RatioNumerator / RatioDenominator (the
denominator's sign is the master's travel direction, the numerator's the slave's). When
the master reaches MasterStartDistance before MasterSyncPosition (StartSync), the slave
locks on so that it arrives at SlaveSyncPosition with the geared velocity exactly when the
master reaches MasterSyncPosition (InSync); it then follows until another command takes
over (CommandAborted). The lock-on is planned in the master-position domain (see
``kernel.gear_in_pos``), so a master that changes speed meanwhile does not spoil it.

Inputs are judged against the seed's SyncMode rules when the motion starts: inconsistent
inputs mean no motion, Error, ErrorID 13. Rotary axes (rollover > 0) sync at the next
occurrence of the sync positions; SyncMode 1 (immediate) needs linear axes, and with the
master at or past its start point or the slave at or beyond its sync position it is in
sync in the scan it starts (the slave placed on its geared position, moving backwards
when it was ahead).

Beyond the seed's outputs: ``SyncState`` (waiting 0, synchronizing 1, in sync 2),
``RemainingMasterDistance`` (master travel left to MasterSyncPosition) and ``Warning``
(excessive lock-on acceleration: MasterStartDistance x |ratio| shorter than the slave's
sync distance, a planned peak above the slave's maximum acceleration, or an immediate
synchronisation; also logged). StartSync stays set once the lock-on has begun.

BufferMode defaults to 1 (buffered, the seed's only value); 0 (aborting) is accepted as
for the other blocks.
"""

from __future__ import annotations

import logging

from ...kernel.gear_in_pos import GearInPosProcess, SyncMode, SyncState, plan_sync
from ...kernel.gearing import MasterSource, check_master
from ...kernel.processes import Process
from ..plcopen_common import BufferMode, MotionBlock
from ..registry import register
from ..schema import Operand, Quantity, StatusField, TagType
from .mc_gear_in import MASTER, SLAVE

log = logging.getLogger(__name__)


@register
class MC_GearInPos(MotionBlock):
    TYPE = "MC_GearInPos"
    DESCRIPTION = "Gear the slave to the master from given sync positions"
    DONE_ON_FINISH = False
    OPERANDS = (
        MASTER,
        SLAVE,
        Operand(
            "RatioNumerator",
            TagType.DINT,
            1,
            quantity=Quantity.RATIO,
            description="signed: its sign is the slave's direction",
        ),
        Operand(
            "RatioDenominator",
            TagType.DINT,
            1,
            quantity=Quantity.RATIO,
            description="signed: its sign is the master's direction (sync trigger)",
        ),
        Operand("MasterSyncPosition", TagType.LREAL, 0.0, quantity=Quantity.POSITION),
        Operand("SlaveSyncPosition", TagType.LREAL, 0.0, quantity=Quantity.POSITION),
        Operand(
            "SyncMode",
            TagType.INT,
            SyncMode.NORMAL,
            enum=SyncMode,
            description="0 normal, 1 immediate (linear axes only)",
        ),
        Operand(
            "MasterStartDistance",
            TagType.LREAL,
            10.0,
            quantity=Quantity.POSITION,
            description="master distance before MasterSyncPosition where lock-on begins",
        ),
        Operand(
            "BufferMode",
            TagType.SINT,
            BufferMode.BUFFERED,
            enum=BufferMode,
            description="1 buffered (0 aborting also accepted)",
        ),
    )
    OUTPUTS = (
        StatusField("StartSync", TagType.BOOL, "the lock-on has begun"),
        StatusField("InSync", TagType.BOOL, "the slave is locked on to the master"),
        StatusField(
            "SyncState", TagType.INT, "waiting 0, synchronizing 1, in sync 2", enum=SyncState
        ),
        StatusField(
            "RemainingMasterDistance",
            TagType.LREAL,
            "master travel left to MasterSyncPosition",
            quantity=Quantity.POSITION,
        ),
        StatusField("Warning", TagType.BOOL, "excessive lock-on acceleration"),
    )

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)
        self._warned = False

    def on_restart(self) -> None:
        self._warned = False

    def execute(self) -> None:
        slave = self.axis("Slave")
        master = self.axis("Master")
        self.check_axis(slave)
        check_master(self.ctl, slave, master, MasterSource.ACTUAL)
        args = (
            int(self.op["RatioNumerator"]),
            int(self.op["RatioDenominator"]),
            float(self.op["MasterSyncPosition"]),
            float(self.op["SlaveSyncPosition"]),
            SyncMode(int(self.op["SyncMode"])),
            float(self.op["MasterStartDistance"]),
        )
        buffered = self.buffered()
        starts_now = not buffered or not any(p.active for p in slave.processes)
        if starts_now:
            # judged against the positions now: inconsistent inputs move nothing
            plan_sync(master, slave, *args, self.ctl.dt(slave))
        ctl = self.ctl

        def make(v: float, a: float) -> Process:
            return GearInPosProcess(ctl, slave, master, *args, v, a, owner=self)

        self.begin(slave, make)

    def poll(self) -> None:
        super().poll()
        p = self.process
        if isinstance(p, GearInPosProcess) and p.warning and not self._warned:
            self._warned = True
            log.warning(
                "%s: excessive lock-on acceleration expected (slave %s); lengthen "
                "MasterStartDistance or move the slave nearer to SlaveSyncPosition",
                self.name,
                self.op["Slave"],
            )

    def publish_extra(self) -> None:
        p = self.process
        busy = bool(self.outputs["Busy"])
        live = busy and isinstance(p, GearInPosProcess) and p.active
        if live:
            assert isinstance(p, GearInPosProcess)
            self.outputs["StartSync"] = p.start_sync
            self.outputs["InSync"] = p.locked
            self.outputs["SyncState"] = int(p.sync_state)
            self.outputs["RemainingMasterDistance"] = p.remaining_master_distance
        else:
            self.outputs["StartSync"] = False
            self.outputs["InSync"] = False
            self.outputs["SyncState"] = int(SyncState.WAITING)
            self.outputs["RemainingMasterDistance"] = 0.0
        self.outputs["Warning"] = self._warned
