"""Engineering units and ranges of analog values (OPC UA ``EUInformation``, ``EURange``).

Units: an axis measures positions in its site-map ``units``; velocities, accelerations
and jerks are those per second, per second squared and per second cubed. Each known unit
maps to its UNECE Recommendation 20 common code as the OPC Foundation publishes it for OPC
UA (``UNECE_to_OPCUA.csv``): the OPC UA ``UnitId`` packs the code's characters into an
integer (OPC 10000-8, 5.6.3: MMT -> 5066068). Jerk units (mm/s³, °/s³) have no common
code; like any unit outside the table they get ``UnitId`` -1, the value OPC 10000-8 gives
a unit without a code, and their symbol as ``DisplayName``. Gear ratios are dimensionless:
UNECE C62 ("one").

Ranges (``EURange``, the span a value takes in normal operation, from the axis limits):

- velocity: ± max_velocity;
- acceleration and deceleration: ± the larger of max_acceleration and max_deceleration
  (a stop decelerates at max_deceleration, a jog accelerates at max_acceleration);
- jerk: ± max_jerk, or with unlimited jerk (0) ± that acceleration per coarse update
  period (a trapezoidal profile changes its acceleration within one period);
- position on a rotary axis, as the server reports it: [0, rollover]; a position or
  distance operand of a rotary axis, and any position on a linear axis: ± 2³¹ counts /
  counts per unit (the travel of a signed 32-bit position counter); the position error:
  ± following_error_limit when one is set, else ± rollover on a rotary axis and the
  counter's travel on a linear one;
- an operand's own limits narrow the range (``MAJ.Speed >= 0``: [0, max_velocity]);
- an operand no axis limit bounds has the range its document gives
  (:func:`operand_range`: MAG's real ``Ratio``, |Ratio| 0.00001..9.99999, so
  [-9.99999, 9.99999]: the sign selects the direction);
- the axis configuration tags (limits themselves): [0, value];
- times: ``CoarseUpdatePeriod`` and ``Clock.Period`` [1, 32] ms (the allowed periods),
  ``CycleTime``/``MaxCycleTime`` [0, period] µs (a longer cycle is an overrun),
  ``Clock.SimTime`` [0, 2³² periods] s (the time ``Clock.Cycle`` counts before it wraps).

Which axis: an axis tag's own axis; an instruction's, the axis its site-map entry names
(``Axis``, else ``SlaveAxis``, else its first axis operand; ``Master...`` operands the
``MasterAxis``). An instruction that names no axis (the group instructions) has no axis
units: its analog operands carry no ``EngineeringUnits`` and the range of their type or
their own limits.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..instructions.schema import Quantity
from ..kernel.config import MAX_PERIOD, MIN_PERIOD, AxisConfig

#: NamespaceUri of UNECE units in EUInformation
UNECE_NAMESPACE = "http://www.opcfoundation.org/UA/units/un/cefact"


@dataclass(frozen=True)
class Unit:
    """A UNECE unit: common code, symbol (EUInformation DisplayName) and name
    (Description), as in the OPC Foundation's UNECE_to_OPCUA.csv."""

    code: str
    symbol: str
    name: str

    @property
    def unit_id(self) -> int:
        return unit_id_of(self.code)


#: our unit strings (site-map axis units and their derived units; fixed units of the
#: diagnostics) -> UNECE unit
UNITS: dict[str, Unit] = {
    "mm": Unit("MMT", "mm", "millimetre"),
    "cm": Unit("CMT", "cm", "centimetre"),
    "m": Unit("MTR", "m", "metre"),
    "um": Unit("4H", "µm", "micrometre (micron)"),
    "µm": Unit("4H", "µm", "micrometre (micron)"),
    "in": Unit("INH", "in", "inch"),
    "deg": Unit("DD", "°", "degree [unit of angle]"),
    "°": Unit("DD", "°", "degree [unit of angle]"),
    "rad": Unit("C81", "rad", "radian"),
    "rev": Unit("M44", "rev", "revolution"),
    "mm/s": Unit("C16", "mm/s", "millimetre per second"),
    "cm/s": Unit("2M", "cm/s", "centimetre per second"),
    "m/s": Unit("MTS", "m/s", "metre per second"),
    "in/s": Unit("IU", "in/s", "inch per second"),
    "deg/s": Unit("E96", "°/s", "degree per second"),
    "°/s": Unit("E96", "°/s", "degree per second"),
    "rad/s": Unit("2A", "rad/s", "radian per second"),
    "rev/s": Unit("RPS", "r/s", "revolutions per second"),
    "mm/s²": Unit("M41", "mm/s²", "millimetre per second squared"),
    "cm/s²": Unit("M39", "cm/s²", "centimetre per second squared"),
    "m/s²": Unit("MSK", "m/s²", "metre per second squared"),
    "in/s²": Unit("IV", "in/s²", "inch per second squared"),
    "deg/s²": Unit("M45", "°/s²", "degree [unit of angle] per second squared"),
    "°/s²": Unit("M45", "°/s²", "degree [unit of angle] per second squared"),
    "rad/s²": Unit("2B", "rad/s²", "radian per second squared"),
    "s": Unit("SEC", "s", "second [unit of time]"),
    "ms": Unit("C26", "ms", "millisecond"),
    "us": Unit("B98", "µs", "microsecond"),
    "µs": Unit("B98", "µs", "microsecond"),
    "1": Unit("C62", "1", "one"),
    # Diagnostics.ScanLoad; UNECE Recommendation 20 common code P1 (percent), the code
    # node-opcua's standard units give percent as well
    "%": Unit("P1", "%", "percent"),
}
#: the unit of dimensionless ratios
RATIO_UNIT = UNITS["1"]
#: the span of a signed 32-bit position counter, in counts
COUNTER_SPAN = float(2**31)


