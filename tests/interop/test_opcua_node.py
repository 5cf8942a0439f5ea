"""Interop: node-opcua (a JavaScript OPC UA stack, installed by `make test` with `npm ci`
in tests/interop/node_opcua) drives the server over Basic256Sha256 SignAndEncrypt with
user names. The client lets its own certificate manager create its certificate in a
temporary folder and accept the server's self-signed one.

The same jog as the Modbus interop tests, from first principles: MAJ at 10 mm/s with
100 mm/s² reaches speed after 10/100 = 0.1 s = 50 cycles of 2 ms, having covered
½·100·0.1² = 0.5 mm; 50 more cycles at 10 mm/s add 1.0 mm: 1.5 mm after 100 cycles.
The client ran 2 cycles for MSO (one with the rung false, one with the edge) and 101 for
MAJ (rung false, edge, 99 more): Clock.Cycle advances by 103.
"""

from __future__ import annotations

import asyncio
import json
import shutil
from pathlib import Path

import pytest

from motion_server import config
from motion_server.tagmap import build_tagmap, companion
from motion_server.tagmap import export as export_map
from tests.opcua_support import USERS, opcua_site, running, user_hashes

NODE_PROJECT = Path(__file__).resolve().parent / "node_opcua"
EXAMPLES_MAP = Path(__file__).resolve().parents[2] / "clients" / "examples" / "bench.toml"
NODE = shutil.which("node")

pytestmark = pytest.mark.skipif(
    NODE is None or not (NODE_PROJECT / "node_modules" / "node-opcua-client").is_dir(),
    reason="node or tests/interop/node_opcua/node_modules missing (make test runs npm ci)",
)


async def run_client(site: config.SiteMap, pki: Path) -> dict:
    async with running(site) as rt:
        assert rt.opcua is not None
        args = {
            "endpoint": rt.opcua.endpoint,
            "namespaceUri": site.site.namespace_uri,
            "pki": str(pki),
            "admin": ["admin", USERS["admin"][1]],
            "viewer": ["viewer", USERS["viewer"][1]],
        }
        assert NODE is not None
        proc = await asyncio.create_subprocess_exec(
            NODE,
            str(NODE_PROJECT / "client.js"),
            json.dumps(args),
            cwd=NODE_PROJECT,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
        )
        try:
            out, err = await asyncio.wait_for(proc.communicate(), 120.0)
        except TimeoutError:
            proc.kill()
            await proc.wait()
            raise
    text = out.decode(errors="replace")
    assert proc.returncode == 0, f"node client failed:\n{text[-3000:]}\n{err.decode()[-3000:]}"
    lines = [ln for ln in text.splitlines() if ln.startswith("RESULT ")]
    assert len(lines) == 1, text[-3000:]
    result: dict = json.loads(lines[0].removeprefix("RESULT "))
    result["log"] = text + err.decode(errors="replace")
    return result


async def test_node_opcua_jogs_an_axis_over_the_secure_endpoint(tmp_path: Path) -> None:
    # lockout 0: the deliberately wrong password must not lock out the test's address
    site = opcua_site(tmp_path / "server", user_hashes(), lockout=0.0)
    r = await run_client(site, tmp_path / "node-pki")

    assert r["securityPolicy"].endswith("#Basic256Sha256")
    assert r["securityMode"] == "SignAndEncrypt"
    # the client certificate was made by node-opcua's own certificate manager
    assert list((tmp_path / "node-pki").rglob("*.pem"))

    assert (r["msoDN"], r["msoER"]) == (True, False)
    assert (r["majDN"], r["majIP"]) == (True, True)  # MAJ: DN and IP in the first scan
    assert r["position"] == pytest.approx(1.5, abs=1e-9)
    assert r["velocity"] == pytest.approx(10.0, abs=1e-9)
    assert r["cycleAfter"] - r["cycleBefore"] == 103
    assert r["seenIP"][0] is False and True in r["seenIP"]  # by subscription

    # the server judges node-opcua's writes item by item, as asyncua's
    assert r["wrongType"] == "BadTypeMismatch"  # REAL is Float, not Double
    assert r["output"] == "BadNotWritable"
    assert r["speedAfterRefused"] == pytest.approx(10.0)
    assert r["viewerReads"] is True
    assert r["viewerWrite"] == "BadUserAccessDenied"
    assert r["wrongPassword"] == "refused"
    # the negotiated transport limits are consistent: node-opcua warns when the chunks
    # cannot carry the largest message
    assert "maxChunkCount is not big enough" not in r["log"]


