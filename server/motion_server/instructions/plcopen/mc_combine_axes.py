"""MC_CombineAxes: the slave follows the sum or difference of two geared masters.

Slave displacement = Master1 displacement x NumeratorM1 / DenominatorM1 +/- Master2
displacement x NumeratorM2 / DenominatorM2 (CombineMode add 0, subtract 1), each master
from its own MasterValueSource. Like MC_GearIn the slave catches up with Acceleration /
Deceleration / Jerk when the masters already move; InSync once it runs at the combined
velocity. Stopped by MC_Stop; MC_GearOut on the slave is refused (ErrorID 1002).

Errors: a zero numerator or denominator 13 (the seed allows either sign); a set-value
reference to a feedback-only master 8; a master/slave loop 10; the slave must be in Servo
Control (5, 7, 20) and not stopping (78).
"""

from __future__ import annotations

from enum import IntEnum

from ...kernel.gearing import GearProcess, GearTerm, catch_up, check_master
from ...kernel.processes import Process
from ..operands import plcopen_dynamics
from ..plcopen_common import BUFFER_MODE, MCSource, MotionBlock
from ..registry import register
from ..schema import Kind, Operand, Quantity, StatusField, TagType
from .mc_gear_in import CONTINUOUS_UPDATE, SLAVE, master_source


class CombineMode(IntEnum):
    ADD = 0
    SUBTRACT = 1


def _ratio(name: str) -> Operand:
    return Operand(
        name,
        TagType.LREAL,
        1.0,
        quantity=Quantity.RATIO,
        description="signed, non-zero",
    )


@register
class MC_CombineAxes(MotionBlock):
    TYPE = "MC_CombineAxes"
    DESCRIPTION = "Gear the slave to the sum or difference of two masters"
    DONE_ON_FINISH = False
    OPERANDS = (
        Operand("Master1", TagType.DINT, 1, kind=Kind.AXIS, description="master 1 axis number"),
        Operand("Master2", TagType.DINT, 3, kind=Kind.AXIS, description="master 2 axis number"),
        SLAVE,
        CONTINUOUS_UPDATE,
        Operand(
            "CombineMode",
            TagType.DINT,
            CombineMode.ADD,
            enum=CombineMode,
            description="0 add, 1 subtract",
        ),
        _ratio("GearRatioNumeratorM1"),
        _ratio("GearRatioDenominatorM1"),
        _ratio("GearRatioNumeratorM2"),
        _ratio("GearRatioDenominatorM2"),
        Operand("MasterValueSourceM1", TagType.DINT, MCSource.SET_VALUE, enum=MCSource),
        Operand("MasterValueSourceM2", TagType.DINT, MCSource.SET_VALUE, enum=MCSource),
        *plcopen_dynamics(with_velocity=False),
        BUFFER_MODE,
    )
    OUTPUTS = (StatusField("InSync", TagType.BOOL, "the slave runs at the combined velocity"),)

    def execute(self) -> None:
        slave = self.axis("Slave")
        self.check_axis(slave)
        sign = -1.0 if int(self.op["CombineMode"]) == CombineMode.SUBTRACT else 1.0
        terms = []
        for k, s in (("1", 1.0), ("2", sign)):
            master = self.axis(f"Master{k}")
            source = master_source(int(self.op[f"MasterValueSourceM{k}"]))
            check_master(self.ctl, slave, master, source)
            for part in ("Numerator", "Denominator"):
                name = f"GearRatio{part}M{k}"
                if float(self.op[name]) == 0.0:
                    raise self.out_of_range(name, f"{name} must be non-zero")
            num = s * float(self.op[f"GearRatioNumeratorM{k}"])
            terms.append(
                GearTerm(master.number, source, num, float(self.op[f"GearRatioDenominatorM{k}"]))
            )
        dt = self.ctl.dt(slave)
        acc, dec, jerk = (float(self.op[k]) for k in ("Acceleration", "Deceleration", "Jerk"))
        self.check_gear_dynamics(slave)
        catch_up(dt, acc, dec, jerk)  # judge the dynamics now: a bad value moves nothing
        ctl = self.ctl

        def make(v: float, a: float) -> Process:
            ramp = catch_up(dt, acc, dec, jerk)
            return GearProcess(ctl, slave, terms, ramp, v, a, owner=self)

        self.begin(slave, make)

    def publish_extra(self) -> None:
        p = self.process
        self.outputs["InSync"] = bool(
            self.outputs["Busy"] and isinstance(p, GearProcess) and p.active and p.locked
        )
