"""Operand definitions shared by several instruction types (one place, many schemas)."""

from __future__ import annotations

from .dynamics import AccelUnits, JerkUnits, MergeMode, MergeSpeed, ProfileType, SpeedUnits
from .schema import Kind, Operand, Quantity, StatusField, TagType

AXIS = Operand("Axis", TagType.DINT, 1, kind=Kind.AXIS, description="axis number (1-based)")
SLAVE_AXIS = Operand("SlaveAxis", TagType.DINT, 2, kind=Kind.AXIS, description="slave axis number")
MASTER_AXIS = Operand(
    "MasterAxis", TagType.DINT, 1, kind=Kind.AXIS, description="master axis number"
)
GROUP = Operand("Group", TagType.DINT, 1, kind=Kind.GROUP, description="motion group number")

#: MAJ/MAM status in master-driven mode: the slave follows its master at the programmed
#: speed (after a change of master: the change is finished)
TRACKING_MASTER = StatusField(
    "TrackingMaster", TagType.BOOL, "master-driven: the slave is tracking its master"
)


def logix_dynamics(default_speed: float = 10.0) -> tuple[Operand, ...]:
    """Speed, AccelRate ... MergeSpeed as MAJ and MAM share them."""
    return (
        Operand(
            "Speed",
            TagType.REAL,
            default_speed,
            minimum=0.0,
            quantity=Quantity.VELOCITY,
            description="speed (units/s, % of maximum, or units per master unit)",
        ),
        Operand(
            "SpeedUnits",
            TagType.DINT,
            0,
            enum=SpeedUnits,
            description="0 units/s, 1 % of maximum, 4 units per master unit (MDAC)",
        ),
        Operand(
            "AccelRate",
            TagType.REAL,
            100.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.ACCELERATION,
        ),
        Operand(
            "AccelUnits",
            TagType.DINT,
            0,
            enum=AccelUnits,
            description="0 units/s^2, 1 % of maximum, 4 units per master unit^2 (MDAC)",
        ),
        Operand(
            "DecelRate",
            TagType.REAL,
            100.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.ACCELERATION,
        ),
        Operand(
            "DecelUnits",
            TagType.DINT,
            0,
            enum=AccelUnits,
            description="0 units/s^2, 1 % of maximum, 4 units per master unit^2 (MDAC)",
        ),
        Operand("Profile", TagType.DINT, 0, enum=ProfileType),
        Operand("AccelJerk", TagType.REAL, 100.0, minimum=0.0, quantity=Quantity.JERK),
        Operand("DecelJerk", TagType.REAL, 100.0, minimum=0.0, quantity=Quantity.JERK),
        Operand(
            "JerkUnits",
            TagType.DINT,
            2,
            enum=JerkUnits,
            description="0 units/s^3, 1 % of maximum, 2 % of time, 4 units per master unit^3",
        ),
        Operand("Merge", TagType.DINT, 0, enum=MergeMode),
        Operand("MergeSpeed", TagType.DINT, 0, enum=MergeSpeed),
    )


def plcopen_dynamics(with_velocity: bool = True) -> tuple[Operand, ...]:
    ops = []
    if with_velocity:
        ops.append(
            Operand(
                "Velocity",
                TagType.LREAL,
                10.0,
                minimum=0.0,
                exclusive_min=True,
                quantity=Quantity.VELOCITY,
            )
        )
    ops += [
        Operand(
            "Acceleration",
            TagType.LREAL,
            100.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.ACCELERATION,
        ),
        Operand(
            "Deceleration",
            TagType.LREAL,
            100.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.ACCELERATION,
        ),
        Operand(
            "Jerk",
            TagType.LREAL,
            0.0,
            minimum=0.0,
            quantity=Quantity.JERK,
            description="0: trapezoidal",
        ),
    ]
    return tuple(ops)
