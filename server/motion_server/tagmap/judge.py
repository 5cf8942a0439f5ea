"""What a client may write: every value is judged before it reaches the write queue.

The checks are those a tag has always had (its type's range: a SINT beyond -128..127,
an unknown ``Clock.Mode``), plus the numeric boundary of the kernel: a floating-point
value must be finite, and its magnitude in the kernel's own units must stay within
:data:`MAX_COUNTS` (2^53, where float64 still counts every encoder count exactly). For a
position, velocity, acceleration or jerk that unit is the encoder count: the value times
the conversion constant of the tag's axis, or for an instruction operand (whose axis is
another operand, free to change) the largest conversion constant of the site. Other
analog values (ratios, percentages, times) are judged as they are. So no client value can
make the kernel compute an infinite or NaN number; what is finite but outside an
operand's own range is judged by the instruction at execution (ER/Error 13).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..instructions.schema import Quantity, TagType
from .errors import BadValueError
from .fields import ClockMode, CommFault
from .model import Folder, Tag, TagMap

#: the largest magnitude, in encoder counts (or plain units), a client may write
MAX_COUNTS = float(2**53)
_PHYSICAL = frozenset({Quantity.POSITION, Quantity.VELOCITY, Quantity.ACCELERATION, Quantity.JERK})


def checked(tag_type: TagType, value: Any) -> bool | int | float:
    """``value`` as the Python value a tag of ``tag_type`` holds, or :class:`BadValueError`."""
    if tag_type == TagType.BOOL:
        if value in (0, 1):  # True/False, 0/1, 0.0/1.0
            return bool(value)
        raise BadValueError(f"{value!r} is not a BOOL (0 or 1)")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise BadValueError(f"{value!r} is not a number")
    if tag_type.is_float:
        return float(value)
    if isinstance(value, float) and not value.is_integer():
        raise BadValueError(f"{value!r} is not an integer ({tag_type.value})")
    lo, hi = tag_type.bounds
    if not lo <= value <= hi:
        raise BadValueError(f"{value} is outside the {tag_type.value} range {lo:.0f}..{hi:.0f}")
    return int(value)


class Judge:
    """Judges values for the tags of one map. ``counts_per_unit``: axis name ->
    conversion constant (counts per position unit)."""

    def __init__(self, tagmap: TagMap, counts_per_unit: Mapping[str, float]) -> None:
        largest = max(counts_per_unit.values(), default=1.0)
        self._scale: dict[str, float] = {}
        for tag in tagmap:
            if not tag.type.is_float:
                continue
            scale = 1.0
            if tag.quantity in _PHYSICAL:
                if tag.folder == Folder.AXES:
                    scale = counts_per_unit.get(tag.owner, largest)
                elif tag.folder == Folder.INSTRUCTIONS:
                    scale = largest
            self._scale[tag.name] = max(scale, 1.0)

    @classmethod
    def for_system(cls, tagmap: TagMap, system: Any) -> Judge:
        """The judge of ``tagmap`` on a built system (its axes' conversion constants)."""
        return cls(tagmap, {ax.name: ax.config.counts_per_unit for ax in system.ctl.axes})

    def __call__(self, tag: Tag, value: Any) -> bool | int | float:
        v = checked(tag.type, value)
        if tag.type.is_float:
            f = float(v)
            if not math.isfinite(f):
                raise BadValueError(f"{tag.name} must be finite, got {f}")
            scale = self._scale.get(tag.name, 1.0)
            if abs(f) * scale > MAX_COUNTS:
                unit = "counts" if scale > 1.0 else "units"
                raise BadValueError(
                    f"{tag.name}: {f:g} is beyond the kernel's range "
                    f"(|value| x {scale:g} must not exceed 2^53 {unit})"
                )
            return f
        if tag.owner == "Clock" and tag.field == "Mode":
            try:
                return ClockMode(int(v))
            except ValueError:
                modes = ", ".join(f"{int(m)} {m.name.lower()}" for m in ClockMode)
                raise BadValueError(f"Clock.Mode {v}: expected {modes}") from None
        if tag.owner == "Clock" and tag.field == "CommFault":
            try:
                return CommFault(int(v))
            except ValueError:
                kinds = ", ".join(f"{int(m)} {m.name.lower()}" for m in CommFault)
                raise BadValueError(f"Clock.CommFault {v}: expected {kinds}") from None
        return v
