"""The OPC UA information model as a SCADA engineer browses it (asyncua's client, the
demo site): typed instances, the PLCopen function-block references, engineering units,
ranges from the axis limits, the server's identity, and a certificate that outlives a
change of site map.

Numbers: the demo site map (server/motion_server/data/demo.toml): Axis1 virtual, 500 mm/s,
5000 mm/s²; Axis2 1000 mm/s, 20000 mm/s², following-error limit 10 mm; Axis3 rotary
(360° rollover), 3600 °/s. UNECE codes and UnitIds: the OPC Foundation's
UNECE_to_OPCUA.csv (MMT 5066068 mm, C16 4403510 mm/s, M41 5059633 mm/s², DD 17476 °,
E96 4536630 °/s, M45 5059637 °/s², SEC 5457219 s, C26 4403766 ms, B98 4340024 µs,
C62 4404786 "one"). Node ids of OPC 30000 (PLCopen 1.02): CtrlFunctionBlockType i=1005,
CtrlProgramOrganizationUnitType i=1003, HasInputVar i=4001, HasOutputVar i=4002.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import pytest
from asyncua import Client, ua
from cryptography import x509

import motion_server
from motion_server import config
from motion_server.identity import MANUFACTURER_NAME, PRODUCT_URI
from motion_server.runtime import Runtime
from motion_server.tagmap import Folder, TagMap, build_tagmap
from motion_server.tagmap.nodeset import is_analog
from tests.opcua_support import running

PLCOPEN = "http://PLCopen.org/OpcUa/IEC61131-3/"
DI = "http://opcfoundation.org/UA/DI/"
UNIT_IDS = {
    "mm": 5066068,
    "mm/s": 4403510,
    "mm/s²": 5059633,
    "deg": 17476,
    "deg/s": 4536630,
    "deg/s²": 5059637,
    "s": 5457219,
    "ms": 4403766,
    "us": 4340024,
    "": 4404786,  # gear ratios: C62, "one"
    "%": 0x5031,  # Diagnostics.ScanLoad: P1, percent ("P" << 8 | "1")
}
#: units without a UNECE common code: UnitId -1 (OPC 10000-8)
NO_CODE = {"mm/s³", "deg/s³"}


def demo_site(data_dir: Path, name: str = "demo", uri: str = "urn:motion-server:demo"):  # type: ignore[no-untyped-def]
    site = config.load(environ={})
    return site.model_copy(
        update={
            "site": site.site.model_copy(update={"name": name, "namespace_uri": uri}),
            "controller": site.controller.model_copy(
                update={"clock": "manual", "status_log_interval": 0.0}
            ),
            "modbus": site.modbus.model_copy(update={"enabled": False}),
            "opcua": site.opcua.model_copy(update={"port": 0, "data_dir": str(data_dir)}),
        }
    )


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("opcua-model")


@pytest.fixture
async def served(data_dir: Path) -> AsyncIterator[tuple[Runtime, Client, TagMap]]:
    site = demo_site(data_dir)
    async with running(site) as rt:
        assert rt.opcua is not None
        client = Client(rt.opcua.endpoint, timeout=10)  # the demo's anonymous None endpoint
        await client.connect()
        try:
            yield rt, client, build_tagmap(site)
        finally:
            await client.disconnect()


async def supertypes(client: Client, node_id: ua.NodeId) -> list[tuple[str, str]]:
    """(namespace URI, browse name) of a type and its supertypes, nearest first."""
    namespaces = await client.get_namespace_array()
    out = []
    node = client.get_node(node_id)
    while True:
        name = await node.read_browse_name()
        out.append((namespaces[name.NamespaceIndex], name.Name))
        parents = await node.get_referenced_nodes(
            refs=ua.ObjectIds.HasSubtype, direction=ua.BrowseDirection.Inverse
        )
        if not parents:
            return out
        node = parents[0]


async def test_an_instance_is_typed_by_a_plcopen_function_block_type(served) -> None:  # type: ignore[no-untyped-def]
    _, client, tagmap = served
    ns = await client.get_namespace_index("urn:motion-server:demo")
    for owner in ("MAG_1", "MC_GearIn_1", "MSO_1"):
        inst = client.get_node(ua.NodeId(f"Instructions.{owner}", ns))
        typedef = await inst.read_type_definition()
        chain = await supertypes(client, typedef)
        instruction = tagmap.block(owner).instruction
        assert chain[0] == ("urn:motion-server:demo", f"{instruction}_Type")
        assert chain[1] == (PLCOPEN, "CtrlFunctionBlockType")
        assert chain[2] == (PLCOPEN, "CtrlProgramOrganizationUnitType")
        assert (DI, "BlockType") in chain
        assert chain[-1] == ("http://opcfoundation.org/UA/", "BaseObjectType")
    axis = client.get_node(ua.NodeId("Axes.Axis2", ns))
    assert (await supertypes(client, await axis.read_type_definition()))[0][1] == "MotionAxisType"
    group = client.get_node(ua.NodeId("Groups.Group1", ns))
    assert (await supertypes(client, await group.read_type_definition()))[0][1] == (
        "MotionGroupType"
    )


async def test_every_operand_and_output_hangs_by_has_input_var_or_has_output_var(served) -> None:  # type: ignore[no-untyped-def]
    _, client, tagmap = served
    namespaces = await client.get_namespace_array()
    ns, plc = namespaces.index("urn:motion-server:demo"), namespaces.index(PLCOPEN)
    has_input, has_output = ua.NodeId(4001, plc), ua.NodeId(4002, plc)
    for owner in tagmap.owners(Folder.INSTRUCTIONS):
        tags = tagmap.owned_by(owner)
        inst = client.get_node(ua.NodeId(f"Instructions.{owner}", ns))
        for ref, writable in ((has_input, True), (has_output, False)):
            found = {n.nodeid.Identifier for n in await inst.get_referenced_nodes(refs=ref)}
            assert found == {t.node_id for t in tags if t.writable == writable}, owner
        # the type declares them the same way, as Mandatory instance declarations
        typedef = client.get_node(await inst.read_type_definition())
        declared = {
            (await n.read_browse_name()).Name
            for n in await typedef.get_referenced_nodes(refs=has_input)
        }
        assert declared == {t.field for t in tags if t.writable}, owner


async def test_engineering_units_are_unece_and_ranges_come_from_the_axis_limits(served) -> None:  # type: ignore[no-untyped-def]
    _, client, tagmap = served
    ns = await client.get_namespace_index("urn:motion-server:demo")
    analog = [t for t in tagmap if is_analog(t) and (t.units or t.quantity == "ratio")]
    assert len(analog) > 100
    eus = await client.read_values(
        [client.get_node(ua.NodeId(f"{t.node_id}.EngineeringUnits", ns)) for t in analog]
    )
    for tag, eu in zip(analog, eus, strict=True):
        assert isinstance(eu, ua.EUInformation), tag.name
        assert eu.NamespaceUri == "http://www.opcfoundation.org/UA/units/un/cefact"
        if tag.units in NO_CODE:
            assert eu.UnitId == -1, tag.name
        else:
            assert eu.UnitId == UNIT_IDS[tag.units], tag.name

    async def eu_range(node_id: str) -> tuple[float, float]:
        r = await client.get_node(ua.NodeId(f"{node_id}.EURange", ns)).read_value()
        return r.Low, r.High

    assert await eu_range("Axes.Axis2.CommandVelocity") == (-1000.0, 1000.0)
    assert await eu_range("Axes.Axis1.CommandAcceleration") == (-5000.0, 5000.0)
    assert await eu_range("Axes.Axis3.ActualPosition") == (0.0, 360.0)  # rollover span
    assert await eu_range("Axes.Axis2.PositionError") == (-10.0, 10.0)  # the limit
    # a linear axis: ± 2^31 counts / 1000 counts per mm
    assert await eu_range("Axes.Axis2.ActualPosition") == (-2147483.648, 2147483.648)
    # MAJ_1 jogs Axis1 (its default Axis = 1): Speed >= 0 up to Axis1's 500 mm/s
    assert await eu_range("Instructions.MAJ_1.Speed") == (0.0, 500.0)
    assert await eu_range("Axes.Axis2.MaxVelocity") == (0.0, 1000.0)
    for node_id in ("Axes.Axis2.CommandVelocity", "Axes.Axis3.CommandVelocity"):
        eu = await client.get_node(ua.NodeId(f"{node_id}.EngineeringUnits", ns)).read_value()
        assert (eu.DisplayName.Text, eu.Description.Text) in {
            ("mm/s", "millimetre per second"),
            ("°/s", "degree per second"),
        }


async def test_build_info_and_application_uri(served, data_dir: Path) -> None:  # type: ignore[no-untyped-def]
    _, client, _ = served
    info = await client.get_node(ua.ObjectIds.Server_ServerStatus_BuildInfo).read_value()
    assert info.ProductName == "motion-server"
    assert info.ManufacturerName == MANUFACTURER_NAME
    assert info.ProductUri == PRODUCT_URI
    assert info.SoftwareVersion == motion_server.__version__
    assert info.BuildNumber == metadata.version("motion-server")
    assert datetime(2025, 1, 1, tzinfo=UTC) < info.BuildDate.replace(tzinfo=UTC)
    assert info.BuildDate.replace(tzinfo=UTC) <= datetime.now(UTC)
    cert = x509.load_der_x509_certificate((data_dir / "server-cert.der").read_bytes())
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    (app_uri,) = san.get_values_for_type(x509.UniformResourceIdentifier)
    assert "127.0.0.1" in {str(ip) for ip in san.get_values_for_type(x509.IPAddress)}
    endpoints = await client.get_endpoints()
    assert {e.Server.ApplicationUri for e in endpoints} == {app_uri}
    assert {e.Server.ProductUri for e in endpoints} == {PRODUCT_URI}
    server_array = await client.get_node(ua.ObjectIds.Server_ServerArray).read_value()
    assert server_array[0] == app_uri


async def test_the_certificate_outlives_a_change_of_site_map(tmp_path: Path) -> None:
    data = tmp_path / "opcua"
    uris = []
    for name, uri in (("demo", "urn:motion-server:demo"), ("other", "urn:example:other-site")):
        async with running(demo_site(data, name, uri)) as rt:
            assert rt.opcua is not None
            client = Client(rt.opcua.endpoint, timeout=10)
            await client.connect()
            try:
                uris.append({e.Server.ApplicationUri for e in await client.get_endpoints()})
                assert uri in await client.get_namespace_array()
            finally:
                await client.disconnect()
        if len(uris) == 1:
            first = (data / "server-cert.der").read_bytes(), (data / "server-key.pem").read_bytes()
    assert ((data / "server-cert.der").read_bytes(), (data / "server-key.pem").read_bytes()) == (
        first
    )
    assert uris[0] == uris[1] and len(uris[0]) == 1


async def test_an_asyncua_client_gets_the_session_timeout_it_asks_for(
    served,  # type: ignore[no-untyped-def]
    caplog: pytest.LogCaptureFixture,
) -> None:
    rt, _, _ = served
    client = Client(rt.opcua.endpoint, timeout=10)
    asked = client.session_timeout  # asyncua's default: one hour
    with caplog.at_level(logging.WARNING, logger="asyncua"):
        await client.connect()
        try:
            assert client.session_timeout == asked == 3_600_000
        finally:
            await client.disconnect()
    assert not [r for r in caplog.records if "session timeout" in r.getMessage()]
