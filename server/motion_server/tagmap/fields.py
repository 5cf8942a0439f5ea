"""The tags that are not instruction operands: axis, group, diagnostics and clock fields.

Instruction tags come from each instruction class's own schema (``input_operands()`` and
``status_fields()``); these tables are the equivalent schema for the other owners. The
live values behind them are bound in :mod:`.image`.
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass
from enum import IntEnum

from ..instructions.schema import Quantity, TagType
from ..kernel import AxisState, AxisType, GroupState, PLCopenState


class ClockMode(IntEnum):
    """``Clock.Mode``: how simulated time advances (DESIGN.md, "The scan")."""

    REALTIME = 0
    MANUAL = 1
    SCALED = 2
    #: cycles back to back, as fast as the CPU allows (test benches, co-simulation)
    FAST = 3


class CommFault(IntEnum):
    """``Clock.CommFault``: what happens to the answers a client gets (for testing an
    HMI's timeouts; the Modbus front-end applies it, ``Clock.CommClientPort`` says to whom)."""

    NONE = 0
    #: every answer is sent ``Clock.CommDelay`` ms late
    DELAY = 1
    #: requests are served, their answers never sent
    DROP = 2


@dataclass(frozen=True)
class FieldSpec:
    """One field of a non-instruction owner. ``units`` fixes the units; otherwise they
    follow ``quantity`` and the owner's axis units."""

    name: str
    type: TagType
    writable: bool = False
    quantity: Quantity = Quantity.NONE
    enum: builtins.type[IntEnum] | None = None
    description: str = ""
    units: str = ""


MOTION_STATUS_BITS = (
    "bits: 0 Accel, 1 Decel, 2 Move, 3 Jog, 4 Gearing, 5 Homing, 6 Stopping, 7 Homed, "
    "8 PositionCam, 9 TimeCam, 10 PositionCamPending, 11 TimeCamPending, 12 GearingLock, "
    "13 PositionCamLock, 14 TimeCamLock, 19 DirectVelocityControl, 20 DirectTorqueControl"
)

AXIS_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec("Number", TagType.DINT, description="axis number (what axis operands hold)"),
    FieldSpec("Type", TagType.INT, enum=AxisType, description="servo, virtual, feedback only"),
    FieldSpec("AxisState", TagType.INT, enum=AxisState, description="Logix power state"),
    FieldSpec("PLCopenState", TagType.INT, enum=PLCopenState, description="PLCopen axis state"),
    FieldSpec(
        "MotionStatus", TagType.UDINT, description="Logix MotionStatus " + MOTION_STATUS_BITS
    ),
    FieldSpec(
        "AxisFault",
        TagType.UDINT,
        description="fault bits: 0 position error, 1 profile, 2 communication watchdog, "
        "3 numeric (a value the kernel could not compute)",
    ),
    FieldSpec("ActualPosition", TagType.LREAL, quantity=Quantity.POSITION),
    FieldSpec("CommandPosition", TagType.LREAL, quantity=Quantity.POSITION),
    FieldSpec("ActualVelocity", TagType.LREAL, quantity=Quantity.VELOCITY),
    FieldSpec("CommandVelocity", TagType.LREAL, quantity=Quantity.VELOCITY),
    FieldSpec("CommandAcceleration", TagType.LREAL, quantity=Quantity.ACCELERATION),
    FieldSpec(
        "PositionError",
        TagType.LREAL,
        quantity=Quantity.POSITION,
        description="command minus actual position (following error)",
    ),
)

#: only feedback-only axes with ``feedback_signal = "input"`` (a hand wheel) have it
FEEDBACK_INPUT = FieldSpec(
    "FeedbackInput",
    TagType.LREAL,
    writable=True,
    quantity=Quantity.POSITION,
    description="hand-wheel reading: the actual position taken at the next cycle",
)

#: only axes with a home switch (``home_switch``) have it
HOME_SWITCH = FieldSpec(
    "HomeSwitch",
    TagType.BOOL,
    description="the simulated home switch is engaged (the load is on its cam)",
)

