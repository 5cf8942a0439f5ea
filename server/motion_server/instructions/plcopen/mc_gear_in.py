"""MC_GearIn: gear the slave to the master at RatioNumerator / RatioDenominator.

Slave displacement = master displacement x RatioNumerator / RatioDenominator, from the
master's set value (command, MasterValueSource 0) or actual position (1). When the gear
engages while the master moves, the slave catches up with Acceleration / Deceleration
(and Jerk, 0: trapezoidal) from the velocity it had; InGear when it has reached the geared
velocity. A new rising edge changes the ratio (the slave catches up again, InGear falls
until then). The block stays Busy until another command takes the slave over
(CommandAborted: MC_GearOut, MC_Stop, an aborting move ...); it has no Done.

Errors: RatioDenominator must be > 0 and RatioNumerator non-zero (ErrorID 13); a set-value
reference to a feedback-only master 8; a master/slave loop 10; the slave must be in
Servo Control (5, 7, 20) and not stopping (78).
"""

from __future__ import annotations

from typing import Any

from ...kernel import Axis, AxisType
from ...kernel.gearing import (
    CatchUp,
    GearProcess,
    GearTerm,
    MasterSource,
    RateRamp,
    catch_up,
    check_master,
)
from ...kernel.processes import Process
from ..operands import plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MCSource, MotionBlock, follows_as
from ..registry import register
from ..scan_pass import Batch, BatchKind, takes_motion
from ..schema import Kind, Operand, Quantity, StatusField, TagType

#: the operands the gear's ratio and catch-up read (not its axes)
_GEAR = ("RatioNumerator", "RatioDenominator", "Acceleration", "Deceleration", "Jerk")
_FEEDBACK_ONLY = AxisType.FEEDBACK_ONLY

MASTER = Operand("Master", TagType.DINT, 1, kind=Kind.AXIS, description="master axis number")
SLAVE = Operand("Slave", TagType.DINT, 2, kind=Kind.AXIS, description="slave axis number")
CONTINUOUS_UPDATE = Operand(
    "ContinuousUpdate", TagType.BOOL, False, description="reserved (no effect)"
)


def master_source(value: int) -> MasterSource:
    """PLCopen MC_Source (0 set value, 1 actual) as the kernel's master reference."""
    return MasterSource.ACTUAL if value == MCSource.ACTUAL_VALUE else MasterSource.COMMAND


