"""Modbus/TCP Security (Modbus.org MB-TCP-Security-v21): the TLS context and who a client
is.

The standard runs the Modbus TCP frames unchanged inside TLS (1.2 or later) on port 802,
with mutual authentication: the server verifies every client certificate against the
site's CA (``ssl.CERT_REQUIRED``; no certificate, another CA, an expired one: the
handshake fails). The client's role travels in its certificate as the X.509 v3 extension
:data:`ROLE_OID` whose value is an ASN.1 UTF8String; :func:`identify` maps it to a
:class:`~motion_server.safety.roles.Role` through ``[modbus.tls] roles``:

- no role extension: ``default_role`` (viewer unless the site map says otherwise);
- a role the table does not name (compared without regard to case, but exactly otherwise:
  " admin " with its spaces is no role), or an extension that is not a well-formed
  UTF8String: viewer (read only; logged), never more.

The extension must not be marked critical: OpenSSL refuses certificates with critical
extensions it does not know, before the server sees them.

The client's name in logs and in the audit log is the common name of its certificate
subject (the whole subject when there is no CN); nothing else of the certificate, and
nothing of any key, is ever logged.
"""

from __future__ import annotations

import ssl
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.x509.oid import NameOID

from ..config import ModbusTlsSection
from ..safety.roles import Role
from .certificates import pem_copy, self_signed

#: the role extension of Modbus/TCP Security client certificates
ROLE_OID = x509.ObjectIdentifier("1.3.6.1.4.1.50316.802.1")
#: a longer role text is refused as malformed
MAX_ROLE_BYTES = 255
#: a longer certificate name is cut (for log lines)
MAX_NAME = 128
_UTF8STRING = 0x0C


@dataclass(frozen=True)
class Identity:
    """A verified client: ``name`` (subject CN), the ``role`` granted, the role text its
    certificate claims (None: no role extension), ``why`` in words, and whether the
    claimed role was understood (False: unknown or unreadable, viewer given)."""

    name: str
    role: Role
    claimed: str | None
    why: str
    recognised: bool = True


def server_context(cert: str | Path, key: str | Path, ca: str | Path) -> ssl.SSLContext:
    """TLS 1.2+ server context with the server's certificate and key; client
    certificates are required and verified against ``ca``. An unusable file raises
    OSError (ssl.SSLError for a malformed one) naming it."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    ctx.verify_mode = ssl.CERT_REQUIRED
    ctx.options |= ssl.OP_NO_RENEGOTIATION  # TLS 1.2: no renegotiation storms
    for path in (cert, key, ca):
        if not Path(path).is_file():
            raise FileNotFoundError(2, "no such file", str(path))
    # an encrypted key fails here instead of prompting for a pass phrase on the terminal
    ctx.load_cert_chain(str(cert), str(key), password=_no_password)
    ctx.load_verify_locations(cafile=str(ca))
    return ctx


def _no_password() -> bytes:
    return b""


async def server_files(cfg: ModbusTlsSection, app_uri: str, common_name: str) -> tuple[Path, Path]:
    """The server's certificate and key (PEM): the site map's, or a self-signed pair
    generated in ``data_dir`` on first start and kept there."""
    if cfg.cert_file:
        return Path(cfg.cert_file), Path(cfg.key_file)
    der, key = await self_signed(cfg.data_dir, app_uri, common_name, "Modbus/TLS")
    return pem_copy(der), key


def utf8string(der: bytes) -> str:
    """The text of a DER-encoded ASN.1 UTF8String; ValueError when it is not one."""
    if len(der) < 2 or der[0] != _UTF8STRING:
        raise ValueError("not a UTF8String")
    length, head = der[1], 2
    if length & 0x80:  # long form: the next (length & 0x7f) bytes hold the length
        size = length & 0x7F
        if size == 0 or size > 2 or len(der) < 2 + size:
            raise ValueError("bad UTF8String length")
        length, head = int.from_bytes(der[2 : 2 + size], "big"), 2 + size
    if length > MAX_ROLE_BYTES or len(der) != head + length:
        raise ValueError("bad UTF8String length")
    return der[head:].decode("utf-8")


def certificate_role(cert: x509.Certificate) -> str | None:
    """The role text of ``cert`` (None: no role extension); ValueError when the
    extension is there but unreadable."""
    try:
        ext = cert.extensions.get_extension_for_oid(ROLE_OID)
    except x509.ExtensionNotFound:
        return None
    value = ext.value
    if not isinstance(value, x509.UnrecognizedExtension):
        raise ValueError("unexpected role extension type")
    return utf8string(value.value)


def subject_name(cert: x509.Certificate) -> str:
    """The subject's common name (the whole subject when it has none), cut for logs."""
    cns = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    raw = cns[0].value if cns else cert.subject.rfc4514_string()
    name = raw.decode("utf-8", "replace") if isinstance(raw, bytes) else str(raw)
    name = "".join(c if c.isprintable() else "?" for c in name)
    return name[:MAX_NAME] or "?"


def identify(der: bytes, roles: Mapping[str, str], default_role: str) -> Identity:
    """Who the (verified) certificate ``der`` is and which role it gets."""
    cert = x509.load_der_x509_certificate(der)
    name = subject_name(cert)
    try:
        claimed = certificate_role(cert)
    except (ValueError, UnicodeDecodeError) as exc:
        why = f"unreadable role extension ({exc}): viewer"
        return Identity(name, Role.VIEWER, "?", why, recognised=False)
    if claimed is None:
        role = Role.named(default_role)
        return Identity(name, role, None, f"no role extension: default role {role.label}")
    shown = "".join(c if c.isprintable() else "?" for c in claimed)[:MAX_NAME]
    # case is ignored, padding is not: " admin " is no role (a CA that issues it is wrong)
    mapped = roles.get(claimed.lower())
    if mapped is None:
        why = f"unknown certificate role {shown!r}: viewer"
        return Identity(name, Role.VIEWER, shown, why, recognised=False)
    role = Role.named(mapped)
    return Identity(name, role, shown, f"certificate role {shown!r}: {role.label}")


def handshake_failure(exc: BaseException) -> str:
    """Why a handshake failed, in words for the log and the audit log."""
    if isinstance(exc, ssl.SSLCertVerificationError):
        return f"certificate verify failed: {exc.verify_message}"
    if isinstance(exc, ssl.SSLError):
        return exc.reason or str(exc)
    if isinstance(exc, ConnectionAbortedError | TimeoutError):
        return "handshake timed out"
    if isinstance(exc, ConnectionError | EOFError):
        return "connection closed during the handshake"
    return f"{type(exc).__name__}: {exc}"
