"""MC_CamTableSelect: select a cam table for MC_CamIn (PLCopen Part 1 v2.0).

The table's first ``Length`` points (the table's writable ``Length`` tag) are computed
into its profile (linear and cubic segments as for MCCP, slopes 0 at both ends), a
snapshot: a cam that runs on an earlier selection keeps it, and editing the table
afterwards changes nothing until the next selection (PLCopen implementations that
reference the table warn against editing it while a cam runs; the snapshot makes that
safe). ``CamTableID`` names the selection for MC_CamIn, together with how it runs:
``Periodic`` (the profile repeats) or not (the slave holds at the ends), and
``MasterAbsolute`` / ``SlaveAbsolute`` (see MC_CamIn). Selecting changes no axis state.
Done in the scan of the rising edge. ``ExecutionMode`` (1 immediately, 2 queued) is
accepted with both values: the selection takes effect for the next MC_CamIn either way,
since a running cam never changes its profile. The newest 256 selections are kept.

Errors: ErrorID 13 a table that does not exist or a Master/Slave that is not an axis, 26
a Length below 2 or beyond the table, 28 a segment type other than 0 or 1, 29 master
values not strictly increasing.
"""

from __future__ import annotations

from enum import IntEnum

from ..base import BlockEvent, PLCopenBlock
from ..registry import register
from ..schema import Operand, StatusField, TagType
from .mc_gear_in import MASTER, SLAVE


class CamExecutionMode(IntEnum):
    IMMEDIATELY = 1
    QUEUED = 2


@register
class MC_CamTableSelect(PLCopenBlock):
    TYPE = "MC_CamTableSelect"
    DESCRIPTION = "Select a cam table (a profile snapshot) for MC_CamIn"
    OPERANDS = (
        MASTER,
        SLAVE,
        Operand("CamTable", TagType.DINT, 1, minimum=1, description="cam table number"),
        Operand("Periodic", TagType.BOOL, True, description="the profile repeats"),
        Operand(
            "MasterAbsolute",
            TagType.BOOL,
            True,
            description="the table's master values are "
            "master positions (else relative to the master at coupling)",
        ),
        Operand(
            "SlaveAbsolute",
            TagType.BOOL,
            True,
            description="the table's slave values are "
            "slave positions (else relative to the slave at coupling)",
        ),
        Operand(
            "ExecutionMode",
            TagType.DINT,
            CamExecutionMode.IMMEDIATELY,
            enum=CamExecutionMode,
            description="1 immediately, 2 queued",
        ),
    )
    OUTPUTS = (StatusField("CamTableID", TagType.UDINT, "the selection, for MC_CamIn"),)

    def execute(self) -> None:
        table = int(self.op["CamTable"])
        if table not in self.ctl.cams.tables:
            raise self.out_of_range("CamTable", f"cam table {table} does not exist")
        self.outputs["CamTableID"] = self.ctl.cams.select(
            table,
            bool(self.op["Periodic"]),
            bool(self.op["MasterAbsolute"]),
            bool(self.op["SlaveAbsolute"]),
        )
        self.fire(BlockEvent.START)
        self.fire(BlockEvent.COMPLETE)
