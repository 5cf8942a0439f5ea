"""Self-signed server certificates, generated on first start and kept in a data directory.

Used by the OPC UA front-end (its application instance certificate) and by Modbus/TCP
Security when the site map names no certificate of its own. asyncua's
``setup_self_signed_certificate`` makes the pair: an RSA 2048 key (PEM, mode 0600) and a
certificate (DER) valid for a year, naming the application URI and this host; it is made
again when missing, expired, expiring or naming another URI or host.
"""

from __future__ import annotations

import contextlib
import logging
import socket
from pathlib import Path

from asyncua.crypto.cert_gen import setup_self_signed_certificate
from cryptography import x509
from cryptography.hazmat.primitives.serialization import Encoding
from cryptography.x509.oid import ExtendedKeyUsageOID

log = logging.getLogger("motion_server.certificates")

CERT_FILE = "server-cert.der"
KEY_FILE = "server-key.pem"


async def self_signed(
    directory: str | Path, app_uri: str, common_name: str, what: str
) -> tuple[Path, Path]:
    """The (certificate DER, key PEM) paths in ``directory``, generated when needed.
    ``what`` names the user in the log line (``OPC UA``, ``Modbus/TLS``)."""
    data = Path(directory)
    data.mkdir(parents=True, exist_ok=True)
    cert, key = data / CERT_FILE, data / KEY_FILE
    if not cert.exists():
        log.info("%s: generating the server certificate in %s", what, data)
    await setup_self_signed_certificate(
        key,
        cert,
        app_uri,
        socket.gethostname(),
        [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH],
        {"commonName": common_name},
    )
    with contextlib.suppress(OSError):
        key.chmod(0o600)
    return cert, key


def pem_copy(der: Path) -> Path:
    """A PEM copy of the DER certificate ``der`` beside it (``.pem``), for the ssl
    module, which reads PEM only; rewritten when the DER one changed."""
    pem = der.with_suffix(".pem")
    text = x509.load_der_x509_certificate(der.read_bytes()).public_bytes(Encoding.PEM)
    if not pem.exists() or pem.read_bytes() != text:
        pem.write_bytes(text)
    return pem
