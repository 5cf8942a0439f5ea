"""The OPC UA back-end (asyncua client): the same tag calls as over Modbus.

Nodes are ``ns=<site namespace>;s=<tag.node_id>``. Secure by default, as the server is:
Basic256Sha256 with SignAndEncrypt, a self-signed client certificate generated (once) in
``cert_dir``, and a user name and password. ``security="None"`` uses the None endpoint
(only when the server allows it; it takes no user name: anonymous only). Writes carry
the node's exact DataType, so the server never answers BadTypeMismatch; a refused write
(BadUserAccessDenied, BadOutOfRange...) raises :class:`~.backend.ClientError` with the
status code's name. Reads of many tags are split into requests of at most the server's
``MaxNodesPerRead`` (read from its ServerCapabilities.OperationLimits once connected).
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from asyncua import Client, ua
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

from .backend import Backend, ClientError, connection_refused_hint, held_logs
from .tagmap import ClientMap, MapTag, Value

VARIANT = {
    "BOOL": ua.VariantType.Boolean,
    "SINT": ua.VariantType.SByte,
    "INT": ua.VariantType.Int16,
    "DINT": ua.VariantType.Int32,
    "UDINT": ua.VariantType.UInt32,
    "REAL": ua.VariantType.Float,
    "LREAL": ua.VariantType.Double,
}
MODES = {
    "Sign": ua.MessageSecurityMode.Sign,
    "SignAndEncrypt": ua.MessageSecurityMode.SignAndEncrypt,
}
CLIENT_URI = "urn:motion-server:motion-client"
MAX_NODES_PER_READ = ua.NodeId(
    ua.ObjectIds.Server_ServerCapabilities_OperationLimits_MaxNodesPerRead
)
#: status codes of a refused identity: a wrong user name or password (or a locked-out address)
IDENTITY_REFUSED = frozenset(
    {"BadUserAccessDenied", "BadIdentityTokenInvalid", "BadIdentityTokenRejected"}
)
#: status codes of a refused secure channel
CHANNEL_REFUSED = frozenset(
    {
        "BadSecurityPolicyRejected",
        "BadSecurityModeRejected",
        "BadCertificateInvalid",
        "BadCertificateUntrusted",
        "BadSecurityChecksFailed",
    }
)


class OpcUaBackend(Backend):
    protocol = "opcua"
    default_port = 4840

    def __init__(
        self,
        tagmap: ClientMap,
        host: str = "127.0.0.1",
        port: int | None = None,
        user: str | None = None,
        password: str | None = None,
        security: str = "Basic256Sha256",
        mode: str = "SignAndEncrypt",
        cert_dir: str | Path | None = None,
        timeout: float = 10.0,
        **_: Any,
    ) -> None:
        super().__init__(tagmap, host, port)
        if security not in ("None", "Basic256Sha256"):
            raise ClientError(f"security {security!r}: expected Basic256Sha256 or None")
        if mode not in MODES:
            raise ClientError(f"mode {mode!r}: expected {' or '.join(MODES)}")
        if security == "None" and user is not None:
            # the server refuses user names on a channel without security
            raise ClientError("a user name needs security Basic256Sha256, not None")
        self.endpoint = f"opc.tcp://{host}:{self.port}/"
        self.user, self.password = user, password
        self.security, self.mode = security, mode
        self.cert_dir = (
            Path(cert_dir) if cert_dir else Path(tempfile.gettempdir()) / "motion-client"
        )
        self.client = Client(self.endpoint, timeout=timeout)
        self.client.application_uri = CLIENT_URI
        self.ns = 0
        #: the most nodes one Read may carry (0: no limit), from the server
        self.max_read = 0

    async def connect(self) -> None:
        if self.security != "None":
            self.cert_dir.mkdir(parents=True, exist_ok=True)
            cert, key = await self.client.setup_self_signed_certificate(
                self.cert_dir / "client-key.pem", self.cert_dir / "client-cert.der"
            )
            await self.client.set_security(
                SecurityPolicyBasic256Sha256, str(cert), str(key), mode=MODES[self.mode]
            )
        if self.user is not None:
            self.client.set_user(self.user)
            self.client.set_password(self.password or "")
        with held_logs("asyncua"):
            try:
                await self.client.connect()
                self.ns = await self.client.get_namespace_index(self.map.namespace_uri)
                limit = await self.client.get_node(MAX_NODES_PER_READ).read_value()
                self.max_read = int(limit or 0)
            except (OSError, TimeoutError, ua.UaError, ValueError) as exc:
                await self.close()
                why = self._why(exc)
                raise ClientError(f"cannot connect to OPC UA {self.endpoint}: {why}") from None

    def _why(self, exc: BaseException) -> str:
        """The likely cause of a failed connection, in one line."""
        name = type(exc).__name__
        if name in IDENTITY_REFUSED:
            who = f"user {self.user!r}" if self.user is not None else "an anonymous session"
            return (
                f"{who} refused ({name}): a wrong user name or password, or this address "
                "is locked out for a while after repeated failures"
            )
        if name in CHANNEL_REFUSED:
            return (
                f"the secure channel was refused ({name}): the server offers no endpoint "
                f"with {self.security}/{self.mode}, or does not accept our certificate"
            )
        if isinstance(exc, ConnectionRefusedError):
            return connection_refused_hint("OPC UA", self.port)
        if isinstance(exc, TimeoutError):
            return "no answer in time (a wrong host or port, or a firewall)"
        if isinstance(exc, ua.UaStatusCodeError):
            return name
        if isinstance(exc, ValueError) and self.map.namespace_uri in str(exc):
            return (
                f"the server has no namespace {self.map.namespace_uri!r}: the tag map is "
                "not this server's site"
            )
        return f"{name}: {exc}"

    async def close(self) -> None:
        # a session that never opened, or a server already gone
        with contextlib.suppress(OSError, ua.UaError, AttributeError):
            await self.client.disconnect()

    def _node(self, tag: MapTag) -> Any:
        return self.client.get_node(ua.NodeId(tag.node_id, self.ns))

    async def read(self, tags: Sequence[MapTag]) -> list[Value]:
        step = self.max_read or max(len(tags), 1)
        values: list[Any] = []
        try:
            for start in range(0, len(tags), step):
                part = tags[start : start + step]
                values += await self.client.read_values([self._node(t) for t in part])
        except ua.UaStatusCodeError as exc:
            raise ClientError(f"read refused: {exc}") from None
        out: list[Value] = []
        for tag, v in zip(tags, values, strict=True):
            out.append(bool(v) if tag.type == "BOOL" else v)
        return out

    async def write(self, tag: MapTag, value: Value) -> None:
        if not tag.writable:
            raise ClientError(f"{tag.name} is read-only")
        variant = ua.Variant(tag.coerce(value), VARIANT[tag.type])
        try:
            await self._node(tag).write_value(ua.DataValue(variant))
        except ua.UaStatusCodeError as exc:
            raise ClientError(
                f"write {tag.name} = {value!r} refused by the server: {exc}"
            ) from None