#: only axes with an encoder marker (``marker_interval`` > 0) have it
MARKER = FieldSpec(
    "Marker",
    TagType.BOOL,
    description="an encoder marker was passed in the last cycle",
)

GROUP_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec("Number", TagType.DINT, description="group number (what group operands hold)"),
    FieldSpec("GroupState", TagType.INT, enum=GroupState),
    FieldSpec("CoarseUpdatePeriod", TagType.REAL, units="ms"),
    FieldSpec("AxisCount", TagType.INT, description="number of axes in the group"),
)


def group_member(k: int) -> FieldSpec:
    """``GroupN.Member<k>``: the number of the group's k-th axis (1-based k)."""
    return FieldSpec(f"Member{k}", TagType.DINT, description=f"axis number of member {k}")


DIAGNOSTICS_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec("Heartbeat", TagType.UDINT, description="incremented every cycle (wraps at 2^32)"),
    FieldSpec("CycleTime", TagType.REAL, units="us", description="CPU time of the last cycle"),
    FieldSpec("MaxCycleTime", TagType.REAL, units="us", description="longest cycle so far"),
    FieldSpec("Overruns", TagType.UDINT, description="cycles that started late (realtime)"),
    FieldSpec("DroppedCycles", TagType.UDINT, description="cycles dropped beyond the catch-up"),
    FieldSpec("VersionMajor", TagType.INT, description="server version, major"),
    FieldSpec("VersionMinor", TagType.INT, description="server version, minor"),
    FieldSpec("VersionPatch", TagType.INT, description="server version, patch"),
    FieldSpec("AxisCount", TagType.INT),
    FieldSpec("GroupCount", TagType.INT),
    FieldSpec("InstanceCount", TagType.INT, description="instruction instances"),
    FieldSpec(
        "ScanLoad",
        TagType.REAL,
        units="%",
        description="share of the last second the scan spent running cycles",
    ),
    FieldSpec(
        "QueuedWrites",
        TagType.UDINT,
        description="client write batches waiting for the next cycle when the last one began",
    ),
    FieldSpec(
        "FrontendRestarts",
        TagType.UDINT,
        description="front-end processes restarted after they died (motion went on)",
    ),
    FieldSpec(
        "Ready",
        TagType.BOOL,
        description="1 while the controller runs (the scan cycles); 0 while it starts or stops",
    ),
    # after Ready: placed after its register, which kept its place
    FieldSpec(
        "ProfileFallbacks",
        TagType.UDINT,
        description="jerk-limited velocity targets the closed-form S-curve left to ruckig "
        "(since the scan started)",
    ),
)


def clock_fields(remote_clock: bool) -> tuple[FieldSpec, ...]:
    """Clock tags; with ``remote_clock = false`` the command fields are read-only."""
    w = remote_clock
    return (
        FieldSpec(
            "Step",
            TagType.BOOL,
            writable=w,
            description="rising edge: run StepCycles cycles (manual mode; the write is "
            "answered once they ran)",
        ),
        FieldSpec("Mode", TagType.INT, writable=w, enum=ClockMode),
        FieldSpec("StepCycles", TagType.UDINT, writable=w, description="cycles per Step edge"),
        FieldSpec("Cycle", TagType.UDINT, description="completed cycles (wraps at 2^32)"),
        FieldSpec("SimTime", TagType.LREAL, units="s", description="simulated time"),
        FieldSpec("Period", TagType.REAL, units="ms", description="base period of a cycle"),
        FieldSpec("Scale", TagType.REAL, description="simulated s per real s (scaled mode)"),
        # added after the fields above: their registers did not move
        FieldSpec(
            "SnapshotSave",
            TagType.BOOL,
            writable=w,
            description="rising edge: save the controller state as snapshot <Snapshot> "
            "(answered once saved; reads 0 again after)",
        ),
        FieldSpec(
            "SnapshotRestore",
            TagType.BOOL,
            writable=w,
            description="rising edge: restore snapshot <Snapshot> (answered once restored; "
            "reads 0 again after)",
        ),
        FieldSpec("Snapshot", TagType.UDINT, writable=w, description="snapshot number (its name)"),
        FieldSpec(
            "CommFault",
            TagType.INT,
            writable=w,
            enum=CommFault,
            description="answers to CommClientPort (0: every client): 1 delayed by CommDelay, "
            "2 dropped; for CommDuration ms, then 0 again",
        ),
        FieldSpec("CommDelay", TagType.UDINT, writable=w, units="ms"),
        FieldSpec(
            "CommDuration", TagType.UDINT, writable=w, units="ms", description="0: until cleared"
        ),
        FieldSpec(
            "CommClientPort",
            TagType.UDINT,
            writable=w,
            description="TCP port of the one client affected; 0: every client",
        ),
    )


