"""MGSD / MGSR and axis shutdown: ERR 7 while shut down, success after the reset, and a
shut-down master releasing whatever follows it (generic over process kinds).

dt = 2 ms. Coasting axes lose C*dt per cycle; a released follower ramps its released
velocity down at its maximum deceleration, 1000 mm/s^2 = 2 mm/s per cycle.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_server.instructions import Instruction, LogixInstruction, MotionSystem
from motion_server.kernel import (
    AbortReason,
    Axis,
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    GroupState,
    MotionStatusBit,
    Process,
    ProcessKind,
    ProcessState,
)

from ..support import make_system, trigger

DT = 0.002
COAST = 500.0


def logix(inst: Instruction) -> LogixInstruction:
    assert isinstance(inst, LogixInstruction)
    return inst


def servo(number: int) -> AxisConfig:
    return AxisConfig(
        number,
        f"Axis{number}",
        AxisType.SERVO,
        max_velocity=200.0,
        max_acceleration=1e4,
        max_deceleration=1e4,
        coast_deceleration=COAST,
    )


def shut_down_group() -> MotionSystem:
    """Two servo axes jogging at 50 mm/s and a hand wheel, then MGSD."""
    system = make_system(servo(1), servo(2), AxisConfig(3, "Wheel", AxisType.FEEDBACK_ONLY))
    for n in (1, 2):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
        jog = {"Axis": n, "Speed": 50.0, "AccelRate": 1e4}
        trigger(system, system.add("MAJ", f"MAJ_{n}", jog))
    system.cycle(200)
    mgsd = logix(system.add("MGSD", "MGSD_1", {"Group": 1}))
    trigger(system, mgsd)
    assert mgsd.bit("DN") and not mgsd.bit("ER")
    return system


def test_mgsd_shuts_every_axis_down_at_once_and_they_coast() -> None:
    system = shut_down_group()
    ctl = system.ctl
    assert [a.state for a in ctl.axes] == [AxisState.AXIS_SHUTDOWN] * 3
    assert ctl.groups[0].state == GroupState.SHUTDOWN
    for n in (1, 2):
        assert not logix(system[f"MAJ_{n}"]).bit("IP")
        ax = ctl.axis(n)
        assert not ax.drive_enabled
        v = [ax.actual_velocity]
        for _ in range(5):
            system.cycle()
            v.append(ax.actual_velocity)
        np.testing.assert_allclose(np.diff(v), -COAST * DT, atol=1e-9)


def test_instructions_error_with_err_7_until_mgsr() -> None:
    system = shut_down_group()
    system.cycle(200)
    for name, type_name, ops in (
        ("MAJ_x", "MAJ", {"Axis": 1, "Speed": 10.0}),
        ("MAM_x", "MAM", {"Axis": 2, "Position": 5.0, "Speed": 10.0}),
        ("MSO_x", "MSO", {"Axis": 1}),
    ):
        inst = logix(system.add(type_name, name, ops))
        trigger(system, inst)
        assert inst.bit("ER") and inst.outputs["ERR"] == ErrorCode.SHUTDOWN_STATE, name
        inst.inputs["Execute"] = False
    move = system.add("MC_MoveAbsolute", "MC_1", {"Axis": 1, "Position": 5.0})
    trigger(system, move)
    assert move.outputs["Error"] and move.outputs["ErrorID"] == ErrorCode.SHUTDOWN_STATE
    power = system.add("MC_Power", "PWR_2", {"Axis": 2})
    power.inputs["Enable"] = True
    system.cycle()
    assert power.outputs["Error"] and power.outputs["ErrorID"] == ErrorCode.SHUTDOWN_STATE
    assert not power.outputs["Status"]

    mgsr = logix(system.add("MGSR", "MGSR_1", {"Group": 1}))
    trigger(system, mgsr)
    assert mgsr.bit("DN") and not mgsr.bit("ER")
    assert [a.state for a in system.ctl.axes] == [AxisState.AXIS_READY] * 3
    system.cycle()
    # PLCopen: "As long as 'Enable' is true, power is being enabled": the held Enable
    # enables axis 2 once MGSR brought it back to Axis Ready, and the ERR 7 clears
    assert power.outputs["Status"] and not power.outputs["Error"]
    assert power.outputs["ErrorID"] == 0
    assert system.ctl.axis(2).state == AxisState.SERVO_CONTROL
    mso = logix(system["MSO_x"])
    trigger(system, mso)
    assert mso.bit("DN") and not mso.bit("ER")
    maj = logix(system["MAJ_x"])
    trigger(system, maj)
    assert maj.bit("IP") and not maj.bit("ER")
    mam = logix(system["MAM_x"])
    trigger(system, mam)
    assert mam.bit("IP") and not mam.bit("ER")


def test_mgsr_also_resets_a_faulted_axis_and_errors_on_an_unknown_group() -> None:
    system = make_system(servo(1), servo(2))
    ctl = system.ctl
    trigger(system, system.add("MSO", "MSO_1", {"Axis": 1}))
    ctl.fault(ctl.axis(1), AxisFault.POSITION_ERROR)
    assert ctl.axis(1).state == AxisState.AXIS_FAULTED
    bad = logix(system.add("MGSR", "MGSR_9", {"Group": 9}))
    trigger(system, bad)
    assert bad.bit("ER") and bad.outputs["ERR"] == ErrorCode.GROUP_NOT_CONFIGURED
    assert ctl.axis(1).state == AxisState.AXIS_FAULTED
    mgsr = logix(system.add("MGSR", "MGSR_1", {"Group": 1}))
    trigger(system, mgsr)
    assert ctl.axis(1).state == AxisState.AXIS_READY and ctl.axis(1).fault == 0
    bad_sd = logix(system.add("MGSD", "MGSD_9", {"Group": 9}))
    trigger(system, bad_sd)
    assert bad_sd.outputs["ERR"] == ErrorCode.GROUP_NOT_CONFIGURED
    assert ctl.axis(1).state == AxisState.AXIS_READY


class FollowMaster(Process):
    """A stand-in for gearing: ratio times the master's command displacement."""

    kind = ProcessKind.GEAR

    def __init__(self, master: Axis, ratio: float) -> None:
        super().__init__()
        self.masters = (master.number,)
        self.master = master
        self.ratio = ratio
        self.start = master.command_position_unwound

    def step(self, ctl: Controller, dt: float) -> None:
        self.position = self.ratio * (self.master.command_position_unwound - self.start)
        self.velocity = self.ratio * self.master.command_velocity


