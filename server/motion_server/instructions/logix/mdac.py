"""MDAC, Master Driven Axis Control: assign a master axis to a slave for master units.

After an MDAC, a MAJ or MAM on the slave whose rates are in master units runs
master-driven: the slave's speed is the programmed speed times the master's speed.

MotionType Time Cam (3) makes MATC master driven (its profile runs on the master's travel).

Status: DN when executed; IP while the assignment is in place, including while a
reassignment to a second master is pending (the slave switches when its next MAJ/MAM
goes IP); AC while a master-driven motion runs under it. MotionType: All 0, Jog 1,
Move 2; MasterReference: Actual 0, Command 1 (a virtual master is always read at its
command, a feedback-only master at its actual position).

Errors: the same axis as master and slave is refused (ERR 13 naming MasterAxis, a
verification error on a real controller); a feedback-only slave ERR 8; cross-coupled
axes ERR 10; a type other than All while an MDAC All is in place, a new master for a Jog
or Move assignment that no stop has broken, or a new master reference while the slave
moves: ERR 105. The link breaks (IP and AC reset) on MAS All, MGS, MASD, MGSD or a fault
on the slave, on MGS, MASD, MGSD or a fault on the master, and on leaving run mode;
after an MGS, AC is reset once the slave has stopped.
"""

from __future__ import annotations

from ...kernel.master_driven import MasterReference, MotionType
from ...kernel.mdac_links import MasterLink
from ..base import LogixInstruction
from ..operands import MASTER_AXIS, SLAVE_AXIS
from ..registry import register
from ..schema import Operand, TagType


@register
class MDAC(LogixInstruction):
    TYPE = "MDAC"
    DESCRIPTION = "Master Driven Axis Control"
    #: MDAC(SlaveAxis, MasterAxis, MotionControl, MotionType, MasterReference)
    MOTION_CONTROL_INDEX = 2
    OPERANDS = (
        SLAVE_AXIS,
        MASTER_AXIS,
        Operand(
            "MotionType",
            TagType.DINT,
            0,
            enum=MotionType,
            description="0 all, 1 jog, 2 move, 3 time cam",
        ),
        Operand(
            "MasterReference",
            TagType.DINT,
            0,
            enum=MasterReference,
            description="0 actual, 1 command",
        ),
    )

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.link: MasterLink | None = None

    def execute(self) -> None:
        slave = self.axis("SlaveAxis")
        master = self.axis("MasterAxis")
        if slave.number == master.number:
            raise self.out_of_range("MasterAxis", "the master must be another axis than the slave")
        self.link = self.ctl.mdsc.assign(
            slave,
            master,
            MotionType(int(self.op["MotionType"])),
            MasterReference(int(self.op["MasterReference"])),
            owner=self,
        )
        self.set_bits(DN=True)
        self.poll()

    def poll(self) -> None:
        link = self.link
        if link is None:
            return
        self.set_bits(IP=link.in_process, AC=link.active)
        if not (link.in_process or link.active):
            self.link = None
