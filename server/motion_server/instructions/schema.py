"""Operand and status-field schemas: the one description of every instruction's tags.

The tag map, both front-ends and every export are generated from these.
"""

from __future__ import annotations

import builtins
import math
from dataclasses import dataclass
from enum import IntEnum, StrEnum
from typing import Any


class TagType(StrEnum):
    BOOL = "BOOL"
    SINT = "SINT"
    INT = "INT"
    DINT = "DINT"
    UDINT = "UDINT"
    REAL = "REAL"
    LREAL = "LREAL"

    @property
    def is_float(self) -> bool:
        return self in (TagType.REAL, TagType.LREAL)

    @property
    def words(self) -> int:
        """Number of 16-bit registers (a BOOL is one bit of a register)."""
        return {"BOOL": 1, "SINT": 1, "INT": 1, "DINT": 2, "UDINT": 2, "REAL": 2, "LREAL": 4}[
            self.value
        ]

    @property
    def bounds(self) -> tuple[float, float]:
        return {
            "BOOL": (0, 1),
            "SINT": (-128, 127),
            "INT": (-32768, 32767),
            "DINT": (-(2**31), 2**31 - 1),
            "UDINT": (0, 2**32 - 1),
            "REAL": (-3.4028234663852886e38, 3.4028234663852886e38),
            "LREAL": (-math.inf, math.inf),
        }[self.value]


class Kind(StrEnum):
    """What an operand refers to; axis and group operands hold 1-based numbers."""

    VALUE = "value"
    AXIS = "axis"
    GROUP = "group"


class Quantity(StrEnum):
    """Engineering quantity of an analog value (the tag map turns it into units)."""

    NONE = ""
    POSITION = "position"
    VELOCITY = "velocity"
    ACCELERATION = "acceleration"
    JERK = "jerk"
    PERCENT = "percent"
    RATIO = "ratio"


@dataclass(frozen=True)
class Operand:
    """An input of an instruction. A tag accepts any value of its type; :meth:`check`
    judges it at execution (ER/Error with code 13 when out of range)."""

    name: str
    type: TagType
    default: Any = 0
    minimum: float | None = None
    maximum: float | None = None
    enum: builtins.type[IntEnum] | None = None
    kind: Kind = Kind.VALUE
    quantity: Quantity = Quantity.NONE
    description: str = ""
    #: strict bounds: the value must be > minimum / < maximum
    exclusive_min: bool = False

    def check(self, value: Any) -> bool:
        try:
            v = float(value)
            if not math.isfinite(v):
                return False
            if self.enum is not None:
                n = int(value)
                # a member's value passes without the enum's constructor (slow); any other
                # is judged by the constructor, which raises ValueError
                if n not in self.enum._value2member_map_:
                    self.enum(n)
        except (TypeError, ValueError, OverflowError):
            return False
        if self.minimum is not None and (
            v <= self.minimum if self.exclusive_min else v < self.minimum
        ):
            return False
        return not (self.maximum is not None and v > self.maximum)


@dataclass(frozen=True)
class StatusField:
    """An output of an instruction (read-only for clients)."""

    name: str
    type: TagType
    description: str = ""
    enum: builtins.type[IntEnum] | None = None
    quantity: Quantity = Quantity.NONE
    default: Any = 0


def coerce(tag_type: TagType, value: Any) -> Any:
    """Convert a value to the Python value a tag of ``tag_type`` holds."""
    if tag_type == TagType.BOOL:
        return bool(value)
    if tag_type.is_float:
        return float(value)
    return int(value)
