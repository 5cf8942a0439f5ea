"""The plugin's fast path (``motion_server_reuse = module``): one server for the tests of a
module, each test given the controller as it was at start-up, bit for bit.

A project of three tests is run with pytest in a subprocess: the first drives a script
(enable, jog with an S-curve, a gear, an injected fault, the clock switched) and writes
its trace; the second finds a fresh controller on the same server (same pid, the start-up
cycle, nothing moving, no fault, the clock manual again) and runs the same script: the
same trace, value by value; the third has a ``motion_server`` marker of its own and gets
a server of its own.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

PROJECT_INI = """\
[pytest]
motion_server_reuse = module
"""

PROJECT_TESTS = """\
import json
from pathlib import Path

import pytest

TRACE = ["Axis1.ActualPosition", "Axis1.CommandVelocity", "Axis2.ActualPosition",
         "Axis2.AxisFault", "MAG_1.IP", "MAJ_1.IP", "Clock.Cycle"]
OUT = Path(__file__).parent / "out"


def script(ms):
    start = ms.read_many(["Clock.Cycle", "Clock.Mode", "Axis1.ActualPosition",
                          "Axis2.AxisFault", "MAJ_1.IP", "MAG_1.IP"])
    for axis in (1, 2):
        assert ms.trigger("MSO_1", Axis=axis).ok
        ms.step(2)
    assert ms.read("Axis2.AxisState") == 2  # servo control
    assert ms.trigger("MAJ_1", Axis=1, Speed=100.0, AccelRate=1000.0, DecelRate=1000.0,
                      Profile=1, AccelJerk=100.0, DecelJerk=100.0, JerkUnits=2).ok
    assert ms.trigger("MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5, Clutch=0,
                      AccelRate=1000.0).ok
    rows = []
    for n in range(60):
        if n == 40:
            ms.inject("Axis2", "PosSoftOvertravel")
        ms.step(5)
        rows.append(ms.read_many(TRACE))
    ms.write("Clock.StepCycles", 7)
    ms.comm_fault("delay", delay_ms=1, client_port=1)
    return start, rows


def test_first(motion_server):
    start, rows = script(motion_server)
    OUT.mkdir(exist_ok=True)
    (OUT / "first.json").write_text(json.dumps(
        {"pid": motion_server.pid, "start": start, "rows": rows}))


def test_second_finds_a_fresh_controller(motion_server):
    first = json.loads((OUT / "first.json").read_text())
    assert motion_server.pid == first["pid"]
    assert motion_server.read("Clock.StepCycles") == 1
    start, rows = script(motion_server)
    assert start == first["start"]
    assert start["Axis1.ActualPosition"] == 0.0 and start["MAJ_1.IP"] is False
    assert rows == first["rows"]


@pytest.mark.motion_server(opcua=False)
def test_a_marker_gets_a_server_of_its_own(motion_server):
    first = json.loads((OUT / "first.json").read_text())
    assert motion_server.pid != first["pid"]
"""


@pytest.mark.slow
def test_one_server_per_module_a_fresh_controller_per_test(tmp_path: Path) -> None:
    (tmp_path / "pytest.ini").write_text(PROJECT_INI)
    (tmp_path / "test_panel.py").write_text(PROJECT_TESTS)
    env = dict(os.environ)
    env.pop("PYTEST_ADDOPTS", None)
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert "3 passed" in run.stdout
