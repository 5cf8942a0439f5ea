"""MGS while a MAG and a MAJ are superimposed on the same slave (issue 4, after gearing).

Master Axis1 jogs at 50 mm/s; slave Axis2 is geared to it at ratio 0.5 (command reference,
no clutch) and jogs at 20 mm/s on top: its command velocity is 0.5·50 + 20 = 45 mm/s. The
MGS disengages the gear (GearingStatus and GearingLockStatus cleared), ends the jog, and
each axis ramps to rest at its own maximum deceleration from its own velocity: master
50 / (1000·0.002) = 25 cycles, slave 45 / (900·0.002) = 25 cycles, trapezoidal.
"""

from __future__ import annotations

import numpy as np

from motion_server.kernel import AxisConfig, AxisState, AxisType, MotionStatusBit

from ..support import make_system, trigger
from .test_group_stop_status import CLEARED, bit, logix

DT = 0.002


def axis(number: int, kind: AxisType, decel: float) -> AxisConfig:
    return AxisConfig(number, f"Axis{number}", kind, max_velocity=200.0,
                      max_acceleration=1000.0, max_deceleration=decel)  # fmt: skip


def test_mgs_while_a_mag_and_a_maj_are_active_on_the_same_slave() -> None:
    system = make_system(axis(1, AxisType.VIRTUAL, 1000.0), axis(2, AxisType.SERVO, 900.0))
    for n in (1, 2):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
    master_jog = logix(system.add("MAJ", "MAJ_M", {"Axis": 1, "Speed": 50.0,
                                                  "AccelRate": 1000.0}))  # fmt: skip
    trigger(system, master_jog)
    system.cycle(50)  # the master is at 50 mm/s after 25 cycles
    mag = logix(system.add("MAG", "MAG_1", {"SlaveAxis": 2, "MasterAxis": 1, "Ratio": 0.5,
                                            "MasterReference": 1, "Clutch": 1}))  # fmt: skip
    trigger(system, mag)
    assert mag.bit("DN") and mag.bit("IP")
    slave_jog = logix(system.add("MAJ", "MAJ_S", {"Axis": 2, "Speed": 20.0,
                                                 "AccelRate": 1000.0}))  # fmt: skip
    trigger(system, slave_jog)
    system.cycle(20)
    master, slave = system.ctl.axis(1), system.ctl.axis(2)
    assert master.command_velocity == 50.0
    assert abs(slave.command_velocity - 45.0) < 1e-9
    word = slave.motion_status
    assert bit(word, MotionStatusBit.GEARING) and bit(word, MotionStatusBit.GEARING_LOCK)
    assert bit(word, MotionStatusBit.JOG)

    mgs = logix(system.add("MGS", "MGS_1", {"Group": 1, "StopMode": 1}))  # fast stop
    trigger(system, mgs)
    # every instruction on the stopped axes loses IP
    assert not mag.bit("IP") and not slave_jog.bit("IP") and not master_jog.bit("IP")
    word = slave.motion_status
    assert bit(word, MotionStatusBit.STOPPING)
    assert not any(bit(word, b) for b in CLEARED)
    vm, vs = [master.command_velocity], [slave.command_velocity]
    for _ in range(29):
        system.cycle()
        vm.append(master.command_velocity)
        vs.append(slave.command_velocity)
    k = np.arange(1, 31)
    np.testing.assert_allclose(vm, np.maximum(50.0 - 1000.0 * DT * k, 0.0), atol=1e-9)
    np.testing.assert_allclose(vs, np.maximum(45.0 - 900.0 * DT * k, 0.0), atol=1e-9)
    assert mgs.bit("PC") and not mgs.bit("IP")
    assert (
        slave.state == AxisState.SERVO_CONTROL
        and slave.motion_status & (1 << MotionStatusBit.GEARING) == 0
    )
