"""Read-only axis configuration tags and the float32 (REAL) mirrors of LREAL axis values.

An HMI needs an axis's configuration to turn "% of maximum" into units, a fraction gear
ratio into a real one, or to scale a bar graph: ``<Axis>.ConversionConstant``,
``PositionUnits`` (the units' UNECE code as an OPC UA UnitId, e.g. 5066068 = MMT, mm),
``Rollover``, ``MaxVelocity``, ``MaxAcceleration``, ``MaxDeceleration``, ``MaxJerk``,
``ProgrammedStopMode``, ``CoastDeceleration``, ``FollowingErrorLimit``. They are static:
fixed by the site map for the server's life.

Panels and tools that cannot read a 64-bit LREAL (mbpoll among them) get, with
``[modbus] real_mirrors = true``, a REAL copy of each LREAL axis value:
``<Axis>.ActualPositionREAL`` mirrors ``ActualPosition`` and so on (float32: about seven
significant digits).

Both live in the axis's configuration block (``[modbus] axis_config_base`` + 50·k, the
configuration first, then the mirrors) and under the axis's OPC UA object.
"""

from __future__ import annotations

from collections.abc import Callable

from ..instructions.schema import Quantity, TagType
from ..kernel import Axis, ProgrammedStopMode
from ..kernel.enums import HomeDirection, HomeMode, HomeSequence
from .codec import Value
from .fields import FieldSpec
from .units import unit_id

CONFIG_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec("ConversionConstant", TagType.REAL, description="feedback counts per position unit"),
    FieldSpec(
        "Rollover",
        TagType.REAL,
        quantity=Quantity.POSITION,
        description="rotary axis: positions read in [0, Rollover); 0: linear",
    ),
    FieldSpec("MaxVelocity", TagType.REAL, quantity=Quantity.VELOCITY),
    FieldSpec("MaxAcceleration", TagType.REAL, quantity=Quantity.ACCELERATION),
    FieldSpec("MaxDeceleration", TagType.REAL, quantity=Quantity.ACCELERATION),
    FieldSpec(
        "MaxJerk",
        TagType.REAL,
        quantity=Quantity.JERK,
        description="0: unlimited (trapezoidal profiles)",
    ),
    FieldSpec(
        "CoastDeceleration",
        TagType.REAL,
        quantity=Quantity.ACCELERATION,
        description="deceleration of a disabled axis coasting to rest",
    ),
    FieldSpec(
        "FollowingErrorLimit",
        TagType.REAL,
        quantity=Quantity.POSITION,
        description="position error that faults the axis; 0: no limit",
    ),
    FieldSpec(
        "PositionUnits",
        TagType.DINT,
        description="position units: UNECE common code as OPC UA UnitId "
        "(5066068 MMT mm, 17476 DD degree, 5067858 MTR m); -1 none",
    ),
    FieldSpec("ProgrammedStopMode", TagType.INT, enum=ProgrammedStopMode),
)

#: the axis's homing configuration (after the REAL mirrors in the configuration block:
#: they keep their registers)
HOMING_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec(
        "HomeMode", TagType.INT, enum=HomeMode, description="MAH: 0 passive, 1 active, 2 absolute"
    ),
    FieldSpec(
        "HomeSequence",
        TagType.INT,
        enum=HomeSequence,
        description="0 immediate, 1 switch, 2 marker, 3 switch then marker",
    ),
    FieldSpec(
        "HomeDirection",
        TagType.INT,
        enum=HomeDirection,
        description="0 forward uni-, 1 forward bi-, 2 reverse uni-, 3 reverse bidirectional",
    ),
    FieldSpec(
        "HomePosition",
        TagType.REAL,
        quantity=Quantity.POSITION,
        description="where an active homing sequence leaves the axis",
    ),
    FieldSpec(
        "HomeOffset",
        TagType.REAL,
        quantity=Quantity.POSITION,
        description="the home event reads HomePosition - HomeOffset",
    ),
    FieldSpec("HomeSpeed", TagType.REAL, quantity=Quantity.VELOCITY),
    FieldSpec("HomeReturnSpeed", TagType.REAL, quantity=Quantity.VELOCITY),
)

#: configuration field -> its value on an axis
CONFIG_GETTERS: dict[str, Callable[[Axis], Value]] = {
    "ConversionConstant": lambda ax: ax.config.conversion_constant,
    "Rollover": lambda ax: ax.config.rollover,
    "MaxVelocity": lambda ax: ax.system_config.max_velocity,
    "MaxAcceleration": lambda ax: ax.system_config.max_acceleration,
    "MaxDeceleration": lambda ax: ax.system_config.max_deceleration,
    "MaxJerk": lambda ax: ax.system_config.max_jerk,
    "CoastDeceleration": lambda ax: ax.config.coast_deceleration,
    "FollowingErrorLimit": lambda ax: ax.config.following_error_limit,
    "PositionUnits": lambda ax: unit_id(ax.config.units),
    "ProgrammedStopMode": lambda ax: int(ax.config.programmed_stop_mode),
    "HomeMode": lambda ax: int(ax.config.home_mode),
    "HomeSequence": lambda ax: int(ax.config.home_sequence),
    "HomeDirection": lambda ax: int(ax.config.home_direction),
    "HomePosition": lambda ax: ax.config.home_position,
    "HomeOffset": lambda ax: ax.config.home_offset,
    "HomeSpeed": lambda ax: ax.config.home_speed,
    "HomeReturnSpeed": lambda ax: ax.config.home_return_speed,
}

#: REAL mirror field -> the LREAL axis field it copies
MIRRORS: dict[str, str] = {
    f"{source}REAL": source
    for source in (
        "ActualPosition",
        "CommandPosition",
        "ActualVelocity",
        "CommandVelocity",
        "CommandAcceleration",
        "PositionError",
    )
}


def mirror_fields(sources: tuple[FieldSpec, ...]) -> tuple[FieldSpec, ...]:
    """The REAL mirror of each LREAL field in ``sources`` that has one."""
    by_name = {s.name: s for s in sources}
    return tuple(
        FieldSpec(
            mirror,
            TagType.REAL,
            quantity=by_name[source].quantity,
            description=f"float32 copy of {source} (for panels without LREAL)",
        )
        for mirror, source in MIRRORS.items()
        if source in by_name
    )
