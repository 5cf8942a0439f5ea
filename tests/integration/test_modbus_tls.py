"""Modbus/TCP Security over real sockets on 127.0.0.1: TLS with required client
certificates, the role from the certificate's role extension, refused handshakes.

Each test makes a throwaway PKI in its tmp dir (cryptography, P-256 keys): a site CA
that signs the server certificate (IP address 127.0.0.1, so clients check the host name)
and the client certificates, and a second, foreign CA. A client's role travels in the
extension 1.3.6.1.4.1.50316.802.1, whose value is an ASN.1 UTF8String: tag 0x0C, one
length byte (below 128), the UTF-8 bytes.
"""

from __future__ import annotations

import asyncio
import datetime
import ipaddress
import json
import logging
import re
import ssl
import struct
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from pymodbus.client import AsyncModbusTcpClient, AsyncModbusTlsClient
from pymodbus.pdu import ExceptionResponse

from motion_server import config
from motion_server.runtime import Runtime
from tests.integration.test_modbus import Tags
from tests.modbus_support import SITE

ROLE_OID = x509.ObjectIdentifier("1.3.6.1.4.1.50316.802.1")


def utf8string(text: str) -> bytes:
    data = text.encode("utf-8")
    assert len(data) < 128
    return bytes([0x0C, len(data)]) + data


# -- a throwaway PKI -------------------------------------------------------------------------
@dataclass
class Issued:
    cert: Path
    key: Path


class Authority:
    """A CA in ``directory`` that issues P-256 certificates valid for a day."""

    def __init__(self, directory: Path, name: str) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self.dir = directory
        self.key = ec.generate_private_key(ec.SECP256R1())
        subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
        now = datetime.datetime.now(datetime.UTC)
        self.cert = (
            x509.CertificateBuilder()
            .subject_name(subject)
            .issuer_name(subject)
            .public_key(self.key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(
                x509.KeyUsage(
                    digital_signature=True,
                    content_commitment=False,
                    key_encipherment=False,
                    data_encipherment=False,
                    key_agreement=False,
                    key_cert_sign=True,
                    crl_sign=True,
                    encipher_only=False,
                    decipher_only=False,
                ),
                critical=True,
            )
            .sign(self.key, hashes.SHA256())
        )
        self.pem = directory / "ca.pem"
        self.pem.write_bytes(self.cert.public_bytes(serialization.Encoding.PEM))
        self.key_file = _write_key(directory / "ca.key", self.key)

    def issue(self, name: str, role: str | bytes | None = None, server: bool = False) -> Issued:
        """A certificate for ``name``; ``role``: text for the role extension, raw bytes
        for a malformed one, None for none."""
        key = ec.generate_private_key(ec.SECP256R1())
        now = datetime.datetime.now(datetime.UTC)
        usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
        builder = (
            x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
            .issuer_name(self.cert.subject)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.ExtendedKeyUsage([usage]), critical=False)
        )
        if server:
            san = x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))])
            builder = builder.add_extension(san, critical=False)
        if role is not None:
            value = utf8string(role) if isinstance(role, str) else role
            builder = builder.add_extension(
                x509.UnrecognizedExtension(ROLE_OID, value), critical=False
            )
        cert = builder.sign(self.key, hashes.SHA256())
        stem = re.sub(r"\W", "_", name)
        path = self.dir / f"{stem}.pem"
        path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        return Issued(path, _write_key(self.dir / f"{stem}.key", key))


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> Path:
    path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return path


