"""`motion-server run` end to end: serves Modbus on the demo map, stops cleanly on SIGINT."""

from __future__ import annotations

import re
import signal
import subprocess
import sys

from pyModbusTCP.client import ModbusClient

from motion_server import config
from motion_server.tagmap import TagType, build_tagmap, decode


def test_run_serves_modbus_and_stops_on_sigint() -> None:
    tagmap = build_tagmap(config.load())
    cmd = [
        sys.executable,
        "-m",
        "motion_server.cli",
        "run",
        "--clock",
        "manual",
        "--modbus-port",
        "0",
        "--no-opcua",
    ]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        port = 0
        seen: list[str] = []
        for line in proc.stderr:
            seen.append(line)
            m = re.search(r"Modbus TCP on 127\.0\.0\.1:(\d+)", line)
            if m:
                port = int(m.group(1))
                break
        assert port, "".join(seen)
        client = ModbusClient(host="127.0.0.1", port=port, unit_id=1, timeout=5.0)
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
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "programmed stop complete" in err