#: a communication watchdog's block (``[[watchdogs]]``): ``<name>.<field>``; its values
#: are bound by the runtime (``motion_server.safety.watchdog``)
WATCHDOG_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec("Fault", TagType.BOOL, description="latched: the heartbeat stopped (reset needed)"),
    FieldSpec(
        "State",
        TagType.INT,
        description="0 idle (no heartbeat yet), 1 armed, 2 stopping, 3 faulted",
    ),
    FieldSpec("Trips", TagType.UDINT, description="times the watchdog has tripped"),
    FieldSpec("Age", TagType.UDINT, description="cycles since the oldest supervised beat"),
    FieldSpec("Reset", TagType.BOOL, writable=True, description="rising edge: clear the fault"),
    FieldSpec(
        "Heartbeat", TagType.UDINT, writable=True, description="change it at least every timeout"
    ),
)

#: the header of a cam table's block (``[[cams]]``), before its elements
CAM_HEADER: tuple[FieldSpec, ...] = (
    FieldSpec(
        "ProfileStatus",
        TagType.DINT,
        description="CAM_PROFILE Status: 0 not calculated, 1 being calculated, 2 calculated, "
        "n = calculated and in use by n - 2 cams",
    ),
    FieldSpec("Capacity", TagType.DINT, description="elements the table holds"),
    FieldSpec(
        "Number",
        TagType.DINT,
        description="cam table number (what the cam instructions' table and profile operands hold)",
    ),
    FieldSpec(
        "Length",
        TagType.DINT,
        writable=True,
        description="elements MC_CamTableSelect uses (from element 0)",
    ),
)
#: the fields of one cam element (the Logix CAM: REAL, REAL, DINT), in register order
CAM_ELEMENT_FIELDS = ("Master", "Slave", "SegmentType")


def cam_element(field: str, k: int) -> FieldSpec:
    """``<cam>.<field>[k]``: one value of element ``k`` (0-based) of a cam table."""
    if field == "SegmentType":
        return FieldSpec(
            f"SegmentType[{k}]",
            TagType.DINT,
            writable=True,
            description=f"element {k}: segment to the next element, 0 linear, 1 cubic",
        )
    what = "master (x)" if field == "Master" else "slave (y)"
    return FieldSpec(
        f"{field}[{k}]", TagType.REAL, writable=True, description=f"element {k}: {what} value"
    )


def cam_fields(capacity: int) -> tuple[FieldSpec, ...]:
    """Every field of a cam table of ``capacity`` elements, in register order."""
    elements = (cam_element(f, k) for k in range(capacity) for f in CAM_ELEMENT_FIELDS)
    return (*CAM_HEADER, *elements)


def cam_element_of(field: str) -> tuple[str, int] | None:
    """(``Master``, 3) for ``Master[3]``; None for a header field."""
    name, sep, rest = field.partition("[")
    if not sep or name not in CAM_ELEMENT_FIELDS:
        return None
    return name, int(rest.rstrip("]"))


UNITS_SUFFIX: dict[Quantity, str] = {
    Quantity.POSITION: "",
    Quantity.VELOCITY: "/s",
    Quantity.ACCELERATION: "/s²",
    Quantity.JERK: "/s³",
}


def units_of(quantity: Quantity, axis_units: str) -> str:
    """Engineering units of a quantity on an axis measured in ``axis_units``."""
    if quantity == Quantity.PERCENT:
        return "%"
    if quantity in UNITS_SUFFIX and axis_units:
        return axis_units + UNITS_SUFFIX[quantity]
    return ""
