"""Which stops break an MDAC link, and MGS in master-driven mode.

Masters A (axis 1) and B (axis 2) are in group 1, the slave (axis 3, virtual, maximum
deceleration 1000 mm/s^2) in group 2, dt = 2 ms. A jogs at 100 mm/s; the slave follows
A master-driven at 0.5 mm per master mm, i.e. 50 mm/s. A time-driven stop of the slave
takes 1000 * 0.002 = 2 mm/s off per cycle: 25 cycles from 50 mm/s.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from motion_server.instructions import Instruction, LogixInstruction, MotionSystem
from motion_server.kernel import (
    AbortReason,
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    ProcessState,
)
from motion_server.kernel.group import OperatingMode
from motion_server.kernel.master_driven import MasterDrivenJog

from ..support import trigger

DT = 0.002
SLAVE_DECEL = 1000.0


def logix(inst: Instruction) -> LogixInstruction:
    assert isinstance(inst, LogixInstruction)
    return inst


def virtual(number: int, decel: float = 1e4) -> AxisConfig:
    return AxisConfig(
        number,
        f"Axis{number}",
        AxisType.VIRTUAL,
        max_velocity=1000.0,
        max_acceleration=1e4,
        max_deceleration=decel,
    )


def md(speed: float) -> dict[str, float]:
    return {
        "Speed": speed,
        "SpeedUnits": 4,
        "AccelRate": 0.05,
        "AccelUnits": 4,
        "DecelRate": 0.05,
        "DecelUnits": 4,
    }


class Rig:
    """The slave tracking master A, with its MDAC and MAJ."""

    def __init__(self) -> None:
        ctl = Controller(
            [virtual(1), virtual(2), virtual(3, SLAVE_DECEL)],
            [GroupConfig(1, "Masters", (1, 2), DT), GroupConfig(2, "Slaves", (3,), DT)],
        )
        self.system = system = MotionSystem(ctl)
        self.ctl = ctl
        for n in (1, 2, 3):
            trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
        for n, speed in ((1, 100.0), (2, 80.0)):
            jog = {"Axis": n, "Speed": speed, "AccelRate": 1e4}
            trigger(system, system.add("MAJ", f"JOG_{n}", jog))
        self.mdac = self.add("MDAC", "MDAC_1", SlaveAxis=3, MasterAxis=1, MasterReference=1)
        self.maj = self.add("MAJ", "MAJ_1", Axis=3, **md(0.5))
        system.cycle(60)
        self.slave = ctl.axis(3)
        self.master = ctl.axis(1)
        assert self.slave.command_velocity == pytest.approx(50.0, abs=1e-9)
        assert self.mdac.bit("IP") and self.mdac.bit("AC")
        self.process = self.slave.processes[0]
        assert isinstance(self.process, MasterDrivenJog)

    def add(self, type_name: str, name: str, **operands: object) -> LogixInstruction:
        inst = logix(self.system.add(type_name, name, dict(operands)))
        trigger(self.system, inst)
        return inst


def mas_all_slave(rig: Rig) -> None:
    rig.add("MAS", "MAS_s", Axis=3, StopType=0)


def mgs_slave(rig: Rig) -> None:
    rig.add("MGS", "MGS_s", Group=2)


def masd_slave(rig: Rig) -> None:
    rig.ctl.shutdown(rig.slave)
    rig.system.cycle()


def mgsd_slave(rig: Rig) -> None:
    rig.add("MGSD", "MGSD_s", Group=2)


def fault_slave(rig: Rig) -> None:
    rig.ctl.fault(rig.slave, AxisFault.POSITION_ERROR)
    rig.system.cycle()


def masd_master(rig: Rig) -> None:
    rig.ctl.shutdown(rig.master)
    rig.system.cycle()


def mgsd_master(rig: Rig) -> None:
    rig.add("MGSD", "MGSD_m", Group=1)


def mgs_master(rig: Rig) -> None:
    rig.add("MGS", "MGS_m", Group=1)


def program_mode(rig: Rig) -> None:
    rig.ctl.set_mode(OperatingMode.PROGRAM)
    rig.system.cycle()


@pytest.mark.parametrize(
    "stop",
    [
        mas_all_slave,
        mgs_slave,
        masd_slave,
        mgsd_slave,
        fault_slave,
        masd_master,
        mgsd_master,
        mgs_master,
        program_mode,
    ],
)
def test_stops_that_break_the_link(stop: Callable[[Rig], None]) -> None:
    rig = Rig()
    stop(rig)
    assert not rig.mdac.bit("IP")
    assert rig.ctl.mdsc.links(3) == []
    assert not rig.maj.bit("IP")
    # master units now need a new MDAC
    rig.system.cycle(200)
    if rig.slave.state == AxisState.SERVO_CONTROL and rig.ctl.run_mode:
        again = rig.add("MAJ", "MAJ_again", Axis=3, **md(0.5))
        assert again.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE


def test_stops_that_keep_the_link() -> None:
    rig = Rig()
    # MAS All on the master: the slave follows it down, the link stays
    rig.add("MAS", "MAS_m", Axis=1, StopType=0)
    rig.system.cycle(20)
    assert rig.master.command_velocity == 0.0 and rig.slave.command_velocity == 0.0
    assert rig.mdac.bit("IP") and rig.mdac.bit("AC") and rig.maj.bit("IP")
    # MAS Jog on the slave: the jog stops, AC is reset, IP stays
    rig.add("MAS", "MAS_j", Axis=3, StopType=1)
    rig.system.cycle()
    assert rig.mdac.bit("IP") and not rig.mdac.bit("AC") and not rig.maj.bit("IP")
    # MSF on the slave: the link stays
    rig.ctl.servo_off(rig.slave)
    rig.system.cycle()
    assert rig.mdac.bit("IP") and rig.ctl.mdsc.links(3) != []


def test_mgs_in_master_driven_mode_stops_time_driven() -> None:
    rig = Rig()
    pending = rig.add("MDAC", "MDAC_2", SlaveAxis=3, MasterAxis=2, MasterReference=1)
    assert pending.bit("IP") and not pending.bit("AC")
    mgs = rig.add("MGS", "MGS_s", Group=2)
    # the link and the pending reassignment are reset at once; AC waits for rest
    assert not rig.mdac.bit("IP") and rig.mdac.bit("AC")
    assert not pending.bit("IP") and not pending.bit("AC")
    assert not rig.maj.bit("IP")
    assert rig.process.state == ProcessState.ABORTED
    # time-driven: 2 mm/s per cycle whatever the master does (it runs on at 100 mm/s)
    vel = [rig.slave.command_velocity]
    while mgs.bit("IP") and len(vel) < 40:
        rig.system.cycle()
        vel.append(rig.slave.command_velocity)
        assert rig.mdac.bit("AC") == mgs.bit("IP")
    expected = np.maximum(50.0 - SLAVE_DECEL * DT * np.arange(1, len(vel) + 1), 0.0)
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert len(vel) == 25 and mgs.bit("PC")
    assert rig.master.command_velocity == pytest.approx(100.0)
    assert not rig.mdac.bit("AC")
    # MGS cleared the pending master: master units need a new MDAC
    late = rig.add("MAJ", "MAJ_late", Axis=3, **md(0.5))
    assert late.outputs["ERR"] == ErrorCode.MDSC_INVALID_MODE_OR_MASTER_CHANGE


def test_a_shut_down_master_releases_its_master_driven_slave() -> None:
    """The slave keeps Servo Control and ramps the released speed down at its maximum
    deceleration; its own time-driven move goes on."""
    rig = Rig()
    move = rig.add(
        "MAM", "MAM_t", Axis=3, MoveType=1, Position=1000.0, Speed=10.0, AccelRate=1000.0
    )
    rig.system.cycle(20)  # the move cruises at 10 mm/s on top of the 50 mm/s jog
    assert rig.slave.command_velocity == pytest.approx(60.0, abs=1e-9)
    rig.ctl.shutdown(rig.master)
    assert rig.process.state == ProcessState.ABORTED
    assert rig.process.abort_reason == AbortReason.SHUTDOWN
    assert rig.slave.stopping
    vel = []
    for _ in range(30):
        rig.system.cycle()
        vel.append(rig.slave.command_velocity)
    expected = 10.0 + np.maximum(50.0 - SLAVE_DECEL * DT * np.arange(1, 31), 0.0)
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert rig.slave.state == AxisState.SERVO_CONTROL and move.bit("IP")
    assert not rig.maj.bit("IP") and not rig.mdac.bit("IP")
    assert not rig.slave.stopping


def test_mgs_on_the_master_group_switches_the_slave_to_a_time_driven_stop() -> None:
    """The master stops in 5 cycles (1e4 mm/s^2); the slave, in another group, does not
    follow it down master-driven but ramps 50 mm/s off at 2 mm/s per cycle: 25 cycles."""
    rig = Rig()
    rig.add("MGS", "MGS_m", Group=1)
    assert not rig.mdac.bit("IP") and rig.mdac.bit("AC")
    assert rig.process.state == ProcessState.ABORTED
    vel = [rig.slave.command_velocity]
    for _ in range(30):
        rig.system.cycle()
        vel.append(rig.slave.command_velocity)
    expected = np.maximum(50.0 - SLAVE_DECEL * DT * np.arange(1, 32), 0.0)
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert rig.master.command_velocity == 0.0
    assert not rig.mdac.bit("AC")  # reset once the slave has stopped
    assert rig.slave.state == AxisState.SERVO_CONTROL


def test_a_faulted_master_breaks_the_link_and_the_slave_stops_time_driven() -> None:
    rig = Rig()
    rig.ctl.fault(rig.master, AxisFault.POSITION_ERROR)
    rig.system.cycle()  # the fault is seen at the end of this cycle's update
    assert not rig.mdac.bit("IP") and not rig.mdac.bit("AC")
    assert rig.process.abort_reason == AbortReason.FAULTED
    vel = [rig.slave.command_velocity]
    for _ in range(10):
        rig.system.cycle()
        vel.append(rig.slave.command_velocity)
    np.testing.assert_allclose(np.diff(vel), -SLAVE_DECEL * DT, atol=1e-9)
