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

from ...kernel.gearing import GearProcess, GearTerm, MasterSource, catch_up, check_master
from ...kernel.processes import Process
from ..operands import plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MCSource, MotionBlock, follows_as
from ..registry import register
from ..schema import Kind, Operand, Quantity, StatusField, TagType

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

    def execute(self) -> None:
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
        dt = self.ctl.dt(slave)
        acc, dec, jerk = (float(self.op[k]) for k in ("Acceleration", "Deceleration", "Jerk"))
        self.check_gear_dynamics(slave)
        catch_up(dt, acc, dec, jerk)  # judge the dynamics now: a bad value moves nothing
        ctl = self.ctl
        direction = 1 if num > 0 else -1

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
