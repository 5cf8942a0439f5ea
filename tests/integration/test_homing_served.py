"""MAH, MRP and MC_ReadActualPosition over Modbus TCP against ``motion-server run`` (the
pytest plugin's server, manual clock), on the demo map's Axis2.

Axis2 (data/demo.toml) homes actively, bidirectional forward, switch then marker: forward
at 20 mm/s to the home switch (a cam on [50, 55] mm of the raw feedback), back off it at
5 mm/s until it clears at 50 mm, on at 5 mm/s to the next marker going down (markers
every 10 mm from 2.5 mm: 42.5 mm), which reads home_position - home_offset = 0; then
back to the home position 0. Everything after is checked in the redefined coordinates,
where the cam now lies on [50 - 42.5, 55 - 42.5] = [7.5, 12.5] mm.
"""

from __future__ import annotations

import pytest

from motion_server.kernel import MotionStatusBit, PLCopenState
from motion_server.testing import MotionServer

HOMING = 1 << MotionStatusBit.HOMING
HOMED = 1 << MotionStatusBit.HOMED


def move_to(srv: MotionServer, position: float) -> None:
    out = srv.trigger(
        "MAM_1", Axis=2, MoveType=0, Position=position, Speed=50.0, AccelRate=1000.0,
        DecelRate=1000.0, until=("PC",), timeout=5.0,
    )  # fmt: skip
    assert out.ok, out


@pytest.mark.motion_server(site_map=None, opcua=False)
def test_mah_homes_axis2_to_its_marker_over_modbus(motion_server: MotionServer) -> None:
    srv = motion_server
    assert srv.trigger("MSO_1", Axis=2).ok
    assert srv.read("Axis2.MotionStatus") & HOMED == 0
    out = srv.trigger("MAH_1", Axis=2)
    assert out.ok and out.flag == "DN", out
    # 1 s into the seek: 20 mm at most, short of the switch, in the Homing state
    srv.run_for(1.0)
    assert srv.read("Axis2.PLCopenState") == PLCopenState.HOMING
    status = srv.read("Axis2.MotionStatus")
    assert status & HOMING and not status & HOMED
    assert srv.read("MAH_1.IP") is True and srv.read("MAH_1.PC") is False
    assert srv.read("Axis2.HomeSwitch") is False
    # seek 50 mm at 20 mm/s (2.5 s), back off 7.5 mm at 5 mm/s (1.5 s), a short return:
    # 5 s of simulated time is ample
    srv.run_for(4.0)
    assert srv.read("MAH_1.PC") is True and srv.read("MAH_1.IP") is False
    assert srv.read("Axis2.PLCopenState") == PLCopenState.STANDSTILL
    status = srv.read("Axis2.MotionStatus")
    assert status & HOMED and not status & HOMING
    assert srv.read("Axis2.CommandPosition") == pytest.approx(0.0, abs=1e-9)
    assert srv.read("Axis2.ActualPosition") == pytest.approx(0.0, abs=1e-3)
    # the cam stayed where it is on the machine: [7.5, 12.5] mm in the new coordinates
    move_to(srv, 7.0)
    srv.run_for(0.5)
    assert srv.read("Axis2.HomeSwitch") is False
    move_to(srv, 8.0)
    srv.run_for(0.5)
    assert srv.read("Axis2.HomeSwitch") is True

    # MRP: the actual position becomes 100 mm, nothing moves, the switch moves with it
    out = srv.trigger("MRP_1", Axis=2, Type=0, PositionSelect=0, Position=100.0)
    assert out.ok and out.flag == "DN", out
    assert srv.read("Axis2.ActualPosition") == pytest.approx(100.0, abs=1e-9)
    assert srv.read("Axis2.CommandPosition") == pytest.approx(100.0, abs=1e-3)
    assert srv.read("Axis2.HomeSwitch") is True
    move_to(srv, 99.0)  # raw 8 - 1 + 42.5 = 49.5 mm: off the cam's low edge at 50
    srv.run_for(0.5)
    assert srv.read("Axis2.HomeSwitch") is False
    assert srv.read("Axis2.MotionStatus") & HOMED  # MRP leaves Homed as it is
    # MC_ReadActualPosition over the same connection: the trigger handshake waits for
    # Valid and leaves Enable high; the block reads every cycle until Enable falls
    out = srv.trigger("MC_ReadActualPosition_1", Axis=2)
    assert out.ok and out.flag == "Valid", out
    assert srv.read("MC_ReadActualPosition_1.Position") == srv.read("Axis2.ActualPosition")
    move_to(srv, 98.0)
    srv.run_for(0.5)
    assert srv.read("MC_ReadActualPosition_1.Position") == pytest.approx(98.0, abs=1e-3)
    srv.write("MC_ReadActualPosition_1.Enable", False)
    srv.step(1)
    assert srv.read("MC_ReadActualPosition_1.Valid") is False
    assert srv.read("MC_ReadActualPosition_1.Busy") is False
    move_to(srv, 99.0)
    assert srv.read("MC_ReadActualPosition_1.Position") == pytest.approx(98.0, abs=1e-3)
