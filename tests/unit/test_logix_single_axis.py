"""Logix single-axis instructions: rung and status-bit rules, DN/IP/PC sequences,
preconditions and error codes, MSO/MSF/MASD/MASR/MAFR and MCD.

The rung rules are the seeds' execution table (MAG, MGS): a false-to-true transition sets
EN and executes; with the rung false EN is cleared once DN or ER is set. EXERR is the
0-based index of the offending operand in the instruction's ST signature, which counts
the Motion Control operand (index 1).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from motion_server.instructions import LogixInstruction, MotionSystem
from motion_server.instructions.operands import AXIS
from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    ErrorCode,
    MotionStatusBit,
)

from ..support import make_system, sample, trigger

DT = 0.002
EN, DN, ER, PC, IP = 1 << 31, 1 << 29, 1 << 28, 1 << 27, 1 << 26


def system_of_axes() -> MotionSystem:
    """Axis1 linear servo, Axis2 virtual, Axis4 feedback only; Axis1 and Axis2 powered."""
    system = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.SERVO,
            max_velocity=100.0,
            max_acceleration=1000.0,
            max_deceleration=1000.0,
            coast_deceleration=500.0,
        ),
        AxisConfig(2, "Axis2", AxisType.VIRTUAL, max_velocity=100.0),
        AxisConfig(4, "Axis4", AxisType.FEEDBACK_ONLY, conversion_constant=100.0),
    )
    mso = system.add("MSO", "MSO_1")
    for n in (1, 2):
        trigger(system, mso, Axis=n)
        rung(system, mso, False)
    return system


def rung(system: MotionSystem, inst: LogixInstruction | Any, value: bool, cycles: int = 1) -> None:
    inst.inputs[inst.TRIGGER] = value
    system.cycle(cycles)


def fire(system: MotionSystem, inst: Any, **operands: Any) -> None:
    """A fresh rising edge: rung false for a scan, then true with ``operands``."""
    rung(system, inst, False)
    trigger(system, inst, **operands)


def snapshot(system: MotionSystem) -> np.ndarray:
    c = system.ctl
    return np.concatenate([c.cmd_pos, c.act_pos, c.cmd_vel, c.act_vel])


# -- rung rules -----------------------------------------------------------------------------
def test_en_follows_the_rung_once_done() -> None:
    system = system_of_axes()
    mso = system.add("MSO", "MSO_2")
    trigger(system, mso, Axis=1)
    assert mso.outputs["FLAGS"] == EN | DN
    rung(system, mso, True, 3)  # rung stays true: nothing changes
    assert mso.outputs["FLAGS"] == EN | DN
    rung(system, mso, False)  # rung false with DN set: EN cleared, DN kept
    assert mso.outputs["FLAGS"] == DN
    rung(system, mso, False, 3)
    assert mso.outputs["FLAGS"] == DN
    trigger(system, mso, Axis=1)  # a new rising edge executes again
    assert mso.outputs["FLAGS"] == EN | DN


class Transaction(LogixInstruction):
    """Stand-in for an instruction whose message transaction has not completed: the
    rising edge sets EN and nothing else (not registered)."""

    TYPE = "TEST_TRANSACTION"
    OPERANDS = (AXIS,)

    def execute(self) -> None:
        pass


def test_en_stays_set_with_the_rung_false_until_done_or_error() -> None:
    system = system_of_axes()
    inst = Transaction("T", system.ctl)
    system.instances["T"] = inst
    trigger(system, inst, Axis=1)
    assert inst.outputs["FLAGS"] == EN
    rung(system, inst, False, 3)
    assert inst.outputs["FLAGS"] == EN  # neither DN nor ER: EN stays
    inst.set_bits(DN=True)  # the transaction completes
    assert inst.outputs["FLAGS"] == EN | DN
    rung(system, inst, False)
    assert inst.outputs["FLAGS"] == DN
    trigger(system, inst, Axis=1)
    inst.fail(ErrorCode.AXIS_IN_MOTION)  # this time it ends in error
    rung(system, inst, False)
    assert inst.outputs["FLAGS"] == ER


def test_error_holds_er_and_err_until_the_next_rising_edge() -> None:
    system = system_of_axes()
    msf = system.add("MSF", "MSF_1")
    trigger(system, msf, Axis=1)
    maj = system.add("MAJ", "MAJ_1")
    trigger(system, maj, Axis=1)
    assert maj.outputs["FLAGS"] == EN | ER
    assert maj.outputs["ERR"] == ErrorCode.SERVO_OFF_STATE
    rung(system, maj, False, 2)
    assert maj.outputs["FLAGS"] == ER
    assert maj.outputs["ERR"] == ErrorCode.SERVO_OFF_STATE
    fire(system, system["MSO_1"], Axis=1)
    trigger(system, maj, Axis=1)  # new edge: ER and ERR cleared, then executed
    assert maj.outputs["FLAGS"] == EN | DN | IP
    assert maj.outputs["ERR"] == 0


# -- DN / IP / PC sequences -----------------------------------------------------------------
def test_maj_sets_dn_and_ip_at_once_and_ip_until_stopped() -> None:
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_1")
    mas = system.add("MAS", "MAS_1")
    ax = system.ctl.axis(1)
    trigger(system, maj, Axis=1, Speed=20.0)
    assert maj.outputs["FLAGS"] == EN | DN | IP
    assert ax.motion_status & (1 << MotionStatusBit.JOG)
    rung(system, maj, False, 50)  # the rung does not end a jog
    assert maj.outputs["FLAGS"] == DN | IP
    trigger(system, mas, Axis=1, StopType=1)  # stop the jog
    assert maj.outputs["FLAGS"] == DN  # IP cleared, a jog never sets PC
    assert mas.outputs["FLAGS"] == EN | DN | IP
    assert ax.motion_status & (1 << MotionStatusBit.STOPPING)
    system.cycle(100)
    assert mas.outputs["FLAGS"] == EN | DN | PC
    assert ax.command_velocity == 0.0
    assert not ax.motion_status & (1 << MotionStatusBit.STOPPING)


def test_a_new_maj_supersedes_the_jog_and_inherits_its_velocity() -> None:
    system = system_of_axes()
    maj1 = system.add("MAJ", "MAJ_1")
    maj2 = system.add("MAJ", "MAJ_2")
    ax = system.ctl.axis(1)
    trigger(system, maj1, Axis=1, Speed=50.0, AccelRate=500.0, DecelRate=500.0)
    system.cycle(60)
    assert ax.command_velocity == 50.0
    before = ax.command_position
    trigger(system, maj2, Axis=1, Direction=1, Speed=50.0, AccelRate=500.0, DecelRate=500.0)
    assert not maj1.outputs["IP"] and not maj1.outputs["PC"]
    assert maj2.outputs["IP"]
    p = np.concatenate([[before, ax.command_position], sample(system, 1, 250)])
    a = np.diff(p, 2) / DT**2
    assert np.abs(a).max() <= 500.0 * (1 + 1e-9)  # no velocity jump: inherited
    assert ax.command_velocity == -50.0


def test_mam_sets_pc_when_it_arrives() -> None:
    system = system_of_axes()
    mam = system.add("MAM", "MAM_1")
    ax = system.ctl.axis(1)
    trigger(system, mam, Axis=1, Position=5.0, Speed=50.0, AccelRate=500.0, DecelRate=500.0)
    assert mam.outputs["FLAGS"] == EN | DN | IP
    assert ax.motion_status & (1 << MotionStatusBit.MOVE)
    rung(system, mam, False)
    flags = []
    while not mam.outputs["PC"]:
        assert ax.command_position != 5.0  # not there before PC
        flags.append(mam.outputs["FLAGS"])
        system.cycle()
        assert len(flags) < 200
    assert set(flags) == {DN | IP}
    assert mam.outputs["FLAGS"] == DN | PC  # IP and PC change in the same scan
    assert ax.command_position == 5.0
    # 5 mm at 50 mm/s, 500 mm/s^2 is a triangle (5 = v^2/a): 2*sqrt(5/500) = 0.2 s
    assert abs((len(flags) + 2) * DT - 0.2) <= DT * (1 + 1e-9)


@pytest.mark.parametrize("ender", ["MAM", "MASD", "MSF"])
def test_mam_superseded_or_disabled_clears_ip_without_pc(ender: str) -> None:
    system = system_of_axes()
    mam = system.add("MAM", "MAM_1")
    trigger(system, mam, Axis=1, Position=50.0)
    system.cycle(10)
    other = system.add(ender, f"{ender}_2")
    operands = {"Position": 0.0} if ender == "MAM" else {}
    trigger(system, other, Axis=1, **operands)
    assert mam.outputs["DN"] and not mam.outputs["IP"] and not mam.outputs["PC"]


def test_mas_on_an_axis_at_rest_is_complete_at_once() -> None:
    system = system_of_axes()
    mas = system.add("MAS", "MAS_1")
    trigger(system, mas, Axis=1)
    assert mas.outputs["FLAGS"] == EN | DN | PC


def test_mas_move_leaves_a_superimposed_jog_running() -> None:
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_1")
    mam = system.add("MAM", "MAM_1")
    mas = system.add("MAS", "MAS_1")
    ax = system.ctl.axis(1)
    dyn = {"AccelRate": 1000.0, "DecelRate": 1000.0}
    trigger(system, maj, Axis=1, Speed=20.0, **dyn)
    trigger(system, mam, Axis=1, MoveType=1, Position=100.0, Speed=30.0, **dyn)
    system.cycle(60)
    assert ax.command_velocity == 50.0  # velocities add: 20 + 30
    trigger(system, mas, Axis=1, StopType=2)  # move only
    system.cycle(60)
    assert ax.command_velocity == 20.0
    assert maj.outputs["IP"] and not mam.outputs["IP"] and not mam.outputs["PC"]
    assert mas.outputs["PC"]


# -- power state instructions ---------------------------------------------------------------
def test_msf_turns_the_drive_off_and_the_axis_coasts() -> None:
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_1")
    msf = system.add("MSF", "MSF_1")
    ax = system.ctl.axis(1)
    trigger(system, maj, Axis=1, Speed=50.0)
    system.cycle(400)  # at speed, the drive settled
    v0 = ax.actual_velocity
    assert v0 == pytest.approx(50.0, rel=1e-6)
    trigger(system, msf, Axis=1)
    assert msf.outputs["FLAGS"] == EN | DN
    assert ax.state == AxisState.AXIS_READY
    assert not maj.outputs["IP"]
    assert not ax.motion_status & (1 << MotionStatusBit.JOG)
    # coasting at 500 mm/s^2: 50 mm/s to rest in 0.1 s, v0^2/(2 c) = 2.5 mm further
    v, x = [ax.actual_velocity], [ax.actual_position]
    for _ in range(60):
        system.cycle()
        v.append(ax.actual_velocity)
        x.append(ax.actual_position)
        assert ax.command_position == ax.actual_position
    dv = np.diff(v)
    moving = np.array(v[:-1]) > 500.0 * DT
    assert dv[moving] == pytest.approx(-500.0 * DT, rel=1e-9)
    assert v[-1] == 0.0
    assert x[-1] - x[0] == pytest.approx(v[0] ** 2 / (2 * 500.0), abs=1e-3 + 0.5 * v[0] * DT)


def test_masd_and_masr() -> None:
    system = system_of_axes()
    masd = system.add("MASD", "MASD_1")
    masr = system.add("MASR", "MASR_1")
    maj = system.add("MAJ", "MAJ_1")
    ax = system.ctl.axis(1)
    trigger(system, maj, Axis=1, Speed=10.0)
    trigger(system, masd, Axis=1)
    assert masd.outputs["FLAGS"] == EN | DN
    assert ax.state == AxisState.AXIS_SHUTDOWN
    assert not maj.outputs["IP"]
    fire(system, maj, Axis=1)
    assert maj.outputs["ER"] and maj.outputs["ERR"] == ErrorCode.SHUTDOWN_STATE
    mso = system["MSO_1"]
    fire(system, mso, Axis=1)
    assert mso.outputs["ER"] and mso.outputs["ERR"] == ErrorCode.SHUTDOWN_STATE
    trigger(system, masr, Axis=1)
    assert masr.outputs["FLAGS"] == EN | DN
    assert ax.state == AxisState.AXIS_READY
    fire(system, mso, Axis=1)
    assert mso.outputs["DN"] and ax.state == AxisState.SERVO_CONTROL


def test_mafr_clears_faults_and_is_done_on_a_healthy_axis() -> None:
    system = system_of_axes()
    mafr = system.add("MAFR", "MAFR_1")
    ax = system.ctl.axis(1)
    trigger(system, mafr, Axis=1)
    assert mafr.outputs["FLAGS"] == EN | DN
    assert ax.state == AxisState.SERVO_CONTROL  # nothing to reset, nothing changed
    system.ctl.fault(ax, AxisFault.POSITION_ERROR)
    assert ax.state == AxisState.AXIS_FAULTED
    fire(system, mafr, Axis=1)
    assert ax.state == AxisState.AXIS_READY and ax.fault == 0


# -- preconditions and error codes ----------------------------------------------------------
def put_in_state(system: MotionSystem, state: str) -> int:
    """Bring Axis1 into ``state``; return the axis number to command."""
    ax = system.ctl.axis(1)
    if state == "servo_off":
        system.ctl.servo_off(ax)
    elif state == "shutdown":
        system.ctl.shutdown(ax)
    elif state == "faulted":
        system.ctl.fault(ax, AxisFault.POSITION_ERROR)
    elif state == "feedback_only":
        return 4
    return 1


@pytest.mark.parametrize(
    ("state", "code"),
    [
        ("servo_off", ErrorCode.SERVO_OFF_STATE),
        ("shutdown", ErrorCode.SHUTDOWN_STATE),
        ("faulted", ErrorCode.AXIS_FAULTED),
        ("feedback_only", ErrorCode.WRONG_AXIS_TYPE),
    ],
)
@pytest.mark.parametrize("type_name", ["MAJ", "MAM"])
def test_motion_refused_by_axis_state(type_name: str, state: str, code: ErrorCode) -> None:
    system = system_of_axes()
    inst = system.add(type_name, f"{type_name}_1")
    n = put_in_state(system, state)
    system.cycle()
    before = snapshot(system)
    trigger(system, inst, Axis=n, Position=10.0, Speed=10.0)
    assert inst.outputs["FLAGS"] == EN | ER
    assert inst.outputs["ERR"] == code
    assert inst.outputs["EXERR"] == 0
    system.cycle(20)
    assert (snapshot(system) == before).all()
    assert system.ctl.axis(n).processes == []


@pytest.mark.parametrize(
    ("type_name", "operands", "exerr"),
    [
        # MAJ(Axis, MotionControl, Direction, Speed, SpeedUnits, AccelRate, AccelUnits, ...)
        ("MAJ", {"Speed": -1.0}, 3),
        ("MAJ", {"Direction": 2}, 2),
        ("MAJ", {"SpeedUnits": 7}, 4),
        ("MAJ", {"AccelRate": 0.0}, 5),
        ("MAJ", {"DecelRate": math.nan}, 7),
        ("MAJ", {"Profile": 1, "AccelJerk": 0.0, "JerkUnits": 0}, 10),
        # MAM(Axis, MotionControl, MoveType, Position, Speed, ...)
        ("MAM", {"MoveType": 9}, 2),
        ("MAM", {"Position": math.inf}, 3),
        ("MAM", {"Position": 10.0, "Speed": 0.0}, 4),
        ("MAM", {"Position": 10.0, "MoveType": 2}, 2),  # rotary type on a linear axis
        # MAS(Axis, MotionControl, StopType, ChangeDecel, DecelRate, ...)
        ("MAS", {"StopType": 99}, 2),
        ("MAS", {"ChangeDecel": 1, "DecelRate": -5.0}, 4),
        # MCD(Axis, MotionControl, MotionType, ChangeSpeed, Speed, ChangeAccel, AccelRate..)
        ("MCD", {"MotionType": 2}, 2),
        ("MCD", {"ChangeSpeed": 1, "Speed": -1.0}, 4),
        ("MCD", {"ChangeAccel": 1, "AccelRate": 0.0}, 6),
        ("MCD", {"ChangeDecel": 1, "DecelUnits": 3}, 15),
    ],
)
def test_out_of_range_operand_names_it_in_exerr(
    type_name: str, operands: dict[str, Any], exerr: int
) -> None:
    # two identical systems with an axis in motion; only one sees the faulty trigger
    system, reference = (jogging(type_name) for _ in range(2))
    inst = system[f"{type_name}_1"]
    trigger(system, inst, Axis=1, **operands)
    reference.cycle()
    assert inst.outputs["FLAGS"] == EN | ER
    assert inst.outputs["ERR"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert inst.outputs["EXERR"] == exerr
    # the running jog goes on exactly as if the instruction had not been triggered
    for _ in range(50):
        assert (snapshot(system) == snapshot(reference)).all()
        system.cycle()
        reference.cycle()


def jogging(type_name: str) -> MotionSystem:
    """Axis1 jogging at 20 mm/s, and an idle ``<type_name>_1`` instance."""
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_RUN")
    trigger(system, maj, Axis=1, Speed=20.0)
    system.cycle(5)
    system.add(type_name, f"{type_name}_1")
    return system


@pytest.mark.parametrize("type_name", ["MSO", "MSF", "MAFR", "MASD", "MASR", "MAJ", "MAM", "MAS"])
@pytest.mark.parametrize("axis", [0, 3, 99, -1])
def test_unconfigured_axis_is_err_11(type_name: str, axis: int) -> None:
    system = system_of_axes()
    inst = system.add(type_name, f"{type_name}_2")
    before = snapshot(system)
    trigger(system, inst, Axis=axis)
    assert inst.outputs["FLAGS"] == EN | ER
    assert inst.outputs["ERR"] == ErrorCode.AXIS_NOT_CONFIGURED
    assert inst.outputs["EXERR"] == 0
    assert (snapshot(system) == before).all()


# -- MCD ------------------------------------------------------------------------------------
def test_mcd_changes_jog_speed_at_the_new_deceleration() -> None:
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_1")
    mcd = system.add("MCD", "MCD_1")
    ax = system.ctl.axis(1)
    trigger(system, maj, Axis=1, Direction=1, Speed=50.0, AccelRate=1000.0, DecelRate=1000.0)
    system.cycle(60)
    assert ax.command_velocity == -50.0
    before = ax.command_position
    trigger(
        system, mcd, Axis=1, MotionType=0, ChangeSpeed=1, Speed=20.0, ChangeDecel=1,
        DecelRate=200.0,
    )  # fmt: skip
    assert mcd.outputs["FLAGS"] == EN | DN
    p = np.concatenate([[before, ax.command_position], sample(system, 1, 200)])
    v = np.diff(p) / DT
    a = np.diff(p, 2) / DT**2
    assert np.abs(a).max() <= 200.0 * (1 + 1e-9)
    assert a.max() == pytest.approx(200.0, rel=1e-6)  # slows at the new decel
    # from -50 to -20 at 200 mm/s^2: 0.15 s; the direction is kept
    k = next(i for i, x in enumerate(v) if x >= -20.0 * (1 + 1e-9))
    assert abs(k * DT - 30.0 / 200.0) <= DT * (1 + 1e-9)
    assert ax.command_velocity == -20.0
    assert maj.outputs["IP"]


def test_mcd_speed_percent_of_maximum() -> None:
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_1")
    mcd = system.add("MCD", "MCD_1")
    trigger(system, maj, Axis=1, Speed=50.0, AccelRate=1000.0, DecelRate=1000.0)
    trigger(system, mcd, Axis=1, ChangeSpeed=1, Speed=10.0, SpeedUnits=1)  # 10 % of 100
    system.cycle(100)
    assert system.ctl.axis(1).command_velocity == 10.0


def test_mcd_on_a_move_keeps_the_target() -> None:
    """100 mm at 50 mm/s, a = d = 500 mm/s^2: 0.1 s up to speed (2.5 mm), cruise; at
    0.5 s (x1 = 22.5 mm) MCD sets 25 mm/s: 0.05 s down to 25 mm/s (1.875 mm), cruise
    at 25 mm/s, 0.05 s down to rest (0.625 mm), exactly on 100 mm."""
    system = system_of_axes()
    mam = system.add("MAM", "MAM_1")
    mcd = system.add("MCD", "MCD_1")
    ax = system.ctl.axis(1)
    trigger(system, mam, Axis=1, Position=100.0, Speed=50.0, AccelRate=500.0, DecelRate=500.0)
    system.cycle(249)  # 0.5 s after the trigger cycle began
    x1 = ax.command_position
    assert x1 == pytest.approx(2.5 + 50.0 * 0.4, abs=1e-9)
    trigger(system, mcd, Axis=1, MotionType=1, ChangeSpeed=1, Speed=25.0)
    n = 1
    while not mam.outputs["PC"]:
        system.cycle()
        n += 1
        assert n < 5000
    cruise = (100.0 - x1 - 1.875 - 0.625) / 25.0
    assert abs(n * DT - (0.05 + cruise + 0.05)) <= DT * (1 + 1e-9)
    assert ax.command_position == 100.0


def test_mcd_speed_zero_pauses_a_move_and_a_new_speed_resumes_it() -> None:
    system = system_of_axes()
    mam = system.add("MAM", "MAM_1")
    mcd = system.add("MCD", "MCD_1")
    ax = system.ctl.axis(1)
    trigger(system, mam, Axis=1, Position=20.0, Speed=50.0, AccelRate=500.0, DecelRate=500.0)
    system.cycle(100)
    trigger(system, mcd, Axis=1, MotionType=1, ChangeSpeed=1, Speed=0.0)
    system.cycle(60)  # 50 mm/s to rest at 500 mm/s^2: 0.1 s
    held = ax.command_position
    assert ax.command_velocity == 0.0 and held < 20.0
    system.cycle(100)
    assert ax.command_position == held
    assert mam.outputs["IP"] and not mam.outputs["PC"]  # paused, still in process
    fire(system, mcd, Axis=1, MotionType=1, ChangeSpeed=1, Speed=50.0)
    system.cycle(400)
    assert mam.outputs["PC"] and ax.command_position == 20.0


def test_mcd_with_nothing_to_change_is_done() -> None:
    system = system_of_axes()
    mcd = system.add("MCD", "MCD_1")
    before = snapshot(system)
    trigger(system, mcd, Axis=1, ChangeSpeed=1, Speed=30.0, ChangeAccel=1, AccelRate=5.0)
    assert mcd.outputs["FLAGS"] == EN | DN
    system.cycle(10)
    assert (snapshot(system) == before).all()


def test_mcd_does_not_judge_values_it_does_not_change() -> None:
    system = system_of_axes()
    maj = system.add("MAJ", "MAJ_1")
    mcd = system.add("MCD", "MCD_1")
    trigger(system, maj, Axis=1, Speed=50.0, AccelRate=1000.0, DecelRate=1000.0)
    trigger(
        system, mcd, Axis=1, ChangeSpeed=1, Speed=30.0, AccelRate=math.nan, DecelRate=-1.0,
        AccelJerk=math.inf, AccelUnits=9,
    )  # fmt: skip
    assert mcd.outputs["FLAGS"] == EN | DN
    system.cycle(100)
    assert system.ctl.axis(1).command_velocity == 30.0
