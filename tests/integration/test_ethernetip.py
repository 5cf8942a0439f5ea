"""Native Logix tags over EtherNet/IP, with clients that are not ours (pylogix 1.1.6 and
pycomm3 1.2.16 from PyPI) against ``motion-server run`` on the demo map, manual clock.

What a Logix controller shows (Rockwell's MOTION_INSTRUCTION data type: FLAGS a DINT,
EN bit 31, DN 29, ER 28, PC 27, IP 26, AC 23) and what the other protocols show for the
same scan (time stands still between two steps of the manual clock, so a value read over
Modbus and over EtherNet/IP must be equal)."""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_server.testing import MotionServer

from .ethernetip_wire import Wire, symbolic

pylogix = pytest.importorskip("pylogix")
pycomm3 = pytest.importorskip("pycomm3")

DN, IP, EN, ER, PC, AC = 29, 26, 31, 28, 27, 23


@pytest.fixture(scope="module")
def srv(tmp_path_factory: pytest.TempPathFactory) -> Iterator[MotionServer]:
    server = MotionServer.start(tmp_path_factory.mktemp("enip"), opcua=False, ethernetip=True)
    try:
        yield server
    finally:
        server.finish()


@pytest.fixture
def plc(srv: MotionServer) -> Iterator[object]:
    with pylogix.PLC("127.0.0.1", port=srv.ethernetip_port) as c:
        yield c


@pytest.fixture
def drv(srv: MotionServer) -> Iterator[object]:
    with pycomm3.LogixDriver(f"127.0.0.1:{srv.ethernetip_port}") as c:
        yield c


def owners(srv: MotionServer) -> list[str]:
    out: list[str] = []
    for t in srv.map:
        owner = t.name.split(".")[0]
        if owner not in out:
            out.append(owner)
    return out


def test_the_ready_file_and_identity_name_the_ethernetip_port(srv: MotionServer) -> None:
    assert srv.ethernetip_port > 0
    with pylogix.PLC("127.0.0.1", port=srv.ethernetip_port) as c:
        dev = c.GetDeviceProperties().Value
        assert dev.Vendor == "Rockwell Automation/Allen-Bradley"
        assert dev.DeviceType == "Programmable Logic Controller"
        assert dev.Revision == "33.11"
    # any backplane slot is answered (as a 5580 reached through any route)
    with pylogix.PLC("127.0.0.1", slot=3, port=srv.ethernetip_port) as c:
        assert c.Read("Clock.Cycle").Status == "Success"


def test_pylogix_lists_every_owner_with_its_udt(srv: MotionServer, plc: object) -> None:
    r = plc.GetTagList()  # type: ignore[attr-defined]
    assert r.Status == "Success"
    names = [t.TagName for t in r.Value]
    assert names == owners(srv)  # one tag per owner of the map, in the map's order
    types = {t.TagName: t.DataType for t in r.Value}
    assert types["MAG_1"] == "MS_MAG" and types["MSO_1"] == "MS_MSO"
    assert types["Axis1"] == "MS_AXIS" and types["Clock"] == "MS_CLOCK"
    udt = plc.UDT[next(t.DataTypeValue for t in r.Value if t.TagName == "MAG_1")]  # type: ignore[attr-defined]
    fields = [f.TagName for f in udt.Fields]
    for name in ("FLAGS", "EN", "DN", "ER", "PC", "IP", "AC", "ERR", "EXERR", "Execute", "Ratio"):
        assert name in fields


