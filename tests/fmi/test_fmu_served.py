"""An FMU whose front-ends serve the controller while the master steps it: an HMI reads
the co-simulation's positions over Modbus and writes an operand the FMU's controller
uses; the clock stays the master's (``remote_clock = false``, required)."""

from __future__ import annotations

import asyncio
import json
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from motion_server.config import SiteMap
from motion_server.fmi.build import FmuBuildError, build_fmu
from motion_server.fmi.engine import CoSimController, site_for_fmu
from motion_server.fmi.serving import ServeError
from motion_server.tagmap import build_tagmap, export

PERIOD = 0.002  # the demo's
DEMO = resources.files("motion_server").joinpath("data", "demo.toml").read_text("utf-8")


def demo_site(remote_clock: bool) -> SiteMap:
    site = site_for_fmu(DEMO, "demo.toml")
    return site.model_copy(
        update={
            "controller": site.controller.model_copy(update={"remote_clock": remote_clock}),
            "modbus": site.modbus.model_copy(update={"port": 0}),
            "opcua": site.opcua.model_copy(update={"enabled": False}),
        }
    )


@pytest.fixture
def served() -> Any:
    ctl = CoSimController(demo_site(remote_clock=False), serve=True)
    yield ctl
    ctl.close()


def test_an_hmi_watches_and_operates_a_co_simulation(served: CoSimController) -> None:
    from pyModbusTCP.client import ModbusClient

    from motion_clients import ClientMap, MotionClient

    ctl = served
    assert ctl.served is None  # nothing listens before the first step
    for name, value in {"MC_Power_1.Axis": 1, "MAJ_1.Axis": 1, "MAJ_1.Speed": 100.0}.items():
        ctl.set(ctl.by_name[name], value)
    ctl.do_step(PERIOD)
    assert ctl.served is not None and ctl.served.modbus_port
    port = ctl.served.modbus_port
    ctl.set(ctl.by_name["MC_Power_1.Enable"], True)
    ctl.do_step(PERIOD)
    ctl.set(ctl.by_name["MAJ_1.Execute"], True)
    ctl.do_step(50 * PERIOD)
    # the map ``motion-server map`` exports for this site map
    cmap = ClientMap(json.loads(export(build_tagmap(ctl.site), "json")))

    async def hmi() -> dict[str, Any]:
        async with MotionClient.connect(cmap, "modbus", "127.0.0.1", port) as mc:
            seen = await mc.read_many(["Clock.Cycle", "Axis1.CommandPosition"])
            # an operand written by the HMI reaches the controller the FMU steps
            await mc.write("MAJ_1.Speed", 50.0)
            return seen

    seen = asyncio.run(hmi())
    assert seen["Clock.Cycle"] == 52
    assert seen["Axis1.CommandPosition"] == ctl.get(ctl.by_name["Axis1.CommandPosition"])
    assert seen["Axis1.CommandPosition"] > 0.0
    # a raw write of the register that holds Clock.Step: the server answers an exception
    step = ctl.view.map.tag("Clock.Step")
    raw = ModbusClient(host="127.0.0.1", port=port, unit_id=cmap.unit_id, timeout=5.0)
    assert raw.write_single_register(step.address, 1 << (step.bit or 0)) is False
    assert raw.last_except != 0
    raw.close()
    ctl.do_step(PERIOD)
    assert ctl.get(ctl.by_name["Clock.Cycle"]) == 53  # no cycle ran but the master's
    slot = ctl.variables[ctl.by_name["MAJ_1.Speed"]].slot
    assert ctl.view.values()[slot] == 50.0


def test_serving_needs_a_clock_no_client_can_step(tmp_path: Path) -> None:
    ctl = CoSimController(demo_site(remote_clock=True), serve=True)
    with pytest.raises(ServeError, match="remote_clock = false"):
        ctl.do_step(PERIOD)
    ctl.close()
    with pytest.raises(FmuBuildError, match="remote_clock = false"):
        build_fmu(None, tmp_path / "served.fmu", 2, serve=True)  # the demo lets clients
