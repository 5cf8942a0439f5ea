"""MAG, Motion Axis Gear: gear a slave axis to a master at a real or fraction ratio.

DN and IP are set in the same scan; IP stays until the gear process is superseded (a new
MAG on the slave), stopped (MAS All/Gear, MGS), merged (MAJ/MAM with Merge), shut down or
faulted. Jog and move processes on the slave superimpose on the gearing.

Decisions the seed leaves open (DESIGN.md):

- **Ratio sign**: the slave moves by Direction sign x Ratio x master displacement, so a
  negative Ratio inverts whatever Direction selects. Reverse and Unchanged act on the
  Direction part only: the direction kept per slave axis is the last resolved Direction
  (same or opposite), never the Ratio's sign. A slave never geared counts as Same.
- **Real ratio resolution**: five decimals, as the seed's range says (0.00001 to 9.99999
  by magnitude): the REAL is rounded to a whole number of 1e-5 and used as that exact
  decimal, so a REAL tag's float32 error does not accumulate into slave position.
- **Fraction**: SlaveCounts and MasterCounts must be >= 1 (the Direction gives the sign);
  counts are each axis's conversion constant per unit; the master's position is taken as
  the nearest whole count.
- **Clutch** enabled: the slave's gear velocity ramps at AccelRate (units/s^2 or % of the
  slave's maximum acceleration) to ratio x master velocity, trapezoidal, then locks; a new
  MAG with clutch starts from the velocity of the gearing it supersedes (merge on the
  fly). Clutch disabled: locks at once.
- **Errors**: slave feedback-only ERR 8, not in Servo Control ERR 5 (shut down 7, faulted
  20); Command reference to a feedback-only master ERR 8; a master/slave loop (including
  the slave as its own master) ERR 10; operands out of range ERR 13 with EXERR.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Any, ClassVar, TypeVar

from ...kernel import Axis, AxisType, ProcessKind
from ...kernel.gearing import (
    GearProcess,
    GearTerm,
    MasterSource,
    RateRamp,
    check_master,
    gearing_direction,
)
from ...kernel.processes import Process
from .. import dynamics
from ..base import Gate, gate
from ..dynamics import AccelUnits
from ..logix_common import STARTED_ACTIVE, ProcessInstruction
from ..operands import MASTER_AXIS, SLAVE_AXIS
from ..registry import register
from ..scan_pass import Batch, BatchKind, takes_motion
from ..schema import Operand, Quantity, TagType


class GearDirection(IntEnum):
    SAME = 0
    OPPOSITE = 1
    REVERSE = 2
    UNCHANGED = 3


class RatioFormat(IntEnum):
    REAL = 0
    FRACTION = 1


class Clutch(IntEnum):
    ENABLED = 0
    DISABLED = 1


#: real ratios are whole numbers of this resolution (five decimals)
RATIO_SCALE = 100_000
RATIO_STEPS = (1, 999_999)


#: MAG's Direction, which MAPC and MATC share (RM002: the same four values)
DIRECTION = Operand(
    "Direction",
    TagType.DINT,
    GearDirection.SAME,
    enum=GearDirection,
    description="0 same, 1 opposite, 2 reverse current, 3 unchanged",
)


def resolve_direction(selection: GearDirection, current: int) -> int:
    """+1 (same) or -1 (opposite) from the Direction operand and the current direction."""
    if selection == GearDirection.SAME:
        return 1
    if selection == GearDirection.OPPOSITE:
        return -1
    if selection == GearDirection.REVERSE:
        return -current
    return current


E = TypeVar("E", bound=IntEnum)

#: the members of the enumerations MAG reads at execution, by value (a judged operand
#: holds one of them: no enum constructor call per execution)
_SOURCES: dict[int, IntEnum] = {int(m): m for m in MasterSource}
_DIRECTIONS: dict[int, IntEnum] = {int(m): m for m in GearDirection}
_FRACTION = int(RatioFormat.FRACTION)
_CLUTCH_ENABLED = int(Clutch.ENABLED)
#: the processes a new gear supersedes
_REPLACE = (ProcessKind.GEAR,)


def _member(enum: type[E], members: dict[int, IntEnum], value: object) -> E:
    """``enum(int(value))``, looked up."""
    n = int(value)  # type: ignore[call-overload]
    member = members.get(n)
    return enum(n) if member is None else member  # type: ignore[return-value]


@register
class MAG(ProcessInstruction):
    TYPE = "MAG"
    DESCRIPTION = "Motion Axis Gear: electronic gearing of a slave to a master"
    SETS_PC = False
    #: MAG(SlaveAxis, MasterAxis, MotionControl, Direction, ...): EXERR counts it
    MOTION_CONTROL_INDEX = 2
    #: the ratio operands of the other format and the clutch rate without the clutch
    #: are not used, so not judged
    GATES: ClassVar[dict[str, tuple[Gate, ...]]] = {
        "Ratio": (gate("RatioFormat", RatioFormat.REAL),),
        "SlaveCounts": (gate("RatioFormat", RatioFormat.FRACTION),),
        "MasterCounts": (gate("RatioFormat", RatioFormat.FRACTION),),
        "AccelRate": (gate("Clutch", Clutch.ENABLED),),
        "AccelUnits": (gate("Clutch", Clutch.ENABLED),),
    }
    OPERANDS = (
        SLAVE_AXIS,
        MASTER_AXIS,
        DIRECTION,
        Operand(
            "Ratio",
            TagType.REAL,
            1.0,
            quantity=Quantity.RATIO,
            description="slave units per master unit, sign-sensitive, |Ratio| 0.00001..9.99999",
        ),
        Operand(
            "SlaveCounts",
            TagType.UDINT,
            1,
            description="fraction ratio: slave feedback counts (>= 1)",
        ),
        Operand(
            "MasterCounts",
            TagType.UDINT,
            1,
            description="fraction ratio: master feedback counts (>= 1)",
        ),
        Operand(
            "MasterReference",
            TagType.DINT,
            MasterSource.COMMAND,
            enum=MasterSource,
            description="0 actual, 1 command",
        ),
        Operand(
            "RatioFormat", TagType.DINT, RatioFormat.REAL, enum=RatioFormat, description="0 real"
        ),
        Operand(
            "Clutch", TagType.DINT, Clutch.ENABLED, enum=Clutch, description="0 enabled, 1 disabled"
        ),
        Operand(
            "AccelRate",
            TagType.REAL,
            100.0,
            quantity=Quantity.ACCELERATION,
            description="clutch acceleration (units/s^2 or % of maximum)",
        ),
        Operand(
            "AccelUnits",
            TagType.DINT,
            AccelUnits.PERCENT_OF_MAXIMUM,
            enum=AccelUnits,
            description="0 units/s^2, 1 % of maximum",
        ),
    )

    #: rising edges in one scan start their gears with one ``Controller.start_gears``
    BATCH = BatchKind.GEAR

    def _gear(self) -> tuple[Axis, GearTerm, float | None, int]:
        """The checks and the plan: slave, gear term, clutch rate (None: no clutch) and
        the resolved direction."""
        op = self.op
        ctl = self.ctl
        slave = ctl.axis(int(op["SlaveAxis"]))
        master = ctl.axis(int(op["MasterAxis"]))
        ctl.require_motion(slave)
        source = _member(MasterSource, _SOURCES, op["MasterReference"])
        check_master(ctl, slave, master, source)
        direction = resolve_direction(
            _member(GearDirection, _DIRECTIONS, op["Direction"]), gearing_direction(slave)
        )
        numerator, denominator, counts, rate = self._coupling(slave, direction)
        term = GearTerm(master.number, source, numerator, denominator, counts=counts)
        return slave, term, rate, direction

    def _coupling(self, slave: Axis, direction: int) -> tuple[int, int, bool, float | None]:
        """The ratio (signed numerator, denominator, in feedback counts or not) and the
        clutch rate (None: no clutch), from the values and the slave's limits: the ratio
        and rate operands judged, in this order."""
        op = self.op
        if int(op["RatioFormat"]) == _FRACTION:
            counts = {}
            for name in ("SlaveCounts", "MasterCounts"):
                counts[name] = int(self.op[name])
                if counts[name] < 1:
                    raise self.out_of_range(name, f"{name} must be >= 1")
            ratio = (direction * counts["SlaveCounts"], counts["MasterCounts"], True)
        else:
            real = float(self.op["Ratio"])
            steps = round(abs(real) * RATIO_SCALE)
            if not RATIO_STEPS[0] <= steps <= RATIO_STEPS[1]:
                raise self.out_of_range("Ratio", f"|Ratio| must be 0.00001..9.99999, got {real}")
            sign = -direction if real < 0 else direction
            ratio = (sign * steps, RATIO_SCALE, False)
        rate = None
        if int(op["Clutch"]) == _CLUTCH_ENABLED:
            rate = dynamics.rate(
                self, slave, "AccelRate", "AccelUnits", slave.config.max_acceleration
            )
        return (*ratio, rate)

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the gear returned as (slave, term,
        clutch rate, direction) for ``Controller.start_gears``. The checks run in
        ``_gear``'s order but in full only where they refuse (the kernel's errors): one
        walk over the master/slave links tells whether the gear closes a loop and
        whether it reaches a queued slave (then the queue is handed over first, and the
        gear planned as ``execute`` plans it); the ratio and clutch rate depend on the
        values, the direction and the slave's limits only, and are worked out once per
        set of them in a scan pass."""
        op = self.op
        ctl = self.ctl
        s = int(op["SlaveAxis"])
        m = int(op["MasterAxis"])
        loops, reaches = batch.reaching(m, s)
        if reaches or s in batch.axes:
            batch.flush()  # its checks see the gears queued before it
            slave, term, rate, direction = self._gear()
        else:
            slave = ctl.axis(s)
            master = ctl.axis(m)
            if not takes_motion(slave):
                ctl.require_motion(slave)  # the kernel's refusal, with its error
            source = _member(MasterSource, _SOURCES, op["MasterReference"])
            if loops or (source == _COMMAND and master.type is _FEEDBACK_ONLY):
                check_master(ctl, slave, master, source)
            direction = resolve_direction(
                _member(GearDirection, _DIRECTIONS, op["Direction"]), gearing_direction(slave)
            )
            memo = None
            coupling = None
            if key is not None:
                memo = (MAG, key, direction, slave.config.max_acceleration)
                coupling = batch.plans.get(memo)
            if coupling is None:
                coupling = self._coupling(slave, direction)
                if memo is not None:
                    batch.plans[memo] = coupling
            numerator, denominator, counts, rate = coupling
            term = GearTerm(m, source, numerator, denominator, counts=counts)
        if rate is not None and not (0.0 < rate < math.inf):
            RateRamp(rate)  # refused now (with its error), as execute builds it at once
        return (slave, term, rate, direction), (s, m)

    def batch_started(self, process: Process) -> None:
        self.started_active(process, STARTED_ACTIVE)

    def batch_refused(self) -> None:
        """Nothing to undo: a refused gear changes no output of its own."""

    def execute(self) -> None:
        ctl = self.ctl
        slave, term, rate, direction = self._gear()
        ramp = None if rate is None else RateRamp(rate)

        def make(v: float, a: float) -> Process:
            return GearProcess(ctl, slave, (term,), ramp, v, a, owner=self, direction=direction)

        self.started(ctl.start(slave, make, replace=_REPLACE))


_COMMAND = MasterSource.COMMAND
_FEEDBACK_ONLY = AxisType.FEEDBACK_ONLY