@register
class MC_GearIn(MotionBlock):
    TYPE = "MC_GearIn"
    DESCRIPTION = "Gear the slave to a master at a ratio (catch-up with Acceleration)"
    DONE_ON_FINISH = False
    OPERANDS = (
        MASTER,
        SLAVE,
        CONTINUOUS_UPDATE,
        Operand(
            "RatioNumerator",
            TagType.LREAL,
            1.0,
            quantity=Quantity.RATIO,
            description="gear ratio numerator (signed, non-zero)",
        ),
        Operand(
            "RatioDenominator",
            TagType.LREAL,
            1.0,
            minimum=0.0,
            exclusive_min=True,
            quantity=Quantity.RATIO,
            description="gear ratio denominator (> 0)",
        ),
        Operand(
            "MasterValueSource",
            TagType.DINT,
            MCSource.SET_VALUE,
            enum=MCSource,
            description="0 set value (command), 1 actual",
        ),
        *plcopen_dynamics(with_velocity=False),
        BUFFER_MODE,
    )
    OUTPUTS = (StatusField("InGear", TagType.BOOL, "the slave runs at the geared velocity"),)

    #: rising edges in one scan start their gears with one ``Controller.start_gears``
    BATCH = BatchKind.GEAR_IN

    def batch_job(self, batch: Batch, key: Any) -> tuple[tuple[Any, ...], tuple[int, ...]] | None:
        """``execute`` up to the kernel command, the gear returned as (slave, term,
        (acceleration, deceleration), direction) for ``Controller.start_gears``; None
        for a buffered block or a jerk-limited catch-up (it executes alone). A gear
        whose slave is an axis of the queue, or whose master is a queued slave or
        follows one, hands the queue over first, so that its checks (a loop of masters
        among them) see the gears queued before it. Raises what ``execute`` raises
        before its command."""
        op = self.op
        s, m = int(op["Slave"]), int(op["Master"])
        loops, reaches = batch.reaching(m, s)
        if reaches or s in batch.axes:
            batch.flush()  # its checks see the gears queued before it (in full)
            slave, term, direction, ramp = self._judged()
            if type(ramp) is not RateRamp or self.buffered():
                return None
            return (slave, term, (ramp.accel, ramp.decel), direction), (s, m)
        # _judged's checks in its order, in full only where they refuse (the kernel's
        # errors); the ratio and the catch-up depend on their operands and the slave's
        # maxima only: worked out once per set of them in a scan pass
        slave = self.axis("Slave")
        master = self.axis("Master")
        if not takes_motion(slave) or slave.stopping:
            self.check_axis(slave)
        source = master_source(int(op["MasterValueSource"]))
        if loops or (source == MasterSource.COMMAND and master.type is _FEEDBACK_ONLY):
            check_master(self.ctl, slave, master, source)
        cfg = slave.config
        dt = self.ctl.dt(slave)
        memo = (MC_GearIn, *map(op.__getitem__, _GEAR), cfg.max_acceleration,
                cfg.max_deceleration, cfg.max_jerk, dt)  # fmt: skip
        planned = batch.plans.get(memo)
        if planned is None:
            num = float(op["RatioNumerator"])
            if num == 0.0:
                raise self.out_of_range("RatioNumerator", "RatioNumerator must be non-zero")
            den = float(op["RatioDenominator"])
            GearTerm(m, source, num, den).validated()
            self.check_gear_dynamics(slave)
            ramp = catch_up(dt, *self._catch_up())
            pair = (ramp.accel, ramp.decel) if type(ramp) is RateRamp else None
            planned = batch.plans[memo] = (num, den, 1 if num > 0 else -1, pair)
        num, den, direction, pair = planned
        if pair is None or self.buffered():
            return None
        return (slave, GearTerm(m, source, num, den), pair, direction), (s, m)

    def _catch_up(self) -> tuple[float, float, float]:
        """Acceleration, Deceleration and Jerk of the catch-up."""
        op = self.op
        return float(op["Acceleration"]), float(op["Deceleration"]), float(op["Jerk"])

    def _judged(self) -> tuple[Axis, GearTerm, int, CatchUp]:
        """The checks of ``execute`` before its command: the slave, the gear's term, its
        direction and the catch-up its dynamics make (built to judge them)."""
        slave = self.axis("Slave")
        master = self.axis("Master")
        self.check_axis(slave)
        source = master_source(int(self.op["MasterValueSource"]))
        check_master(self.ctl, slave, master, source)
        num = float(self.op["RatioNumerator"])
        if num == 0.0:
            raise self.out_of_range("RatioNumerator", "RatioNumerator must be non-zero")
        term = GearTerm(master.number, source, num, float(self.op["RatioDenominator"]))
        term.validated()
        self.check_gear_dynamics(slave)
        ramp = catch_up(self.ctl.dt(slave), *self._catch_up())  # a bad value moves nothing
        return slave, term, 1 if num > 0 else -1, ramp

    def execute(self) -> None:
        slave, term, direction, _ = self._judged()
        dt = self.ctl.dt(slave)
        acc, dec, jerk = self._catch_up()
        ctl = self.ctl

        def make(v: float, a: float) -> Process:
            ramp = catch_up(dt, acc, dec, jerk)
            return GearProcess(ctl, slave, (term,), ramp, v, a, owner=self, direction=direction)

        self.begin(slave, make)

    def publish_extra(self) -> None:
        p = self.process
        self.outputs["InGear"] = bool(
            self.outputs["Busy"] and isinstance(p, GearProcess) and p.active and p.locked
        )

    def parked_on(self) -> Process | None:
        """The gear, once locked with InGear shown: a gear stays locked until it ends,
        so until then, or an operand is written, nothing changes."""
        p = self.running()
        if (
            not isinstance(p, GearProcess)
            or not p.locked
            or not self.outputs["InGear"]
            or not follows_as(type(self), MC_GearIn)
        ):
            return None
        return p