def test_pycomm3_sees_the_motion_instruction_bits_as_aliases_of_flags(drv: object) -> None:
    tags = drv.tags  # type: ignore[attr-defined]
    mag = tags["MAG_1"]["data_type"]
    assert mag["name"] == "MS_MAG"
    internal = mag["internal_tags"]
    assert internal["FLAGS"]["data_type"] == "DINT" and internal["FLAGS"]["offset"] == 0
    # a BOOL member is (byte offset, bit in that byte) for pycomm3: bit n of the DINT at 0
    for name, bit in (("EN", EN), ("DN", DN), ("ER", ER), ("PC", PC), ("IP", IP), ("AC", AC)):
        assert (internal[name]["offset"], internal[name]["bit"]) == (bit // 8, bit % 8), name
    axis = tags["Axis2"]["data_type"]["internal_tags"]
    assert axis["ActualPosition"]["data_type"] == "LREAL"
    assert axis["MotionStatus"]["data_type"] == "UDINT"
    assert tags["Cam1"]["data_type"]["internal_tags"]["Master"]["array"] == 16


def test_trigger_mso_maj_mag_and_see_dn_ip(srv: MotionServer, drv: object) -> None:
    c = drv
    for axis in (1, 2):  # servo on: Axis1 (the master) and Axis2 (the slave)
        assert c.write(("MSO_1.Axis", axis), ("MSO_1.Execute", True))  # type: ignore[attr-defined]
        srv.step(2)
        assert c.read("MSO_1.DN").value is True  # type: ignore[attr-defined]
        assert c.write(("MSO_1.Execute", False))  # type: ignore[attr-defined]
        srv.step(1)
    # MAJ on the virtual Axis1 at 10 mm/s: a jog in process
    assert c.write(("MAJ_1.Axis", 1), ("MAJ_1.Speed", 10.0), ("MAJ_1.Execute", True))  # type: ignore[attr-defined]
    srv.step(5)
    maj = c.read("MAJ_1").value  # type: ignore[attr-defined]
    assert maj["DN"] is True and maj["IP"] is True, (maj["ERR"], maj["EXERR"], maj)
    # MAG: Axis2 follows Axis1 at ratio 1; DN and IP in the same scan (the MAG seed)
    assert c.write(("MAG_1.SlaveAxis", 2), ("MAG_1.MasterAxis", 1), ("MAG_1.Execute", True))  # type: ignore[attr-defined]
    srv.step(1)
    mag = c.read("MAG_1").value  # type: ignore[attr-defined]
    assert mag["DN"] is True and mag["IP"] is True and mag["ER"] is False
    flags = mag["FLAGS"]
    assert mag["DN"] == bool(flags >> DN & 1) and mag["IP"] == bool(flags >> IP & 1)
    assert mag["EN"] == bool(flags >> EN & 1)
    # Modbus shows the same word for the same scan
    assert srv.read("MAG_1.FLAGS") == flags & 0xFFFFFFFF
    srv.step(50)
    values = srv.read_many(["Axis1.ActualPosition", "Axis2.ActualPosition", "Clock.Cycle"])
    assert values["Axis1.ActualPosition"] > 0.0
    r = c.read("Axis1.ActualPosition", "Axis2.ActualPosition", "Clock.Cycle")  # type: ignore[attr-defined]
    assert [t.value for t in r] == [
        values["Axis1.ActualPosition"],
        values["Axis2.ActualPosition"],
        values["Clock.Cycle"],
    ]
    with pylogix.PLC("127.0.0.1", port=srv.ethernetip_port) as p:
        got = p.Read(["Axis2.ActualPosition", "MAG_1.DN", "MAG_1.FLAGS"])
        assert got[0].Value == values["Axis2.ActualPosition"]
        assert got[1].Value == bool(got[2].Value >> DN & 1)


def test_mag_dn_is_bit_29_of_flags_in_every_read(srv: MotionServer) -> None:
    """``MAG_1.DN`` is served from FLAGS itself: the two can never disagree, before,
    during and after a gear."""
    with pylogix.PLC("127.0.0.1", port=srv.ethernetip_port) as p:
        seen = set()
        for _ in range(6):
            r = p.Read(["MAG_1.DN", "MAG_1.FLAGS", "MAG_1.IP"])
            assert all(x.Status == "Success" for x in r)
            assert r[0].Value == bool(r[1].Value >> DN & 1)
            assert r[2].Value == bool(r[1].Value >> IP & 1)
            seen.add(r[0].Value)
            srv.step(3)


def test_members_arrays_and_whole_structures(srv: MotionServer, plc: object, drv: object) -> None:
    p, c = plc, drv
    modbus = srv.read_many([f"Cam1.Master[{i}]" for i in range(4)] + ["Axis2.MaxVelocity"])
    r = p.Read("Cam1.Master[0]", 4)  # type: ignore[attr-defined]
    assert r.Status == "Success"
    assert r.Value == [modbus[f"Cam1.Master[{i}]"] for i in range(4)]
    assert c.read("Cam1.Master{4}").value == r.Value  # type: ignore[attr-defined]
    assert p.Read("Cam1.Master[2]").Value == modbus["Cam1.Master[2]"]  # type: ignore[attr-defined]
    whole = c.read("Axis2").value  # type: ignore[attr-defined]
    assert whole["MaxVelocity"] == pytest.approx(modbus["Axis2.MaxVelocity"])
    # a whole-structure write: the operand changed, the status members written back alone
    mag = c.read("MAG_1").value  # type: ignore[attr-defined]
    mag["AccelRate"] = 250.0
    assert c.write(("MAG_1", mag))  # type: ignore[attr-defined]
    assert srv.read("MAG_1.AccelRate") == 250.0


def test_a_single_bit_write_is_a_read_modify_write(srv: MotionServer, drv: object) -> None:
    c = drv
    srv.write("MAJ_1.Direction", 0)
    assert c.write(("MAJ_1.Direction.1", True))  # type: ignore[attr-defined]
    assert srv.read("MAJ_1.Direction") == 2
    assert c.write(("MAJ_1.Direction.0", True))  # type: ignore[attr-defined]
    assert srv.read("MAJ_1.Direction") == 3
    assert c.write(("MAJ_1.Direction.1", False))  # type: ignore[attr-defined]
    assert srv.read("MAJ_1.Direction") == 1
    srv.write("MAJ_1.Direction", 0)


def test_refusals_answer_the_logix_general_status(srv: MotionServer) -> None:
    w = Wire(srv.ethernetip_port)
    try:
        # unknown tag, unknown member: 0x05 path destination unknown
        assert w.cip(0x4C, symbolic("Nope"), b"\x01\x00")[0] == 0x05
        assert w.cip(0x4C, symbolic("MAG_1", "Nope"), b"\x01\x00")[0] == 0x05
        # a path segment that is not one: 0x04
        assert w.cip(0x4C, b"\x91\x05MA", b"\x01\x00")[0] == 0x04
        # a service a tag does not have: 0x08
        assert w.cip(0x4B, symbolic("MAG_1", "Ratio"), b"\x01\x00")[0] == 0x08
        # a status member is read-only: 0x0F privilege violation
        one = struct.pack("<HHB", 0xC1, 1, 1)
        assert w.cip(0x4D, symbolic("MAG_1", "DN"), one)[0] == 0x0F
        flags = struct.pack("<HHi", 0xC4, 1, 5)
        assert w.cip(0x4D, symbolic("MAG_1", "FLAGS"), flags)[0] == 0x0F
        # the wrong type: 0xFF with Logix's extended status 0x2107
        dint = struct.pack("<HHi", 0xC4, 1, 5)
        assert w.cip(0x4D, symbolic("MAG_1", "Ratio"), dint)[:2] == (0xFF, (0x2107,))
        # beyond the end of an array: 0xFF / 0x2105
        assert w.cip(0x4C, symbolic("Cam1", "Master", 15), b"\x02\x00")[:2] == (0xFF, (0x2105,))
        # a value the judge refuses (a REAL that is not finite)
        nan = struct.pack("<HHf", 0xCA, 1, float("nan"))
        assert w.cip(0x4D, symbolic("MAG_1", "Ratio"), nan)[0] == 0x09
        # Read Tag Fragmented: a structure from an offset, the rest of its bytes
        status, _, whole = w.cip(0x4C, symbolic("Cam1"), b"\x01\x00")
        assert status == 0 and whole[:2] == b"\xa0\x02"
        status, _, part = w.cip(0x52, symbolic("Cam1"), struct.pack("<HI", 1, 100))
        assert status == 0 and part[4:] == whole[4 + 100 :]
        # Write Tag Fragmented: two elements of an array from byte 4 of the element span
        data = struct.pack("<HHI", 0xCA, 4, 8) + struct.pack("<ff", 11.0, 12.0)
        assert w.cip(0x53, symbolic("Cam1", "Slave", 0), data)[0] == 0
        # and a good one still works on the same connection
        two = struct.pack("<HHf", 0xCA, 1, 2.0)
        assert w.cip(0x4D, symbolic("MAG_1", "Ratio"), two)[0] == 0x00
        status, _, data = w.cip(0x4C, symbolic("MAG_1", "Ratio"), b"\x01\x00")
        assert status == 0 and struct.unpack("<Hf", data) == (0xCA, 2.0)
    finally:
        w.close()
    assert srv.read("MAG_1.Ratio") == 2.0
    assert (srv.read("Cam1.Slave[2]"), srv.read("Cam1.Slave[3]")) == (11.0, 12.0)


READ_ONLY_MAP = """
[audit]
enabled = true

[[ethernetip.access.rules]]
networks = ["127.0.0.0/8"]
write = ["MAG_1"]
"""


def test_the_site_map_decides_who_writes_and_refusals_are_audited(tmp_path: Path) -> None:
    demo = Path(__file__).parents[2] / "server" / "motion_server" / "data" / "demo.toml"
    lines = demo.read_text().splitlines()
    # the demo's operator role goes: read only (viewer) but for the rule's MAG_1
    text = "\n".join(ln for ln in lines if not ln.startswith('role = "operator"'))
    site = tmp_path / "site.toml"
    site.write_text(text + READ_ONLY_MAP)
    srv = MotionServer.start(tmp_path / "run", site, opcua=False, ethernetip=True)
    try:
        w = Wire(srv.ethernetip_port)
        try:
            real = struct.pack("<HHf", 0xCA, 1, 3.0)
            assert w.cip(0x4D, symbolic("MAG_1", "Ratio"), real)[0] == 0x00
            dint = struct.pack("<HHi", 0xC4, 1, 2)
            assert w.cip(0x4D, symbolic("MSO_1", "Axis"), dint)[0] == 0x0F
            assert (
                w.cip(0x4D, symbolic("Clock", "StepCycles"), struct.pack("<HHI", 0xC8, 1, 5))[0]
                == 0x0F
            )
        finally:
            w.close()
        assert srv.read("MAG_1.Ratio") == 3.0
        assert srv.read("MSO_1.Axis") != 2
        audit = "\n".join(p.read_text() for p in (tmp_path / "run").rglob("audit*.jsonl*"))
        assert '"protocol":"ethernetip"' in audit
        assert "may not write MSO_1.Axis" in audit
    finally:
        srv.finish()


def test_pylogix_reads_the_wall_clock(srv: MotionServer) -> None:
    """The Wall Clock object gives the host's UTC time (pylogix GetPLCTime)."""
    import datetime as dt

    with pylogix.PLC("127.0.0.1", port=srv.ethernetip_port) as p:
        before = dt.datetime.now(dt.UTC).replace(tzinfo=None)
        r = p.GetPLCTime()
        after = dt.datetime.now(dt.UTC).replace(tzinfo=None)
        assert r.Status == "Success"
        assert before - dt.timedelta(seconds=1) <= r.Value <= after + dt.timedelta(seconds=1)
        assert p.SetPLCTime().Status == "Privilege violation"


def test_a_command_the_scan_refuses_fails_the_request(tmp_path: Path) -> None:
    """An admin's Clock.SnapshotRestore of a snapshot that does not exist: the write was
    judged and queued, the scan's command failed, and the request answers 0x10 (device
    state conflict) as Modbus answers exception 04."""
    demo = Path(__file__).parents[2] / "server" / "motion_server" / "data" / "demo.toml"
    text = demo.read_text().replace('role = "operator"   #', 'role = "admin"   #')
    site = tmp_path / "site.toml"
    site.write_text(text)
    srv = MotionServer.start(tmp_path / "run", site, opcua=False, ethernetip=True)
    try:
        w = Wire(srv.ethernetip_port)
        try:
            number = struct.pack("<HHI", 0xC8, 1, 42)
            assert w.cip(0x4D, symbolic("Clock", "Snapshot"), number)[0] == 0x00
            restore = struct.pack("<HHB", 0xC1, 1, 1)
            assert w.cip(0x4D, symbolic("Clock", "SnapshotRestore"), restore)[0] == 0x10
            # the connection goes on
            assert w.cip(0x4C, symbolic("Clock", "Cycle"), b"\x01\x00")[0] == 0
        finally:
            w.close()
        assert "no such snapshot" in srv.log()
    finally:
        srv.finish()


def test_ethernetip_modbus_and_opcua_show_the_same_scan(tmp_path: Path) -> None:
    """Between two steps of the manual clock time stands still: a jogging master and its
    geared slave read over EtherNet/IP (pycomm3), Modbus and OPC UA (asyncua) give the
    same positions, the same cycle and the same FLAGS word, bit for bit."""
    import asyncio

    from asyncua import Client, ua

    names = {
        "Axis1.ActualPosition": "Axes.Axis1.ActualPosition",
        "Axis2.ActualPosition": "Axes.Axis2.ActualPosition",
        "Axis1.ActualVelocity": "Axes.Axis1.ActualVelocity",
        "Clock.Cycle": "Clock.Cycle",
        "MAG_1.FLAGS": "Instructions.MAG_1.FLAGS",
        "MAJ_1.IP": "Instructions.MAJ_1.IP",
    }

    async def over_opcua(endpoint: str) -> dict[str, object]:
        async with Client(endpoint, timeout=10) as c:
            ns = await c.get_namespace_index("urn:motion-server:demo")
            nodes = [c.get_node(ua.NodeId(node, ns)) for node in names.values()]
            values = await c.read_values(nodes)
        return dict(zip(names, values, strict=True))

    server = MotionServer.start(tmp_path, ethernetip=True)
    try:
        with pycomm3.LogixDriver(f"127.0.0.1:{server.ethernetip_port}") as c:
            for axis in (1, 2):
                assert c.write(("MSO_1.Axis", axis), ("MSO_1.Execute", True))
                server.step(2)
                assert c.write(("MSO_1.Execute", False))
                server.step(1)
            assert c.write(("MAJ_1.Axis", 1), ("MAJ_1.Speed", 25.0), ("MAJ_1.Execute", True))
            assert c.write(("MAG_1.SlaveAxis", 2), ("MAG_1.MasterAxis", 1), ("MAG_1.Execute", True))
            for cycles in (1, 7, 40):
                server.step(cycles)
                modbus = server.read_many(list(names))
                enip = {t.tag: t.value for t in c.read(*names)}
                opcua = asyncio.run(over_opcua(server.opcua_endpoint))
                assert modbus["Axis1.ActualPosition"] > 0.0 and modbus["MAJ_1.IP"]
                for name in names:
                    expected = modbus[name]
                    if name == "MAG_1.FLAGS":  # a DINT over CIP, a UDINT word elsewhere
                        assert enip[name] & 0xFFFFFFFF == expected, name
                        assert opcua[name] & 0xFFFFFFFF == expected, name
                    else:
                        assert enip[name] == expected, name
                        assert opcua[name] == expected, name
    finally:
        server.finish()