def unit_id_of(code: str) -> int:
    """The OPC UA UnitId of a UNECE common code (OPC 10000-8: the code's characters,
    most significant first, each in 8 bits)."""
    out = 0
    for ch in code:
        out = (out << 8) | ord(ch)
    return out


def unit_of(units: str) -> Unit | None:
    """The UNECE unit of one of our unit strings, None when it has no common code."""
    return UNITS.get(units)


def unit_id(units: str) -> int:
    """The UnitId of ``units``; -1 when it has no UNECE common code."""
    unit = UNITS.get(units)
    return unit.unit_id if unit is not None else -1


def axis_range(
    quantity: Quantity,
    cfg: AxisConfig,
    period: float,
    *,
    reported: bool,
    field: str = "",
) -> tuple[float, float] | None:
    """The EURange of a ``quantity`` on the axis ``cfg`` (period: its coarse update
    period in s). ``reported``: a value the server reports (an axis tag), not an
    operand a client writes. None for quantities without an axis range."""
    accel = max(cfg.max_acceleration, cfg.max_deceleration)
    if quantity == Quantity.VELOCITY:
        return -cfg.max_velocity, cfg.max_velocity
    if quantity == Quantity.ACCELERATION:
        return -accel, accel
    if quantity == Quantity.JERK:
        jerk = cfg.max_jerk if cfg.max_jerk > 0 else accel / period
        return -jerk, jerk
    if quantity != Quantity.POSITION:
        return None
    if field == "PositionError" and cfg.following_error_limit > 0:
        return -cfg.following_error_limit, cfg.following_error_limit
    if reported and cfg.rotary and field != "PositionError":
        return 0.0, cfg.rollover
    if reported and cfg.rotary:
        return -cfg.rollover, cfg.rollover
    travel = COUNTER_SPAN / cfg.counts_per_unit
    return -travel, travel


def operand_range(type_name: str, operand: str) -> tuple[float, float] | None:
    """The documented range of an analog operand that no axis limit bounds (None: the
    document gives none). MAG's real ``Ratio`` (Logix MAG: "0.00001 to 9.99999", five
    decimals; signed, the sign selecting the direction): the instruction's own bounds."""
    if (type_name, operand) == ("MAG", "Ratio"):
        from ..instructions.logix.mag import RATIO_SCALE, RATIO_STEPS

        largest = RATIO_STEPS[1] / RATIO_SCALE
        return -largest, largest
    return None


def narrowed(
    span: tuple[float, float], minimum: float | None, maximum: float | None
) -> tuple[float, float]:
    """``span`` within an operand's own limits (the limits alone when they do not meet)."""
    lo, hi = span
    if minimum is not None:
        lo = max(lo, minimum)
    if maximum is not None:
        hi = min(hi, maximum)
    if lo > hi:
        return (minimum if minimum is not None else span[0]), (
            maximum if maximum is not None else span[1]
        )
    return lo, hi


def fixed_range(owner: str, field: str, period: float) -> tuple[float, float] | None:
    """The EURange of the analog tags with fixed units (groups, diagnostics, clock)."""
    if field in ("CoarseUpdatePeriod", "Period"):
        return MIN_PERIOD * 1000.0, MAX_PERIOD * 1000.0
    if field in ("CycleTime", "MaxCycleTime"):
        return 0.0, period * 1e6
    if owner == "Clock" and field == "SimTime":
        return 0.0, float(2**32) * period
    return None
