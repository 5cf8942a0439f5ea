"""The pytest plugin's test-bench helpers (``motion_server.testing.MotionServer``): inject
an axis fault and remove it, save and restore a snapshot, set a communication fault; on
the demo map, through the ``motion_server`` fixture as an HMI team's test uses them.
"""

from __future__ import annotations

import time

import pytest

from motion_server.kernel import AxisFault
from motion_server.testing import MotionServer


@pytest.mark.motion_server(site_map=None, opcua=False)
def test_a_fault_a_snapshot_and_a_communication_fault(motion_server: MotionServer) -> None:
    ms = motion_server
    assert ms.trigger("MSO_1", Axis=2).ok
    ms.step(5)
    before = ms.read("Clock.Cycle")
    ms.snapshot_save(1)
    # a drive fault: Disable Drive, Logix ServoFaultBits bit 9, AxisErrorID 1 + 9
    ms.inject("Axis2", "DriveFault")
    ms.step(1)
    seen = ms.read_many(["Axis2.AxisFault", "Axis2.ServoFault", "Axis2.AxisErrorID"])
    assert seen == {
        "Axis2.AxisFault": AxisFault.DRIVE,
        "Axis2.ServoFault": 1 << 9,
        "Axis2.AxisErrorID": 10,
    }
    # MAFR while the cause is held: done, and the fault is back at once
    assert ms.trigger("MAFR_1", Axis=2).ok
    assert ms.read("Axis2.AxisFault") == AxisFault.DRIVE
    ms.inject("Axis2", "DriveFault", held=False)
    ms.step(1)  # MAFR_1 sees its Execute low (each helper is a client of its own)
    assert ms.read("Axis2.AxisFault") == AxisFault.DRIVE  # latched until the reset
    assert ms.trigger("MAFR_1", Axis=2).ok
    assert ms.read("Axis2.AxisFault") == 0
    # the fault again, then the snapshot taken before it: as it was then
    ms.inject("Axis2", "DriveFault")
    ms.step(3)
    ms.snapshot_restore(1)
    assert ms.read_many(["Clock.Cycle", "Axis2.AxisFault", "Axis2.InjectDriveFault"]) == {
        "Clock.Cycle": before,
        "Axis2.AxisFault": 0,
        "Axis2.InjectDriveFault": False,
    }
    # every answer 0.4 s late for 30 s, then off
    ms.comm_fault("delay", delay_ms=400, duration_s=30.0)
    t0 = time.monotonic()
    assert ms.read("Clock.CommFault") == 1
    assert time.monotonic() - t0 >= 0.4
    ms.comm_fault("off")
    assert ms.read("Clock.CommFault") == 0
