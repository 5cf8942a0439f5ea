"""The FMU's variables: one per tag of the site's tag map, named like the tag.

The list comes from the same :class:`~motion_server.tagmap.TagMap` as the Modbus map and
the OPC UA model, so a tag and its FMU variable cannot disagree. Names are the tag names
(``MAG_1.DN``, ``Axis1.ActualPosition``, ``Cam1.Master[0]``): FMI's structured naming.

What each tag becomes:

- **input** (variability discrete): every writable tag except the ``Clock`` folder's: the
  instruction operands and triggers (``MAG_1.Ratio``, ``MAG_1.Execute``), the plant side
  the site map models (a feedback-only axis's ``FeedbackInput``, the ``Inject*`` fault
  inputs of each axis), cam table points and watchdog tags. The ``Clock`` folder's
  command tags (``Step``, ``Mode``, snapshots, communication faults) are left out: while
  the master steps the FMU, it owns time.
- **parameter** (variability fixed): what the site map fixes for the server's life:
  each axis's configuration block (``ConversionConstant``, ``MaxVelocity``, ...), axis
  and group numbers, types and members, the group's coarse update period,
  ``Clock.Period`` and the version and size counters of ``Diagnostics``. A master may
  set a parameter to the value it has (as some do with every parameter at
  initialization); any other value is refused with an error (fmi2Error): change the site
  map and build the FMU again.
- **output**: every other read-only tag: positions, velocities, every status bit and word.

Every variable has ``initial="exact"``: its start value is what the image holds before
the first cycle, which is what the FMU reports until the first step.

Types: BOOL is Boolean; REAL and LREAL are Real (FMI 3.0: Float64); SINT, INT and DINT
are Integer (FMI 3.0: Int32); UDINT is Integer in FMI 2.0, whose integers are 32-bit
signed, so a value of 2^31 or more reads as its two's complement (value - 2^32) and a
negative value written is taken as value + 2^32; in FMI 3.0 a UDINT is an Int64.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from ..instructions.schema import TagType
from ..tagmap import Folder, TagMap
from ..tagmap.axis_config import CONFIG_FIELDS
from ..tagmap.fields import clock_fields
from ..tagmap.model import Tag

#: fields of axes and groups that the site map fixes (beside the axis configuration block)
_FIXED_FIELDS = frozenset(
    {f.name for f in CONFIG_FIELDS} | {"Number", "Type", "AxisCount", "CoarseUpdatePeriod"}
)
_FIXED_TAGS = frozenset(
    {
        "Clock.Period",
        "Diagnostics.VersionMajor",
        "Diagnostics.VersionMinor",
        "Diagnostics.VersionPatch",
        "Diagnostics.AxisCount",
        "Diagnostics.GroupCount",
        "Diagnostics.InstanceCount",
    }
)


#: the Clock's command fields (writable with ``remote_clock``): never FMU variables
CLOCK_COMMANDS = frozenset(f.name for f in clock_fields(remote_clock=True) if f.writable)


class Kind(IntEnum):
    """The FMI base type of a variable."""

    BOOLEAN = 0
    INTEGER = 1
    REAL = 2


class Causality(IntEnum):
    """What the master does with a variable (FMI's causality)."""

    INPUT = 0
    OUTPUT = 1
    PARAMETER = 2


@dataclass(frozen=True)
class Variable:
    """One FMU variable: the tag it shows, its slot in the image, its FMI type and role."""

    name: str
    kind: Kind
    causality: Causality
    slot: int
    tag: Tag

    @property
    def unsigned32(self) -> bool:
        """A UDINT: 32-bit unsigned (see the module docstring for FMI 2.0)."""
        return self.tag.type == TagType.UDINT

    @property
    def description(self) -> str:
        unit = f" [{self.tag.units}]" if self.tag.units else ""
        return (self.tag.description or self.tag.name) + unit


def kind_of(tag: Tag) -> Kind:
    if tag.type == TagType.BOOL:
        return Kind.BOOLEAN
    if tag.type.is_float:
        return Kind.REAL
    return Kind.INTEGER


def causality_of(tag: Tag) -> Causality | None:
    """The tag's role in the FMU, or None for a tag the FMU does not show."""
    if tag.folder == Folder.CLOCK and tag.field in CLOCK_COMMANDS:
        return None
    if tag.writable:
        return Causality.INPUT
    fixed_owner = tag.folder in (Folder.AXES, Folder.GROUPS) and (
        tag.field in _FIXED_FIELDS or tag.field.startswith("Member")
    )
    if fixed_owner or tag.name in _FIXED_TAGS:
        return Causality.PARAMETER
    return Causality.OUTPUT


def fmu_variables(tagmap: TagMap, slots: dict[str, int]) -> list[Variable]:
    """The variables in tag-map order (that order gives the value references)."""
    out: list[Variable] = []
    for tag in tagmap.tags:
        causality = causality_of(tag)
        if causality is None:
            continue
        out.append(Variable(tag.name, kind_of(tag), causality, slots[tag.name], tag))
    return out