async def load_nodeset(tmp: Path, site_map: Path | None, instance: str, analog: str) -> dict:
    """Run load_nodeset.js on the NodeSet2 export of ``site_map`` (None: the demo)."""
    site = config.load(site_map, environ={})
    export = tmp / "site.NodeSet2.xml"
    export.write_text(export_map(build_tagmap(site), "nodeset"), "utf-8")
    files = {}
    for key, uri in (("di", companion.DI_URI), ("plcopen", companion.PLCOPEN_URI)):
        files[key] = tmp / f"{key}.NodeSet2.xml"
        files[key].write_text(companion.nodeset_text(uri), "utf-8")
    args = {
        "di": str(files["di"]),
        "plcopen": str(files["plcopen"]),
        "site": str(export),
        "namespaceUri": site.site.namespace_uri,
        "instance": instance,
        "analog": analog,
    }
    assert NODE is not None
    proc = await asyncio.create_subprocess_exec(
        NODE,
        str(NODE_PROJECT / "load_nodeset.js"),
        json.dumps(args),
        cwd=NODE_PROJECT,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    out, err = await asyncio.wait_for(proc.communicate(), 120.0)
    text = out.decode(errors="replace")
    assert proc.returncode == 0, f"{text[-3000:]}\n{err.decode()[-3000:]}"
    lines = [ln for ln in text.splitlines() if ln.startswith("RESULT ")]
    assert len(lines) == 1, text[-3000:]
    result: dict = json.loads(lines[0].removeprefix("RESULT "))
    return result


PLCOPEN = "http://PLCopen.org/OpcUa/IEC61131-3/"
DI = "http://opcfoundation.org/UA/DI/"


@pytest.mark.parametrize(
    ("site_map", "instance", "analog", "units", "unit_id", "span"),
    [
        # the demo's MAJ_1 jogs Axis1 (500 mm/s): C16 mm/s, UnitId 4403510 (UNECE_to_OPCUA.csv)
        (None, "Instructions.MAG_1", "Instructions.MAJ_1.Speed", "mm/s", 4403510, [0, 500]),
        # the examples' bench: RotSlave is a 360° rotary axis: DD °, UnitId 17476
        (EXAMPLES_MAP, "Axes.RotSlave", "Axes.RotSlave.ActualPosition", "°", 17476, [0, 360]),
    ],
)
async def test_node_opcua_loads_the_nodeset_export_with_the_nodesets_it_requires(
    tmp_path: Path,
    site_map: Path | None,
    instance: str,
    analog: str,
    units: str,
    unit_id: int,
    span: list[float],
) -> None:
    r = await load_nodeset(tmp_path, site_map, instance, analog)
    assert r["namespaces"][1:3] == [DI, PLCOPEN]
    assert r["requiredModels"] == ["http://opcfoundation.org/UA/", DI, PLCOPEN]
    assert (r["units"], r["unitId"], r["range"]) == (units, unit_id, span)
    if instance.startswith("Instructions."):
        assert r["typeChain"][:4] == [
            ["urn:motion-server:demo", "MAG_Type"],
            [PLCOPEN, "CtrlFunctionBlockType"],
            [PLCOPEN, "CtrlProgramOrganizationUnitType"],
            [DI, "BlockType"],
        ]
        # MAG: the trigger and the seed's operands in; the MOTION_INSTRUCTION word out
        assert "Execute" in r["inputs"] and "Ratio" in r["inputs"]
        assert r["outputs"] == sorted(["FLAGS", "EN", "DN", "ER", "PC", "IP", "AC", "ERR", "EXERR"])
        assert r["declaredInputs"] == r["inputs"]
        assert r["initialValue"] == 10.0  # MAJ Speed's default operand value
    else:
        assert r["typeChain"][0][1] == "MotionAxisType"