def follower_rig() -> tuple[MotionSystem, Process]:
    """Master (axis 1, group 1) at 100 mm/s; the follower (axis 2, group 2, maximum
    deceleration 1000 mm/s^2) geared at 0.5 plus its own jog at 20 mm/s: 70 mm/s."""
    ctl = Controller(
        [
            AxisConfig(1, "Master", AxisType.VIRTUAL, max_acceleration=1e4),
            AxisConfig(2, "Follower", AxisType.VIRTUAL, max_deceleration=1000.0),
        ],
        [GroupConfig(1, "G1", (1,), DT), GroupConfig(2, "G2", (2,), DT)],
    )
    system = MotionSystem(ctl)
    for n in (1, 2):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
    master, follower = ctl.axis(1), ctl.axis(2)
    trigger(system, system.add("MAJ", "JOG_1", {"Axis": 1, "Speed": 100.0, "AccelRate": 1e4}))
    trigger(system, system.add("MAJ", "JOG_2", {"Axis": 2, "Speed": 20.0, "AccelRate": 1e4}))
    gear = ctl.start(follower, lambda v, a: FollowMaster(master, 0.5), replace=())
    system.cycle(20)
    assert follower.command_velocity == pytest.approx(70.0, abs=1e-9)
    return system, gear


@pytest.mark.parametrize("how", ["MASD", "MGSD"])
def test_a_shut_down_master_releases_any_process_that_follows_it(how: str) -> None:
    system, gear = follower_rig()
    ctl = system.ctl
    follower = ctl.axis(2)
    if how == "MASD":
        ctl.shutdown(ctl.axis(1))
    else:
        trigger(system, system.add("MGSD", "MGSD_1", {"Group": 1}))
    assert gear.state == ProcessState.ABORTED and gear.abort_reason == AbortReason.SHUTDOWN
    word = follower.motion_status
    assert not word >> MotionStatusBit.GEARING & 1
    assert word >> MotionStatusBit.STOPPING & 1 and word >> MotionStatusBit.JOG & 1
    vel = [follower.command_velocity]
    for _ in range(30):
        system.cycle()
        vel.append(follower.command_velocity)
    first = 0 if how == "MASD" else 1  # MGSD's own cycle already ran one ramp step
    ramp = np.maximum(50.0 - 2.0 * np.arange(first, first + 31), 0.0)
    np.testing.assert_allclose(vel, 20.0 + ramp, atol=1e-9)
    assert follower.state == AxisState.SERVO_CONTROL
    assert logix(system["JOG_2"]).bit("IP")
    assert not follower.stopping


def test_shutting_the_slave_down_aborts_its_processes() -> None:
    system, gear = follower_rig()
    ctl = system.ctl
    ctl.shutdown(ctl.axis(2))
    assert gear.state == ProcessState.ABORTED and gear.abort_reason == AbortReason.SHUTDOWN
    system.cycle()
    assert not logix(system["JOG_2"]).bit("IP")
    assert ctl.axis(2).state == AxisState.AXIS_SHUTDOWN