def client_context(server_ca: Path, issued: Issued | None) -> ssl.SSLContext:
    """Verifies the server against ``server_ca`` (host name included); presents
    ``issued`` (None: no certificate)."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.load_verify_locations(cafile=str(server_ca))
    if issued is not None:
        ctx.load_cert_chain(str(issued.cert), str(issued.key))
    return ctx


# -- the server --------------------------------------------------------------------------------
@dataclass
class Site:
    runtime: Runtime
    pki: Authority
    tmp: Path

    @property
    def audit(self) -> list[dict[str, object]]:
        path = self.tmp / "audit.jsonl"
        return [json.loads(line) for line in path.read_text("utf-8").splitlines()]

    async def client(self, name: str, role: str | bytes | None = None) -> Tags:
        """A connected pymodbus TLS client with a fresh certificate of the site CA."""
        issued = self.pki.issue(name, role)
        return await self.client_with(client_context(self.pki.pem, issued))

    async def client_with(self, ctx: ssl.SSLContext) -> Tags:
        assert self.runtime.modbus is not None
        client = AsyncModbusTlsClient(
            "127.0.0.1",
            port=self.runtime.modbus.tls_port,
            sslctx=ctx,
            timeout=3,
            retries=0,
            reconnect_delay=0,
        )
        assert await client.connect()
        self._clients.append(client)
        return Tags(client, self.runtime.tagmap, 1)

    async def plain(self) -> Tags:
        assert self.runtime.modbus is not None
        client = AsyncModbusTcpClient(
            "127.0.0.1", port=self.runtime.modbus.port, timeout=3, retries=0, reconnect_delay=0
        )
        assert await client.connect()
        self._clients.append(client)
        return Tags(client, self.runtime.tagmap, 1)

    def __post_init__(self) -> None:
        self._clients: list[AsyncModbusTcpClient] = []


Serve = Callable[..., Awaitable[Site]]


@pytest.fixture
async def serve(tmp_path: Path) -> AsyncIterator[Serve]:
    """``site = await serve(tls_toml="", access_toml="", own_cert=True)``: the test site
    with ``[modbus.tls]`` on an ephemeral port and the audit log on."""
    started: list[tuple[Site, asyncio.Task[None]]] = []

    async def open_(tls: str = "", access: str = "", own_cert: bool = True) -> Site:
        run = tmp_path / f"run{len(started)}"
        pki = Authority(run / "pki", "Site CA")
        files = f'ca_file = "{pki.pem}"\n'
        if own_cert:
            server = pki.issue("motion-server", server=True)
            files += f'cert_file = "{server.cert}"\nkey_file = "{server.key}"\n'
        else:
            files += f'data_dir = "{run / "tls-data"}"\n'
        text = (
            f'data_dir = "{run}"\n'
            + SITE.format(word_order="big", unit_id=1)
            + f"\n[modbus.tls]\nenabled = true\nport = 0\n{files}{tls}\n"
            + (f"\n[modbus.access]\n{access}\n" if access else "")
            + "\n[audit]\nenabled = true\n"
        )
        rt = Runtime(config.parse(text, "tls-test.toml"))
        task = asyncio.create_task(rt.serve())
        await asyncio.wait_for(rt.ready.wait(), 20.0)
        site = Site(rt, pki, run)
        started.append((site, task))
        return site

    yield open_
    for site, task in started:
        for client in site._clients:
            client.close()
        site.runtime.request_stop()
        await asyncio.wait_for(task, 10.0)


async def until(condition: Callable[[], bool], timeout: float = 3.0) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not condition():
        assert loop.time() < end, "condition not met in time"
        await asyncio.sleep(0.01)


def read_frame(tid: int, address: int, count: int) -> bytes:
    return struct.pack(">HHHBBHH", tid, 0, 6, 1, 3, address, count)


async def exchange(port: int, ctx: ssl.SSLContext) -> bytes | BaseException:
    """One FC3 request over TLS: the answer, b"" (closed), or what the client raised."""
    try:
        reader, writer = await asyncio.open_connection("127.0.0.1", port, ssl=ctx)
    except (ssl.SSLError, OSError) as exc:
        return exc
    try:
        writer.write(read_frame(1, 0, 1))
        await writer.drain()
        return await asyncio.wait_for(reader.read(256), 5.0)
    except (ssl.SSLError, OSError) as exc:
        return exc
    finally:
        writer.close()


async def refused_write(tags: Tags, name: str, registers: list[int]) -> int:
    """Write raw registers to ``name``; the exception code (0: accepted)."""
    tag = tags.map.tag(name)
    rr = await tags.client.write_registers(tag.address, registers, device_id=1)
    return rr.exception_code if isinstance(rr, ExceptionResponse) else 0


# -- roles ------------------------------------------------------------------------------------
async def test_an_operator_reads_and_triggers_an_instruction_but_not_the_clock(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve()
    rt = site.runtime
    op = await site.client("hmi-1", "operator")
    admin = await site.client("engineering", "admin")
    assert await op.read("Clock.Mode") == 1  # manual: nothing moves until a step
    await op.trigger("MSO_1", Axis=1)
    assert rt.image.read("MSO_1.Execute") is True
    assert await op.read("MSO_1.DN") is False  # not scanned yet
    # the Clock is for admins: exception 02, nothing changed
    assert await refused_write(op, "Clock.StepCycles", [0, 7]) == 2
    assert rt.image.read("Clock.StepCycles") == 1
    assert rt.cycle_count == 0
    await admin.step(1)  # the admin's step is answered once the cycle ran
    assert rt.cycle_count == 1
    assert await op.read("MSO_1.DN") is True
    assert await op.read("Axis1.AxisState") == 2  # Servo Control


async def test_a_viewer_reads_and_its_writes_get_exception_02(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve()
    rt = site.runtime
    viewer = await site.client("panel-7", "viewer")
    before = rt.image.read("MAJ_1.Speed")
    assert await viewer.read("MAJ_1.Speed") == before
    assert await refused_write(viewer, "MAJ_1.Speed", [0x41C8, 0]) == 2  # 25.0
    assert rt.image.read("MAJ_1.Speed") == before
    refused = [r for r in site.audit if r["event"] == "write" and r["result"] == "refused"]
    assert len(refused) == 1
    line = refused[0]
    assert (line["protocol"], line["user"], line["role"]) == ("modbus-tls", "panel-7", "viewer")
    assert "role viewer may not write" in str(line["reason"])


@pytest.mark.parametrize(
    ("setting", "role", "writes"),
    [("", "viewer", False), ('default_role = "operator"', "operator", True)],
)
async def test_a_certificate_without_a_role_gets_the_default_role(  # type: ignore[no-untyped-def]
    serve, setting: str, role: str, writes: bool
) -> None:
    site = await serve(tls=setting)
    tags = await site.client("legacy-hmi", None)
    assert await tags.read("Clock.Mode") == 1
    code = await refused_write(tags, "MAJ_1.Speed", [0x41C8, 0])  # 25.0
    assert code == (0 if writes else 2)
    assert site.runtime.image.read("MAJ_1.Speed") == (25.0 if writes else 10.0)
    connect = next(r for r in site.audit if r["event"] == "connect")
    assert (connect["result"], connect["user"], connect["role"]) == ("accepted", "legacy-hmi", role)
    assert connect["reason"] == f"no role extension: default role {role}"


async def test_unknown_or_malformed_roles_get_read_only_and_case_is_ignored(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve(tls='default_role = "operator"')
    rt = site.runtime
    unknown = await site.client("intruder", "superuser")
    printable = await site.client("odd-ca", b"\x13\x05admin")  # a PrintableString
    shouting = await site.client("hmi-2", "OPERATOR")
    assert await refused_write(unknown, "MAJ_1.Speed", [0x41C8, 0]) == 2
    assert await refused_write(printable, "MAJ_1.Speed", [0x41C8, 0]) == 2
    assert rt.image.read("MAJ_1.Speed") == 10.0
    assert await refused_write(shouting, "MAJ_1.Speed", [0x41C8, 0]) == 0
    assert rt.image.read("MAJ_1.Speed") == 25.0
    roles = {r["user"]: r["role"] for r in site.audit if r["event"] == "connect"}
    assert roles == {"intruder": "viewer", "odd-ca": "viewer", "hmi-2": "operator"}


async def test_a_padded_role_text_matches_no_role(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve()
    padded = await site.client("padded", " admin ")
    assert await refused_write(padded, "MAJ_1.Speed", [0x41C8, 0]) == 2
    assert await refused_write(padded, "Clock.StepCycles", [0, 7]) == 2
    assert site.runtime.image.read("MAJ_1.Speed") == 10.0
    roles = {r["user"]: r["role"] for r in site.audit if r["event"] == "connect"}
    assert roles == {"padded": "viewer"}


async def test_a_roles_table_maps_the_site_pki_names(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve(tls='roles = { Engineer = "admin", Line = "operator" }')
    rt = site.runtime
    engineer = await site.client("eng-1", "engineer")
    line = await site.client("line-3", "Line")
    operator = await site.client("hmi-1", "operator")  # the table replaces the default one
    await engineer.step(2)
    assert rt.cycle_count == 2
    assert await refused_write(line, "Clock.StepCycles", [0, 7]) == 2
    assert await refused_write(line, "MAJ_1.Speed", [0x41C8, 0]) == 0
    assert await refused_write(operator, "MAJ_1.Speed", [0x41A0, 0]) == 2  # 20.0
    assert rt.image.read("MAJ_1.Speed") == 25.0


# -- handshakes ----------------------------------------------------------------------------------
async def test_no_certificate_or_another_ca_is_refused_and_the_server_keeps_serving(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve()
    rt = site.runtime
    assert rt.modbus is not None and rt.modbus.tls_server is not None
    port = rt.modbus.tls_port
    foreign = Authority(site.tmp / "foreign", "Foreign CA")
    attempts = {
        "no certificate": client_context(site.pki.pem, None),
        "another CA": client_context(site.pki.pem, foreign.issue("hmi-x", "admin")),
    }
    for what, ctx in attempts.items():
        answer = await exchange(port, ctx)
        # never a Modbus answer: the client sees an alert or the connection close
        assert isinstance(answer, BaseException) or answer == b"", f"{what}: {answer!r}"
    await until(lambda: rt.modbus is not None and rt.modbus.tls_refused == 2)
    # the server goes on serving both listeners, and holds nothing of the refused ones
    tags = await site.client("hmi-1", "operator")
    assert await tags.read("Clock.Mode") == 1
    plain = await site.plain()
    assert await plain.read("Clock.Mode") == 1
    assert len(rt.modbus.connections) == 2
    assert len(rt.modbus.tls_server.active_connections) == 1
    refusals = [r for r in site.audit if r["event"] == "connect" and r["result"] == "refused"]
    reasons = [str(r["reason"]) for r in refusals]
    assert len(reasons) == 2 and all(r.startswith("TLS handshake: ") for r in reasons)
    assert "CERTIFICATE" in reasons[0].upper()  # the peer sent none
    assert "certificate verify failed" in reasons[1]  # unknown issuer


async def test_tls_1_2_is_served_and_checks_certificates_the_same(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve()
    rt = site.runtime
    assert rt.modbus is not None
    ctx = client_context(site.pki.pem, site.pki.issue("old-panel", "viewer"))
    ctx.maximum_version = ssl.TLSVersion.TLSv1_2  # the standard's minimum
    answer = await exchange(rt.modbus.tls_port, ctx)
    assert isinstance(answer, bytes) and answer[7] == 3  # an FC3 answer
    bare = client_context(site.pki.pem, None)
    bare.maximum_version = ssl.TLSVersion.TLSv1_2
    refused = await exchange(rt.modbus.tls_port, bare)
    assert isinstance(refused, BaseException) or refused == b""
    await until(lambda: rt.modbus is not None and rt.modbus.tls_refused == 1)


async def test_a_silent_or_plaintext_client_on_the_tls_port_is_dropped(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve(tls="handshake_timeout = 0.5")
    rt = site.runtime
    assert rt.modbus is not None
    port = rt.modbus.tls_port
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    assert await asyncio.wait_for(reader.read(10), 5.0) == b""  # closed by the server
    assert 0.5 <= loop.time() - t0 < 3.0
    writer.close()
    # a plain Modbus request is no ClientHello: refused at once, never answered
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(read_frame(1, 0, 1))
    try:
        answer = await asyncio.wait_for(reader.read(64), 5.0)
    except ConnectionResetError:
        answer = b""
    assert answer[7:8] != b"\x03"  # whatever TLS alert it gets, it is not an FC3 answer
    writer.close()
    await until(lambda: rt.modbus is not None and rt.modbus.tls_refused == 2)
    reasons = [str(r["reason"]) for r in site.audit if r["result"] == "refused"]
    assert reasons[0] == "TLS handshake: handshake timed out"
    assert not rt.modbus.connections
    tags = await site.client("hmi-1", "viewer")
    assert await tags.read("Clock.Mode") == 1


# -- access rules and limits --------------------------------------------------------------------
async def test_access_rules_and_limits_apply_to_tls_clients_too(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve(
        access="max_connections = 2\nidle_timeout = 0.5\n"
        '[[modbus.access.rules]]\nnetworks = ["127.0.0.0/8"]\nwrite = ["MAM_1"]\n'
    )
    rt = site.runtime
    assert rt.modbus is not None
    admin = await site.client("engineering", "admin")
    # the admin's role allows MAJ_1, the network's rule does not: both must agree
    assert await refused_write(admin, "MAJ_1.Speed", [0x41C8, 0]) == 2
    assert await refused_write(admin, "MAM_1.Speed", [0x41C8, 0]) == 0
    second = await site.client("hmi-1", "operator")
    assert await second.read("Clock.Mode") == 1
    # a third connection is past the limit: closed before any handshake
    third = await exchange(rt.modbus.tls_port, client_context(site.pki.pem, site.pki.issue("x")))
    assert isinstance(third, BaseException) or third == b""
    assert rt.modbus.refused_connections == 1 and rt.modbus.tls_refused == 0
    # both stay silent: closed after the idle timeout, audited with their names
    await until(lambda: rt.modbus is not None and rt.modbus.idle_closed == 2, timeout=5.0)
    idle = [r for r in site.audit if r["event"] == "disconnect"]
    assert sorted(str(r["user"]) for r in idle) == ["engineering", "hmi-1"]
    assert all(r["result"] == "idle timeout" for r in idle)


async def test_tls_only_serves_no_plain_modbus(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve(tls="tls_only = true")
    rt = site.runtime
    assert rt.modbus is not None and rt.modbus.server is None
    with pytest.raises(RuntimeError, match="not listening"):
        _ = rt.modbus.port
    tags = await site.client("hmi-1", "viewer")
    assert await tags.read("Clock.Mode") == 1


# -- certificates and what is logged ------------------------------------------------------------
async def test_a_self_signed_server_certificate_is_made_once_and_kept(serve) -> None:  # type: ignore[no-untyped-def]
    site = await serve(own_cert=False)
    data = site.tmp / "tls-data"
    pem = data / "server-cert.pem"
    assert (data / "server-key.pem").stat().st_mode & 0o777 == 0o600
    ctx = client_context(pem, site.pki.issue("hmi-1", "viewer"))
    ctx.check_hostname = False  # a generated certificate names the host, not 127.0.0.1
    tags = await site.client_with(ctx)
    assert await tags.read("Clock.Mode") == 1
    first = pem.read_bytes()
    # a second start with the same data directory reuses the pair
    site.runtime.request_stop()
    rt = Runtime(site.runtime.site)
    task = asyncio.create_task(rt.serve())
    try:
        await asyncio.wait_for(rt.ready.wait(), 20.0)
        assert pem.read_bytes() == first
        assert rt.modbus is not None
        answer = await exchange(rt.modbus.tls_port, ctx)
        assert isinstance(answer, bytes) and answer[7] == 3  # an FC3 answer
    finally:
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)


async def test_names_and_roles_are_logged_and_audited_without_key_material(  # type: ignore[no-untyped-def]
    serve, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG)
    site = await serve()
    op = await site.client("hmi-1", "operator")
    await op.write("MAJ_1.Speed", 25.0)
    foreign = Authority(site.tmp / "foreign", "Foreign CA")
    await exchange(site.runtime.modbus.tls_port, client_context(site.pki.pem, foreign.issue("x")))  # type: ignore[union-attr]
    await until(lambda: site.runtime.modbus is not None and site.runtime.modbus.tls_refused == 1)
    logged = caplog.text
    audited = (site.tmp / "audit.jsonl").read_text("utf-8")
    assert "'hmi-1', certificate role 'operator': operator" in logged
    accepted = [r for r in site.audit if r["event"] == "write" and r["result"] == "accepted"]
    assert [(r["user"], r["role"], r["tag"]) for r in accepted] == [
        ("hmi-1", "operator", "MAJ_1.Speed")
    ]
    keys = list(site.tmp.rglob("*.key"))
    assert len(keys) >= 4  # the two CAs, the server, the clients
    for path in keys:
        body = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("-----")]
        for line in body:
            assert line not in logged and line not in audited, f"{path.name} leaked"
    for text in (logged, audited):
        assert "PRIVATE KEY" not in text and "BEGIN CERTIFICATE" not in text


# -- the site map -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("tls", "message"),
    [
        ("enabled = true", "ca_file is required"),
        ('cert_file = "a.pem"', "cert_file and key_file go together"),
        ("tls_only = true", "tls_only needs enabled = true"),
        ('roles = { viewer = "viewer", Viewer = "admin" }', "mapped twice"),
        ('default_role = "root"', "default_role"),
    ],
)
def test_tls_settings_are_checked(tls: str, message: str) -> None:
    text = SITE.format(word_order="big", unit_id=1) + f"\n[modbus.tls]\n{tls}\n"
    with pytest.raises(config.SiteMapError, match=message) as err:
        config.parse(text, "bad-tls.toml")
    assert "bad-tls.toml:" in str(err.value) and "modbus.tls" in str(err.value)


async def test_an_unreadable_ca_file_stops_the_start_naming_it(tmp_path: Path) -> None:
    missing = tmp_path / "no-such-ca.pem"
    text = SITE.format(word_order="big", unit_id=1) + (
        f'\n[modbus.tls]\nenabled = true\nport = 0\nca_file = "{missing}"\n'
        f'data_dir = "{tmp_path / "tls"}"\n'
    )
    rt = Runtime(config.parse(text, "tls.toml"))
    with pytest.raises(OSError) as err:
        await asyncio.wait_for(rt.serve(), 20.0)
    assert err.value.filename == str(missing)
