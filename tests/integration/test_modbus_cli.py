"""`motion-server run` end to end: serves Modbus on the demo map, stops cleanly on SIGINT
(the server started by the pytest plugin's ``motion_server`` fixture, as a user's test
would start it; the registers read with a client that is not ours)."""

from __future__ import annotations

import signal

import pytest
from pyModbusTCP.client import ModbusClient

from motion_server import config
from motion_server.tagmap import TagType, build_tagmap, decode
from motion_server.testing import MotionServer


@pytest.mark.motion_server(opcua=False)
def test_run_serves_modbus_and_stops_on_sigint(motion_server: MotionServer) -> None:
    tagmap = build_tagmap(config.load())
    assert motion_server.site_map is None  # the embedded demo map
    assert motion_server.modbus_port > 0 and motion_server.opcua_endpoint == ""
    client = ModbusClient(host="127.0.0.1", port=motion_server.modbus_port, unit_id=1, timeout=5)
    mode = tagmap.tag("Clock.Mode")
    assert client.read_holding_registers(mode.address, 1) == [1]  # manual
    steps = tagmap.tag("Clock.StepCycles")
    assert client.write_multiple_registers(steps.address, [0, 7])
    step = tagmap.tag("Clock.Step")
    assert client.write_single_register(step.address, 1)  # answered once they ran
    cycle = tagmap.tag("Clock.Cycle")
    regs = client.read_holding_registers(cycle.address, 2)
    assert regs is not None and decode(TagType.UDINT, regs) == 7
    client.close()
    assert motion_server.stop(timeout=20, sig=signal.SIGINT) == 0, motion_server.log_tail()
    log = motion_server.log()
    assert "programmed stop complete" in log
    assert not motion_server.ready_file.exists()  # removed when the server stopped


def test_the_plugin_steps_reads_and_triggers_by_tag_name(motion_server: MotionServer) -> None:
    """The synchronous helpers on the demo map (OPC UA served as the map says: the first
    start created the admin, whose password the fixture reads)."""
    assert motion_server.opcua_endpoint.startswith("opc.tcp://")
    password = motion_server.opcua_admin_password
    assert password is not None and len(password) == 24
    assert motion_server.read("Clock.Cycle") == 0
    motion_server.step(10)
    assert motion_server.read("Clock.Cycle") == 10
    out = motion_server.trigger("MSO_1", Axis=2)
    assert out.ok and out.flag == "DN", out
    assert motion_server.read("Axis2.AxisState") == 2  # servo control
