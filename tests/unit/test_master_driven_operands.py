"""Master-driven MAJ/MAM operands judged before any profile is planned (ERR 13, EXERR
naming the operand), never an internal error (ERR 1005) from the planner.

The rig of test_mdac: masters A (1) and B (2) jogging, the slave (3) under an MDAC to
A; every axis has a maximum velocity of 1000 mm/s. First principles:

- an AccelRate of 1e-30 mm per master mm² needs 0.5 / 1e-30 = 5e29 mm of master travel
  to reach 0.5 mm per master mm: beyond the 1e9 a master-driven profile may take;
- a DecelRate of 1e-30 would take as long to stop the jog again;
- a move of 10 mm at 1e-30 mm per master mm needs 1e31 mm of master travel, and one of
  1e12 mm at 1.0 needs 1e12 (the distance is at fault there, not the speed);
- a Speed of 1.5 mm per master mm would drive the slave at 1500 mm/s with A at its
  1000 mm/s maximum, beyond the slave's 1000: refused; 1.0 reaches exactly 1000: allowed;
- an AccelRate of 1e-6 reaches 0.5 after 5e5 mm of master travel: long but plannable.
"""

from __future__ import annotations

import pytest

from motion_server.instructions import LogixInstruction, MotionSystem
from motion_server.kernel import ErrorCode, Limits, MotionError
from motion_server.kernel.master_driven import MasterProfile

from ..support import trigger
from .test_mdac import MASTER_UNITS, logix, md_dynamics, mdac, setup


def exerr(inst: LogixInstruction, operand: str) -> int:
    """EXERR of ``operand``: its 0-based place in the ST signature (Motion Control
    counted)."""
    return inst.operand_index(operand) + 1


def master_driven(
    type_name: str, speed: float, **extra: float
) -> tuple[MotionSystem, LogixInstruction]:
    """A master-driven MAJ or MAM (10 mm incremental unless ``extra`` says otherwise) on
    the slave, 50 cycles on."""
    system = setup()
    mdac(system, "MDAC_1", master=1)
    move = {"MoveType": 1, "Position": 10.0} if type_name == "MAM" else {}
    ops: dict[str, float] = {"Axis": 3, **md_dynamics(speed), **move, **extra}
    inst = logix(system.add(type_name, "MD", ops))
    trigger(system, inst)
    system.cycle(50)
    return system, inst


@pytest.mark.parametrize(
    ("type_name", "speed", "extra", "operand"),
    [
        ("MAJ", 0.5, {"AccelRate": 1e-30}, "AccelRate"),
        ("MAJ", 0.5, {"DecelRate": 1e-30}, "DecelRate"),
        ("MAM", 0.5, {"AccelRate": 1e-30}, "AccelRate"),
        ("MAM", 1e-30, {}, "Speed"),
        ("MAM", 1.0, {"Position": 1e12}, "Position"),
        ("MAJ", 1e30, {}, "Speed"),
        ("MAJ", 1.5, {}, "Speed"),
        ("MAM", 1.5, {}, "Speed"),
        (
            "MAJ",
            0.5,
            {"Profile": 1, "JerkUnits": MASTER_UNITS, "AccelJerk": 1e-30, "DecelJerk": 1.0},
            "AccelJerk",
        ),
    ],
)
def test_master_driven_operands_out_of_range_are_err_13(
    type_name: str, speed: float, extra: dict[str, float], operand: str
) -> None:
    system, inst = master_driven(type_name, speed, **extra)
    assert system.internal_errors == []
    assert inst.bit("ER") and not inst.bit("IP")
    assert inst.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert inst.outputs["EXERR"] == exerr(inst, operand)
    slave = system.ctl.axis(3)
    assert slave.command_velocity == 0.0 and slave.command_position == 0.0


@pytest.mark.parametrize(
    ("type_name", "speed", "extra"),
    [("MAJ", 1.0, {}), ("MAM", 1.0, {}), ("MAJ", 0.5, {"AccelRate": 1e-6})],
)
def test_master_driven_operands_within_range_are_accepted(
    type_name: str, speed: float, extra: dict[str, float]
) -> None:
    system, inst = master_driven(type_name, speed, **extra)
    assert system.internal_errors == []
    assert not inst.bit("ER") and (inst.bit("IP") or inst.bit("PC"))
    assert system.ctl.axis(3).command_position > 0.0


@pytest.mark.parametrize(
    ("limits", "ratio", "velocity", "position"),
    [
        (Limits(0.5, 1e-30, 0.05), 0.0, 0.5, None),  # 5e29 master units to reach 0.5
        (Limits(1e-30, 0.05, 0.05), 0.0, None, 10.0),  # 1e31 master units to cover 10
        (Limits(0.5, 0.05, 1e-30), 0.5, 0.0, None),  # 5e29 master units to stop
        (Limits(0.5, 0.05, 0.05, 1e-30), 0.0, 0.5, None),  # 5e28 to build up 0.05
    ],
)
def test_a_kernel_plan_beyond_the_planner_is_a_motion_error_not_a_ruckig_one(
    limits: Limits, ratio: float, velocity: float | None, position: float | None
) -> None:
    """A master-driven profile planned inside the kernel (a change of master re-plans
    from the ratio the slave inherits) is refused with ERR 13 before ruckig raises."""
    with pytest.raises(MotionError) as info:
        MasterProfile(limits, ratio, velocity, position)
    assert info.value.code == ErrorCode.PARAMETER_OUT_OF_RANGE
