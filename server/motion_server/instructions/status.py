"""Status outputs of the two dialects.

Logix: the MOTION_INSTRUCTION word (EN 31, DN 29, ER 28, PC 27, IP 26, AC 23) with ERR and
EXERR. PLCopen: Busy, Active, Done, CommandAborted, Error, ErrorID.
"""

from __future__ import annotations

from enum import IntEnum

from .schema import StatusField, TagType


class LogixBit(IntEnum):
    AC = 23
    IP = 26
    PC = 27
    ER = 28
    DN = 29
    EN = 31


LOGIX_STATUS: tuple[StatusField, ...] = (
    StatusField(
        "FLAGS",
        TagType.UDINT,
        "MOTION_INSTRUCTION status word: bits 31 EN, 29 DN, 28 ER, 27 PC, 26 IP, 23 AC",
    ),
    StatusField("EN", TagType.BOOL, "enable: set on the rung's rising edge"),
    StatusField("DN", TagType.BOOL, "done: the instruction was initiated"),
    StatusField("ER", TagType.BOOL, "error: see ERR and EXERR"),
    StatusField("PC", TagType.BOOL, "process complete"),
    StatusField("IP", TagType.BOOL, "in process"),
    StatusField("AC", TagType.BOOL, "active"),
    StatusField("ERR", TagType.INT, "error code (the shared .ERR table)"),
    StatusField("EXERR", TagType.SINT, "for ERR 13: 0-based index of the offending operand"),
)

PLCOPEN_STATUS: tuple[StatusField, ...] = (
    StatusField("Busy", TagType.BOOL, "the block has not finished"),
    StatusField("Active", TagType.BOOL, "the block controls the axis"),
    StatusField("Done", TagType.BOOL, "finished successfully"),
    StatusField("CommandAborted", TagType.BOOL, "aborted by another command"),
    StatusField("Error", TagType.BOOL, "finished with an error, see ErrorID"),
    StatusField("ErrorID", TagType.UDINT, "error code (the shared .ERR table)"),
)
