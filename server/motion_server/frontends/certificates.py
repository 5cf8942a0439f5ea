"""Self-signed server certificates, generated once per data directory and kept there.

Used by the OPC UA front-end (its application instance certificate) and by Modbus/TCP
Security when the site map names no certificate of its own. The pair is an RSA 2048 key
(PEM, mode 0600) and a certificate (DER, SHA-256, the OPC UA application certificate
extensions asyncua's ``generate_self_signed_app_certificate`` writes) valid for
``VALIDITY_DAYS``.

A certificate is issued when the directory has none (or an unreadable one, a key that does
not match it, or one that expires within ``RENEW_DAYS``), and otherwise kept: running
another site map, on another port or address, in the same directory reuses it, so clients
that trust it keep trusting it. Its SubjectAltName holds the application URI (made once:
``urn:motion-server:<host>:<random>``, read back from the certificate afterwards, so the
server's ApplicationUri always equals the certificate's), the host name and the IP
addresses the server is bound to (every address of the host for a wildcard bind). A kept
certificate that does not name the current host name or bound address is used all the
same, with a warning saying how to have a new one issued (delete the two files).
"""

from __future__ import annotations

import contextlib
import ipaddress
import logging
import socket
import uuid
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

from asyncua.crypto.cert_gen import (
    dump_private_key_as_pem,
    generate_private_key,
    generate_self_signed_app_certificate,
)
from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.serialization import Encoding
from cryptography.x509.oid import ExtendedKeyUsageOID

log = logging.getLogger("motion_server.certificates")

CERT_FILE = "server-cert.der"
KEY_FILE = "server-key.pem"
VALIDITY_DAYS = 5 * 365
#: a certificate that expires within this many days is issued anew
RENEW_DAYS = 30


@dataclass(frozen=True)
class ServerCertificate:
    """The certificate and key files of a data directory and the application URI the
    certificate names."""

    cert: Path
    key: Path
    application_uri: str


def new_application_uri(hostname: str | None = None) -> str:
    """A unique application URI for a new installation."""
    host = (hostname or socket.gethostname()).lower() or "localhost"
    return f"urn:motion-server:{host}:{uuid.uuid4().hex[:12]}"


def bound_addresses(host: str) -> list[ipaddress.IPv4Address | ipaddress.IPv6Address]:
    """The IP addresses a server bound to ``host`` answers on (all of this host's for a
    wildcard bind)."""
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        address = None
    if address is not None and not address.is_unspecified:
        return [address]
    names = [host] if host and address is None else [socket.gethostname(), "localhost"]
    found: list[ipaddress.IPv4Address | ipaddress.IPv6Address] = []
    for name in names:
        with contextlib.suppress(OSError):
            for info in socket.getaddrinfo(name, None, proto=socket.IPPROTO_TCP):
                ip = ipaddress.ip_address(str(info[4][0]).split("%")[0])
                if ip not in found:
                    found.append(ip)
    if not found:
        found.append(ipaddress.ip_address("127.0.0.1"))
    return found


def alt_names(cert: x509.Certificate) -> tuple[list[str], list[str], list[str]]:
    """(URIs, DNS names, IP addresses) of a certificate's SubjectAltName."""
    try:
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except x509.ExtensionNotFound:
        return [], [], []
    return (
        list(san.get_values_for_type(x509.UniformResourceIdentifier)),
        list(san.get_values_for_type(x509.DNSName)),
        [str(ip) for ip in san.get_values_for_type(x509.IPAddress)],
    )


def _usable(cert_path: Path, key_path: Path) -> x509.Certificate | None:
    """The certificate in ``cert_path`` if it and its key can be kept, else None."""
    try:
        cert = x509.load_der_x509_certificate(cert_path.read_bytes())
        key = serialization.load_pem_private_key(key_path.read_bytes(), password=None)
    except (OSError, ValueError, TypeError):
        return None
    if cert.public_key().public_numbers() != key.public_key().public_numbers():  # type: ignore[union-attr]
        return None
    if cert.not_valid_after_utc - datetime.now(UTC) < timedelta(days=RENEW_DAYS):
        return None
    if not alt_names(cert)[0]:
        return None
    return cert


def server_certificate(
    directory: str | Path,
    host: str,
    what: str,
    common_name: str | None = None,
    app_uri: str | None = None,
) -> ServerCertificate:
    """The certificate of ``directory``, issued when needed (see the module docstring).
    ``host`` is the bind address; ``what`` names the user in log lines (``OPC UA``);
    ``app_uri`` the URI a new certificate names (default: a new unique one)."""
    data = Path(directory)
    data.mkdir(parents=True, exist_ok=True)
    cert_path, key_path = data / CERT_FILE, data / KEY_FILE
    hostname = socket.gethostname()
    addresses = bound_addresses(host)
    cert = _usable(cert_path, key_path) if cert_path.exists() and key_path.exists() else None
    if cert is None:
        if cert_path.exists():
            log.info("%s: the certificate in %s cannot be kept; issuing a new one", what, data)
        else:
            log.info("%s: generating the server certificate in %s", what, data)
        uri = app_uri or new_application_uri(hostname)
        key = generate_private_key()
        san: list[x509.GeneralName] = [x509.UniformResourceIdentifier(uri), x509.DNSName(hostname)]
        san += [x509.IPAddress(ip) for ip in addresses]
        cert = generate_self_signed_app_certificate(
            key,
            common_name or f"motion-server@{hostname}",
            {},
            san,
            extended=[ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH],
            days=VALIDITY_DAYS,
        )
        key_path.write_bytes(dump_private_key_as_pem(key))
        cert_path.write_bytes(cert.public_bytes(Encoding.DER))
    uris, dns, ips = alt_names(cert)
    missing = [hostname] if hostname not in dns else []
    missing += [str(ip) for ip in addresses if str(ip) not in ips]
    if missing:
        log.warning(
            "%s: the certificate in %s does not name %s; clients that check host names "
            "will refuse it (delete %s and %s to have a new one issued)",
            what,
            data,
            ", ".join(missing),
            CERT_FILE,
            KEY_FILE,
        )
    with contextlib.suppress(OSError):
        key_path.chmod(0o600)
    return ServerCertificate(cert_path, key_path, uris[0])


async def self_signed(
    directory: str | Path, app_uri: str, common_name: str, what: str, host: str = ""
) -> tuple[Path, Path]:
    """The (certificate DER, key PEM) paths in ``directory``, issued when needed;
    ``app_uri`` is the URI a new certificate names."""
    found = server_certificate(directory, host, what, common_name, app_uri)
    return found.cert, found.key


def pem_copy(der: Path) -> Path:
    """A PEM copy of the DER certificate ``der`` beside it (``.pem``), for the ssl
    module, which reads PEM only; rewritten when the DER one changed."""
    pem = der.with_suffix(".pem")
    text = x509.load_der_x509_certificate(der.read_bytes()).public_bytes(Encoding.PEM)
    if not pem.exists() or pem.read_bytes() != text:
        pem.write_bytes(text)
    return pem
