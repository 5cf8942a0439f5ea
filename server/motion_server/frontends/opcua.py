"""OPC UA front-end (asyncua): the tag map as nodes, client writes into the tag image,
changed values published at a fixed rate.

Public surface::

    from motion_server.frontends.opcua import OpcUaFrontend

    ua_fe = OpcUaFrontend(view, site.opcua, users)   # view: an ImageView of the scan's image
    await ua_fe.start()      # certificate in data_dir (generated on first start), bind, publish
    ua_fe.port               # the bound TCP port (``port = 0`` in the site map: ephemeral)
    ua_fe.endpoint           # opc.tcp://host:port/
    ua_fe.namespace_index    # of the site's namespace URI (tagmap.namespace_uri)
    await ua_fe.publish()    # push changed values now (the runtime does this at the rate)
    await ua_fe.stop()

The OPC UA front-end process (:mod:`.process`) does all of this from the site map's
``[opcua]`` section.

Nodes: see :mod:`motion_server.tagmap.nodeset` (string NodeIds = ``tag.node_id`` in the
site's namespace, e.g. ``ns=<i>;s=Instructions.MAG_1.Ratio``).

Reads and publishing come from the scan's shared image (:class:`~.view.ImageView`);
writes are judged here and queued for the scan, the path Modbus writes take: operands
land in the instance's inputs at the start of the next cycle and the instance fires on
the rising edge of ``Execute`` in that cycle. Each item of a Write gets its own status:

- ``BadUserAccessDenied``: the session's role may not write this tag (viewer: nothing;
  operator: instruction inputs and hand-wheel inputs; admin: also ``Clock``), or an
  attribute other than Value;
- ``BadNotWritable``: a status (read-only) variable;
- ``BadTypeMismatch``: a Variant of another type than the node's DataType;
- ``BadOutOfRange``: a value the tag refuses (an unknown ``Clock.Mode``, a non-finite
  value, a position beyond the kernel's range);
- ``BadResourceUnavailable``: the scan takes no writes (it is gone).

The cam tables' array views (``Cams.<name>.MasterValues``, ``SlaveValues``,
``SegmentTypes``) are read from the element tags' slots and written as one judged batch
of them (:mod:`.opcua_arrays`, which lists their status codes).

A write to ``Clock.Step`` (manual clock) is answered once its cycles ran and their values
are published, so a client that reads after it sees the new cycle.

Security: Basic256Sha256 Sign and SignAndEncrypt endpoints (the site map's
``security_policies``), a self-signed server certificate and key generated in
``data_dir`` on first start and reused after; user name and password checked against
scrypt hashes (:mod:`.opcua_users`); anonymous sessions and the None endpoint only when
the site map sets ``allow_anonymous`` / ``allow_none_endpoint``. Client application
certificates are accepted without a trust list (a simulator's choice; see README).

Reads: the Value of a tag's node (and of its ValueAsText) is answered from the scan's
image through the node's ``value_callback`` (asyncua reads an attribute through it when
it has one): the newest snapshot, with this front-end's own writes the scan has not
applied yet laid over it. Every value of one Read request comes from one snapshot and
carries one timestamp (the Read service takes the snapshot once per request), so a Read
never shows two cycles, whatever a publishing pass is doing meanwhile. With a
``deadband``, an analog value within it of the value last published reads as that value.

Publishing: every ``1/publish_rate_hz`` seconds the newest snapshot is compared with the
values last published for every tag at once (numpy; analog values count as changed when
they moved by more than ``deadband``), the changed values are noted as published, and
the monitored items of the changed nodes are notified in slices that yield to the event
loop after ``chunk_size`` notifications or ``PUBLISH_SLICE_S`` of work, whichever comes
first, so requests run in between (the motion cycle runs in another process and never
waits for this one). A node nobody monitors costs nothing beyond the comparison. The
notifications of a client's subscription are encoded by :mod:`.opcua_notify` (about a
ninth of the time asyncua's generic serializer takes). Monitored items created with
queue size 0 get a queue of one (latest value), as the specification asks.

The wire (:mod:`.opcua_wire`): chunks are framed and judged before they are buffered
(one chunk per connection at most, nothing but a Hello before the Hello), every fatal
fault of a connection or its secure channel is answered with an Error message and the
connection closed (audited ``disconnect``, ``refused``, with the status code's name), a
user name is refused on a channel without security, and a session ends with its
connection, subscriptions included. Operation limits and per-session quotas
(:mod:`.opcua_limits`) are enforced and published in ``Server.ServerCapabilities``.
Writes refused to nodes outside the tag map (namespace 0, properties) are audited with
``node=`` and the status code's name, as refused tag writes are with ``tag=``. What
hostile traffic leaves in the log is one line per refused message, no traceback, and at
most 20 lines per 10 s (:mod:`.opcua_log`).

Silent clients: a session that receives no request for its session timeout (revised by
the server, at most ``max_session_timeout_s``) is closed by asyncua, and with it its
subscriptions. asyncua does not close the TCP connection then, though, and closes one
that never activates a session only after 30 s. So every ``idle_timeout`` / 4 (at most
1 s) the front-end closes the connections that received no byte for ``idle_timeout``
seconds (each connection notes when its last byte came), or, while they hold an
activated session, for that session's timeout if it is longer: a raw socket that never
says Hello, a client silent after its Hello, a connection whose session has timed out.
Closes are logged and audited (``disconnect``, ``idle timeout``).

A client's write of an instruction's BOOL input (``Execute``, ``Enable``) in realtime or
scaled time also notifies the monitored items of that instance's tags as soon as the
scan acknowledges the write (the cycle that took it is in the image), so a subscriber
sees its EN/DN/ER within a cycle or two instead of waiting for the next pass (a Read
shows them from that cycle on anyway).
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import os
import socket
import time
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
from asyncua import Server, ua
from asyncua.common.connection import TransportLimits
from asyncua.crypto.permission_rules import PermissionRuleset, User, UserRole
from asyncua.crypto.security_policies import SecurityPolicyFactory, SecurityPolicyNone
from asyncua.server.internal_session import InternalSession, SessionState
from asyncua.ua import status_codes

from ..config import OpcUaSection, OpcUaUser
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo
from ..safety.roles import Role, required_role
from ..tagmap import BadValueError, ClockMode, Folder, ReadOnlyError, Tag, TagType
from ..tagmap.nodeset import enum_text
from . import opcua_notify
from .certificates import self_signed
from .comm_faults import CommFaults
from .opcua_arrays import ArrayViews, RangeError
from .opcua_identity import identify
from .opcua_limits import OperationLimits, OperationScreen, QuotaSession, publish_capabilities
from .opcua_log import FloodGate
from .opcua_space import VARIANT_TYPES, build_space
from .opcua_users import Account, Directory, LoginLimiter, PeerSession, _peer
from .opcua_wire import ChannelFault, GuardedProtocol, Wire, WireServer
from .view import ImageView, ScanUnavailable, Ticket, WriteRefused, outcome

log = logging.getLogger("motion_server.opcua")

_POLICIES = {
    "Basic256Sha256_Sign": ua.SecurityPolicyType.Basic256Sha256_Sign,
    "Basic256Sha256_SignAndEncrypt": ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
}
#: after a trigger write: how long to wait for the scan's acknowledgement
FOLLOW_LIMIT_S = 0.5
#: the longest stretch of publishing work before a yield to the event loop
PUBLISH_SLICE_S = 0.001


@dataclass
class _Published:
    """One tag the publisher watches: its node, its last published value."""

    tag: Tag
    slot: int
    node_id: ua.NodeId
    vtype: ua.VariantType
    is_float: bool
    last: Any
    text_node: ua.NodeId | None = None  # ValueAsText of an enumerated value
    #: the node's Value attribute in asyncua's address space (set once serving)
    attval: Any = None
    #: the Value attribute of its ValueAsText node
    text_attval: Any = None
    #: reads of the node are answered from the image (:meth:`OpcUaFrontend._read`)
    served: bool = False

    def watched(self) -> bool:
        """Monitored items watch the node or its ValueAsText."""
        text = self.text_attval
        return bool(self.attval.datachange_callbacks) or (
            text is not None and bool(text.datachange_callbacks)
        )


def _is_loopback(host: str) -> bool:
    """True for a loopback address or the name localhost."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class OpcUaFrontend:
    """An OPC UA server for one tag image (see the module docstring)."""

    def __init__(
        self,
        image: ImageView,
        config: OpcUaSection | None = None,
        users: Iterable[OpcUaUser] | None = None,
        audit: AuditLog | None = None,
    ) -> None:
        self.image = image
        #: refused writes are audited here (accepted ones through the image's observers)
        self.audit = audit
        cfg = config or OpcUaSection()
        if (cfg.allow_anonymous or cfg.allow_none_endpoint) and not (
            cfg.allow_insecure_remote or _is_loopback(cfg.host)
        ):
            log.warning(
                "OPC UA: bound to %s, not loopback: anonymous access and the None endpoint are "
                "refused (set allow_insecure_remote to allow them off loopback)",
                cfg.host,
            )
            cfg = cfg.model_copy(update={"allow_anonymous": False, "allow_none_endpoint": False})
        self.config = cfg
        accounts = [
            Account(u.name, Role.named(u.role), u.password_hash)
            for u in (cfg.users if users is None else users)
        ]
        self.directory = Directory(
            accounts,
            allow_anonymous=cfg.allow_anonymous,
            anonymous_role=Role.named(cfg.anonymous_role),
            limiter=LoginLimiter(cfg.max_login_failures, cfg.login_window_s, cfg.login_lockout_s),
        )
        self.server: Server | None = None  # set once listening
        self._server: Server | None = None
        #: the guarded wire (opcua_wire) and the operation limits (opcua_limits)
        self.limits = OperationLimits.of(cfg)
        self.screen = OperationScreen(self.limits)
        #: the client address of each open session (the per-client subscription quota)
        self._peers: dict[ua.NodeId, str] = {}
        self.wire = Wire(cfg.max_chunk_size, self.screen, self._fault)
        #: the communication fault of the Clock tags (delayed or dropped answers); read
        #: from the scan's image (a bare tag image, as unit tests give, has none)
        self.comm_faults = CommFaults(image) if isinstance(image, ImageView) else None
        if self.comm_faults is not None:
            self.wire.answers = self.comm_faults.for_port
        self.namespace_index = 0
        self.port = 0
        self._published: list[_Published] = []
        self._standard_write: Any = None
        self._standard_read: Any = None
        #: the snapshot and time of the Read request being answered
        self._pinned: tuple[np.ndarray, datetime] | None = None
        self._by_node: dict[str, _Published] = {}
        #: the cam tables' array views (``Cams.<name>.MasterValues`` ...)
        self.arrays = ArrayViews(image)
        self._by_owner: dict[str, list[_Published]] = {}
        #: the values last published, one per image slot; which slots are analog
        self._last = np.zeros(0)
        self._analog = np.zeros(0, dtype=bool)
        #: every node is read from the image (no node needs asyncua's write path)
        self._all_served = True
        self._following: dict[str, asyncio.Task[None]] = {}
        self._task: asyncio.Task[None] | None = None
        self._idle_task: asyncio.Task[None] | None = None
        self._lock = asyncio.Lock()
        #: counters (diagnostics, benches)
        self.writes = 0
        self.refused = 0
        self.updates = 0
        self.passes = 0
        #: connections closed for silence
        self.idle_closed = 0
        #: the bound on the lines hostile traffic leaves in the log (opcua_log), while serving
        self.flood_gate: FloodGate | None = None

    # -- lifecycle ------------------------------------------------------------------------
    @property
    def endpoint(self) -> str:
        return f"opc.tcp://{self.config.host}:{self.port}/"

    async def start(self) -> None:
        cfg = self.config
        self.flood_gate = FloodGate()
        self.flood_gate.install()
        server = WireServer(self.wire, user_manager=self.directory)
        self._server = server
        # far below asyncua's 100 MB: a hostile peer cannot make us buffer much
        server.limits = TransportLimits(
            max_recv_buffer=cfg.max_chunk_size,
            max_send_buffer=cfg.max_chunk_size,
            max_chunk_count=cfg.max_chunk_count,
            max_message_size=cfg.max_message_size,
        )
        await server.init()
        await publish_capabilities(server, cfg)
        iserver = server.iserver
        iserver.max_connections = cfg.max_sessions
        iserver.max_subscriptions = cfg.max_subscriptions
        iserver.max_session_timeout_ms = cfg.max_session_timeout_s * 1000.0
        iserver.create_session = self._create_session
        server.set_server_name(f"motion-server {self.image.map.site}")
        uri = self.image.map.namespace_uri
        await identify(server, cfg)  # BuildInfo, certificate, its application URI
        policies = [_POLICIES[p] for p in cfg.security_policies]
        if cfg.allow_none_endpoint:
            policies.insert(0, ua.SecurityPolicyType.NoSecurity)
            log.warning("OPC UA: the None endpoint is enabled (no signing, no encryption)")
        server.set_security_policy(policies)
        tokens: list[type] = [ua.UserNameIdentityToken]
        if cfg.allow_anonymous:
            tokens.insert(0, ua.AnonymousIdentityToken)
            log.warning("OPC UA: anonymous sessions are enabled (role %s)", cfg.anonymous_role)
        server.set_identity_tokens(tokens)
        if not cfg.allow_none_endpoint:
            # asyncua accepts an unsecured channel even without a None endpoint (clients
            # need one for GetEndpoints); let such a channel do discovery and nothing else
            server._policies.append(
                SecurityPolicyFactory(
                    SecurityPolicyNone,
                    ua.MessageSecurityMode.None_,
                    permission_ruleset=_DiscoveryOnly(),
                )
            )
        port = cfg.port or _free_port(cfg.host)
        server.set_endpoint(f"opc.tcp://{cfg.host}:{port}/")
        self.namespace_index = await server.register_namespace(uri)
        space = await build_space(server, self.namespace_index, self.image)
        self._watch(space)
        self._standard_write = iserver.attribute_service.write
        iserver.attribute_service.write = self._write
        self._standard_read = iserver.attribute_service.read
        iserver.attribute_service.read = self._read
        self._patch_queue_size(server)
        self._live_diagnostics(server)
        await server.start()
        self.server = server
        self.port = port
        self._task = asyncio.create_task(self._publish_loop(), name="opcua-publisher")
        if cfg.idle_timeout > 0:
            self._idle_task = asyncio.create_task(
                self._close_idle(cfg.idle_timeout), name="opcua-idle-timeout"
            )
        log.info(
            "OPC UA on %s (%s), namespace %s, %d users",
            self.endpoint,
            ", ".join(p.name for p in policies),
            uri,
            len(self.directory.accounts),
        )

    async def stop(self) -> None:
        for task in (self._task, self._idle_task):
            if task is not None:
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task
        self._task = self._idle_task = None
        for task in list(self._following.values()):
            task.cancel()
        if self.server is not None:
            await self.server.stop()
            self.server = None
        if self.flood_gate is not None:
            self.flood_gate.flush()
            self.flood_gate.remove()

    async def _certificate(self, server: Server, app_uri: str) -> None:
        common_name = f"motion-server {self.image.map.site}"
        cert, key = await self_signed(self.config.data_dir, app_uri, common_name, "OPC UA")
        await server.load_certificate(str(cert))
        await server.load_private_key(str(key))

    # -- silent connections -----------------------------------------------------------------
    async def _close_idle(self, timeout: float) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await asyncio.sleep(min(timeout / 4, 1.0))
            if self.flood_gate is not None:
                self.flood_gate.flush()  # the lines a past flood left unsaid
            try:
                self._sweep(loop.time(), timeout)
            except Exception:  # keep watching whatever one pass hit
                log.exception("OPC UA: idle connection check failed")

    def _sweep(self, now: float, timeout: float) -> None:
        bserver = self.server.bserver if self.server is not None else None
        for proto in list(bserver.clients if bserver is not None else ()):
            last = proto.received_at if isinstance(proto, GuardedProtocol) else now
            limit = timeout
            session = proto.processor.session if proto.processor is not None else None
            if session is not None and session.state == SessionState.Activated:
                limit = max(timeout, session.session_timeout or 0.0)
            if now - last <= limit or proto.transport is None:
                continue
            self.idle_closed += 1
            client = (
                session.client_info()
                if isinstance(session, PeerSession)
                else ClientInfo("opcua", *_peer(proto.peer_name))
            )
            log.info("OPC UA connection %s silent for %.1f s: closed", client.key, now - last)
            if self.audit is not None:
                self.audit.connection(client, "disconnect", "idle timeout")
            proto.transport.close()

    def _create_session(
        self, name: str, user: User | None = None, external: bool = False
    ) -> InternalSession:
        assert self._server is not None
        iserver = self._server.iserver
        user = user if user is not None else User(role=UserRole.Anonymous)
        return QuotaSession(
            iserver,
            iserver.aspace,
            iserver.subscription_service,
            name,
            user=user,
            external=external,
            limits=self.limits,
            peers=self._peers,
        )

    def _fault(self, peer: Any, fault: ChannelFault) -> None:
        """A connection closed for a protocol fault (the Error message is on its way)."""
        if self.audit is not None:
            client = ClientInfo("opcua", *_peer(peer))
            self.audit.connection(client, "disconnect", "refused", fault.name)

    def _live_diagnostics(self, server: Server) -> None:
        """The standard server diagnostics a SCADA reads (Server.ServerDiagnostics): the
        current session and subscription counts, computed when read (asyncua leaves
        them at 0)."""
        iserver = server.iserver
        ids = ua.ObjectIds
        summary = {
            ids.Server_ServerDiagnostics_ServerDiagnosticsSummary_CurrentSessionCount: (
                lambda: InternalSession._current_connections
            ),
            ids.Server_ServerDiagnostics_ServerDiagnosticsSummary_CurrentSubscriptionCount: (
                lambda: len(iserver.subscription_service.subscriptions)
            ),
        }
        for node, count in summary.items():

            def read(nodeid: ua.NodeId, attr: Any, count: Any = count) -> ua.DataValue:
                return ua.DataValue(ua.Variant(int(count()), ua.VariantType.UInt32))

            iserver.aspace.set_attribute_value_callback(
                ua.NodeId(node), ua.AttributeIds.Value, read
            )
        enabled = ua.DataValue(ua.Variant(True, ua.VariantType.Boolean))
        iserver.aspace.set_attribute_value_callback(
            ua.NodeId(ids.Server_ServerDiagnostics_EnabledFlag),
            ua.AttributeIds.Value,
            lambda nodeid, attr: enabled,
        )

    def _patch_queue_size(self, server: Server) -> None:
        """Queue size 0 means a queue of one (latest value), not asyncua's unbounded; and
        monitored items keep the published DataValue instead of a deep copy of it."""
        service = server.iserver.subscription_service
        create = service.create_subscription

        async def create_subscription(*args: Any, **kwargs: Any) -> ua.CreateSubscriptionResult:
            result = await create(*args, **kwargs)
            isub = service.subscriptions[result.SubscriptionId]
            mis = isub.monitored_item_srv
            cap = isub.max_queue_size
            mis._revise_queue_size = lambda requested: min(max(int(requested), 1), cap)
            make_common = mis._make_monitored_item_common

            def make_monitored_item(params: ua.MonitoredItemCreateRequest) -> Any:
                result, mdata = make_common(params)
                mdata.mvalue = opcua_notify.SharedValues()
                return result, mdata

            mis._make_monitored_item_common = make_monitored_item
            # before any item exists: each item registers mis.datachange_callback
            mis.datachange_callback = opcua_notify.lean_datachange_callback(mis)
            enqueue = isub.enqueue_datachange_event

            async def enqueue_datachange_event(mid: int, event: Any, maxsize: int) -> None:
                await enqueue(mid, event, maxsize or 1)

            isub.enqueue_datachange_event = enqueue_datachange_event
            mis.create_monitored_items = opcua_notify.in_batches(mis.create_monitored_items)
            opcua_notify.install(isub)
            return result

        service.create_subscription = create_subscription

    # -- writes ---------------------------------------------------------------------------
    async def _write(
        self, params: ua.WriteParameters, user: User | None = None
    ) -> list[ua.StatusCode]:
        user = user if user is not None else User(role=UserRole.Admin)
        results: list[ua.StatusCode] = []
        for wv in params.NodesToWrite:
            nid = wv.NodeId
            ours = nid.NamespaceIndex == self.namespace_index and isinstance(nid.Identifier, str)
            if ours and nid.Identifier in self.arrays.by_node:
                code = await self._write_array(wv, user)
                if not code.is_good():
                    self._refused(code, node=nid.Identifier)
                results.append(code)
                continue
            pub = self._by_node.get(nid.Identifier) if ours else None
            if pub is None:  # another namespace, or a property: asyncua's own rules
                single = ua.WriteParameters(NodesToWrite=[wv])
                codes = await self._standard_write(single, user=user)
                for code in codes:
                    if not code.is_good():
                        self._refused(code, node=nid.to_string())
                results += codes
                continue
            code = await self._write_tag(pub, wv, user)
            if not code.is_good():
                self._refused(code, tag=pub.tag.name)
            results.append(code)
        return results

    def _refused(self, code: ua.StatusCode, **what: str) -> None:
        """Count and audit one refused write item (``tag=`` or, outside the tag map,
        ``node=``)."""
        self.refused += 1
        if self.audit is not None:
            self.audit.refused(status_codes.get_name_and_doc(code.value)[0], **what)

    async def _write_tag(self, pub: _Published, wv: ua.WriteValue, user: User) -> ua.StatusCode:
        tag = pub.tag
        internal = user.role == UserRole.Admin and user.name is None
        if wv.AttributeId != ua.AttributeIds.Value or wv.IndexRange:
            return ua.StatusCode(ua.StatusCodes.BadUserAccessDenied)
        if not tag.writable:
            return ua.StatusCode(ua.StatusCodes.BadNotWritable)
        if not internal:
            role = self.directory.role_of(user)
            if role is None or role < required_role(tag):
                who = user.name or "anonymous"
                log.info("OPC UA: write of %s by %s refused (role)", tag.name, who)
                return ua.StatusCode(ua.StatusCodes.BadUserAccessDenied)
        var = wv.Value.Value if wv.Value is not None else None
        if var is None or var.VariantType != pub.vtype or var.is_array or var.Value is None:
            return ua.StatusCode(ua.StatusCodes.BadTypeMismatch)
        try:
            ticket = self.image.write(tag, var.Value)
        except ReadOnlyError:
            return ua.StatusCode(ua.StatusCodes.BadNotWritable)
        except BadValueError as exc:
            log.info("OPC UA: write of %s refused: %s", tag.name, exc)
            return ua.StatusCode(ua.StatusCodes.BadOutOfRange)
        except ScanUnavailable as exc:
            log.warning("OPC UA: write of %s: %s", tag.name, exc)
            return ua.StatusCode(ua.StatusCodes.BadResourceUnavailable)
        except Exception:  # never let one item take the request (or the server) down
            log.exception("OPC UA: write of %s failed", tag.name)
            return ua.StatusCode(ua.StatusCodes.BadInternalError)
        self.writes += 1
        await self._set(pub, self.image.read(tag), _now())
        if ticket.waits:
            try:
                # a Clock.Step: answer once its cycles ran; a snapshot once it is done
                await outcome(ticket)
            except ScanUnavailable:
                return ua.StatusCode(ua.StatusCodes.BadResourceUnavailable)
            except WriteRefused as exc:  # the reason is in the log (the scan's)
                log.info("OPC UA: write of %s: %s", tag.name, exc)
                return ua.StatusCode(ua.StatusCodes.BadInvalidState)
            await self.publish()
        elif tag.folder == Folder.INSTRUCTIONS and tag.type == TagType.BOOL:
            self._follow(tag.owner, ticket)
        return ua.StatusCode()

    async def _write_array(self, wv: ua.WriteValue, user: User) -> ua.StatusCode:
        """A write of a cam table's array view: one judged batch of its element tags
        (:mod:`.opcua_arrays`)."""
        if wv.AttributeId != ua.AttributeIds.Value:
            return ua.StatusCode(ua.StatusCodes.BadUserAccessDenied)
        try:
            updates = self.arrays.updates(wv)
        except RangeError as exc:
            return ua.StatusCode(exc.code)
        internal = user.role == UserRole.Admin and user.name is None
        if not internal:
            role = self.directory.role_of(user)
            if role is None or any(role < required_role(t) for t, _ in updates):
                log.info(
                    "OPC UA: write of %s by %s refused (role)",
                    wv.NodeId.Identifier,
                    user.name or "anonymous",
                )
                return ua.StatusCode(ua.StatusCodes.BadUserAccessDenied)
        try:
            ticket = self.image.write_many(updates)
        except ReadOnlyError:
            return ua.StatusCode(ua.StatusCodes.BadNotWritable)
        except BadValueError as exc:
            log.info("OPC UA: write of %s refused: %s", wv.NodeId.Identifier, exc)
            return ua.StatusCode(ua.StatusCodes.BadOutOfRange)
        except ScanUnavailable as exc:
            log.warning("OPC UA: write of %s: %s", wv.NodeId.Identifier, exc)
            return ua.StatusCode(ua.StatusCodes.BadResourceUnavailable)
        except Exception:  # never let one item take the request (or the server) down
            log.exception("OPC UA: write of %s failed", wv.NodeId.Identifier)
            return ua.StatusCode(ua.StatusCodes.BadInternalError)
        self.writes += 1
        if ticket.waits:
            try:
                await outcome(ticket)
            except ScanUnavailable:
                return ua.StatusCode(ua.StatusCodes.BadResourceUnavailable)
            except WriteRefused as exc:
                log.info("OPC UA: write of %s: %s", wv.NodeId.Identifier, exc)
                return ua.StatusCode(ua.StatusCodes.BadInvalidState)
        return ua.StatusCode()

    def _follow(self, owner: str, ticket: Ticket) -> None:
        """Publish ``owner``'s tags once the cycle that took the write is in the image
        (clock running: the scan acknowledges a write with the cycle it ran in)."""
        if owner in self._following or self.image.mode == ClockMode.MANUAL:
            return
        task = asyncio.create_task(self._publish_owner(owner, ticket))
        self._following[owner] = task
        task.add_done_callback(lambda _: self._following.pop(owner, None))

    async def _publish_owner(self, owner: str, ticket: Ticket) -> None:
        try:
            await asyncio.wait_for(ticket.done(), FOLLOW_LIMIT_S)
        except (TimeoutError, ScanUnavailable):
            return
        now = _now()
        values = self.image.values()
        for pub in self._by_owner.get(owner, []):
            raw = values[pub.slot]
            if raw != self._last[pub.slot]:
                self._last[pub.slot] = raw
                await self._set(pub, self.image.typed(pub.slot, float(raw)), now)

    # -- publishing -----------------------------------------------------------------------
    def _watch(self, space: dict[str, Any]) -> None:
        assert self._server is not None
        ns = self.namespace_index
        nodes = getattr(self._server.iserver.aspace, "_nodes", {})
        image = self.image
        values = image.values()
        for tag in image.map:
            text = f"{tag.node_id}.ValueAsText" if tag.enum is not None else None
            node_id = ua.NodeId(tag.node_id, ns)
            node = nodes.get(node_id)
            slot = image.slot(tag)
            pub = _Published(
                tag,
                slot,
                node_id,
                VARIANT_TYPES[tag.type],
                tag.type.is_float,
                image.typed(slot, float(values[slot])),
                ua.NodeId(text, ns) if text in space else None,
                node.attributes.get(ua.AttributeIds.Value) if node is not None else None,
            )
            if pub.text_node is not None:
                text_node = nodes.get(pub.text_node)
                if text_node is not None:
                    pub.text_attval = text_node.attributes.get(ua.AttributeIds.Value)
            self._serve_from_image(pub)
            self._published.append(pub)
            self._by_node[tag.node_id] = pub
            self._by_owner.setdefault(tag.owner, []).append(pub)
        self._published.sort(key=lambda p: p.slot)
        self._last = values.copy()
        self.arrays.serve(nodes, ns, self._snapshot)
        self._analog = np.array([p.is_float for p in self._published], dtype=bool)
        self._all_served = all(p.served for p in self._published)

    def _serve_from_image(self, pub: _Published) -> None:
        """Answer reads of ``pub``'s Value (and ValueAsText) from the image: asyncua reads
        an attribute through its ``value_callback`` when it has one. A node another
        component gave a ``value_setter`` keeps asyncua's own write path."""
        att, text = pub.attval, pub.text_attval
        if att is None or att.value_setter is not None:
            return
        if pub.text_node is not None and (text is None or text.value_setter is not None):
            return
        pub.served = True
        att.value_callback = lambda nodeid, attr, pub=pub: self._read_value(pub)
        if text is not None:
            text.value_callback = lambda nodeid, attr, pub=pub: self._read_text(pub)

    def _read(self, params: ua.ReadParameters) -> list[ua.DataValue]:
        """The Read service: every tag value of one request comes from one snapshot
        (whatever a publishing pass is doing meanwhile), stamped with one time."""
        self._pinned = (self.image.values(), _now())
        try:
            results: list[ua.DataValue] = self._standard_read(params)
            if self.arrays.by_node:
                self._read_ranges(params, results)
        finally:
            self._pinned = None
        return results

    def _read_ranges(self, params: ua.ReadParameters, results: list[ua.DataValue]) -> None:
        """The array views read with an IndexRange: their slice (asyncua's Read gives a
        value callback's whole value)."""
        assert self._pinned is not None
        values, now = self._pinned
        for k, rv in enumerate(params.NodesToRead):
            nid = rv.NodeId
            if (
                rv.IndexRange
                and rv.AttributeId == ua.AttributeIds.Value
                and nid.NamespaceIndex == self.namespace_index
                and nid.Identifier in self.arrays.by_node
                and k < len(results)
            ):
                results[k] = self.arrays.read_range(nid.Identifier, rv.IndexRange, values, now)

    def _snapshot(self) -> tuple[np.ndarray, datetime]:
        """The values a Read shows (those the Read being answered took) and its time."""
        pinned = self._pinned
        return pinned if pinned is not None else (self.image.values(), _now())

    def _current(self, pub: _Published) -> tuple[Any, datetime]:
        """``pub``'s value as a Read shows it: from the newest snapshot (or the one the
        Read being answered took); an analog value within the deadband of the value last
        published reads as that value."""
        pinned = self._pinned
        values, now = pinned if pinned is not None else (self.image.values(), _now())
        slot = pub.slot
        raw = float(values[slot])
        deadband = self.config.deadband
        if deadband and pub.is_float:
            last = float(self._last[slot])
            if abs(raw - last) <= deadband:
                raw = last
        return self.image.typed(slot, raw), now

    def _read_value(self, pub: _Published) -> ua.DataValue:
        value, now = self._current(pub)
        return _datavalue(pub, value, now)

    def _read_text(self, pub: _Published) -> ua.DataValue:
        value, _ = self._current(pub)
        return _text(pub, value)

    async def _set(self, pub: _Published, value: Any, now: datetime) -> None:
        """Notify the monitored items of ``pub`` (and of its ValueAsText) of ``value``."""
        if not pub.served:
            await self._write_slow(pub, value, now)
            return
        if pub.watched():
            await self._notify(pub, value, _datavalue(pub, value, now))

    async def _notify(self, pub: _Published, value: Any, dv: ua.DataValue) -> None:
        for handle, callback in list(pub.attval.datachange_callbacks.items()):
            try:
                await callback(handle, dv)
            except Exception:
                log.exception("OPC UA: data-change callback of %s failed", pub.tag.name)
        text = pub.text_attval
        if text is not None and text.datachange_callbacks:
            tdv = _text(pub, value)
            for handle, callback in list(text.datachange_callbacks.items()):
                try:
                    await callback(handle, tdv)
                except Exception:
                    log.exception("OPC UA: data-change callback of %s failed", pub.tag.name)

    async def _write_slow(self, pub: _Published, value: Any, now: datetime) -> None:
        """A node that asyncua's own write path must set (it has a ``value_setter``)."""
        assert self._server is not None
        pub.last = value
        await self._server.write_attribute_value(pub.node_id, _datavalue(pub, value, now))
        if pub.text_node is not None:
            await self._server.write_attribute_value(pub.text_node, _text(pub, value))

    @staticmethod
    def _notify_failed(node: str) -> None:
        log.exception("OPC UA: data-change callback of %s failed", node)

    async def publish(self) -> int:
        """Push the values that changed since they were last published; returns how many."""
        async with self._lock:
            return await self._publish_pass()

    async def _publish_pass(self) -> int:
        """One pass: the values that changed in the newest snapshot since the last pass
        (beyond the deadband) are noted at once, then the monitored items of those nodes
        are notified in slices that yield to requests. Nodes nobody monitors cost nothing
        more: a Read takes its values from the image (:meth:`_read`)."""
        deadband = self.config.deadband
        values = self.image.values()
        last = self._last
        moved = values != last
        if deadband:
            moved &= ~(self._analog & (np.abs(values - last) <= deadband))
        changed = np.flatnonzero(moved)
        last[changed] = values[changed]
        now = _now()
        pubs = self._published
        typed = self.image.typed
        slices = _Slices(self.config.chunk_size)
        server = self._server
        idle = (
            server is not None
            and not server.iserver.subscription_service.subscriptions
            and self._all_served
        )
        for k in [] if idle else changed.tolist():  # idle: no subscription to notify
            pub = pubs[k]
            if pub.served:
                if not pub.watched():
                    continue
                value = typed(k, float(values[k]))
                await self._notify(pub, value, _datavalue(pub, value, now))
            else:
                await self._write_slow(pub, typed(k, float(values[k])), now)
            await slices.after_update()
        if len(changed) and self.arrays.by_node:
            await self.arrays.notify(values, now, self._notify_failed)
        self.updates += len(changed)
        self.passes += 1
        return len(changed)

    async def _publish_loop(self) -> None:
        period = 1.0 / self.config.publish_rate_hz
        loop = asyncio.get_running_loop()
        deadline = loop.time()
        while True:
            deadline += period
            try:
                await self.publish()
            except Exception:  # keep publishing whatever one pass hit
                log.exception("OPC UA: publish pass failed")
            now = loop.time()
            if deadline < now:  # a slow pass: do not try to catch up
                deadline = now
            await asyncio.sleep(deadline - now)


class _Slices:
    """Where a publishing pass yields to the event loop: after ``chunk`` node updates or
    ``PUBLISH_SLICE_S`` of work, whichever comes first.

    It yields the CPU too (``sched_yield``): Linux's EEVDF scheduler lets a busy process
    run out its slice (about 1.5 ms on two cores) before a process that wakes on the
    same CPU, a Modbus client polling DN on this machine for one, even while the other
    CPU is idle; the yield hands the CPU over at once when someone waits, and costs a
    system call when nobody does."""

    def __init__(self, chunk: int) -> None:
        self.chunk = chunk
        self._restart()

    def _restart(self) -> None:
        self.budget = self.chunk
        self.end = time.perf_counter() + PUBLISH_SLICE_S

    async def _yield_if(self, due: bool) -> bool:
        if due or time.perf_counter() > self.end:
            os.sched_yield()
            await asyncio.sleep(0)
            self._restart()
            return True
        return False

    async def after_update(self) -> bool:
        """Count one node update; True if the pass yielded (other cycles may have run)."""
        self.budget -= 1
        return await self._yield_if(self.budget <= 0)


class _DiscoveryOnly(PermissionRuleset):
    """Refuses every service a session uses (discovery and session set-up are never checked)."""

    def check_validity(self, user: Any, action_type_id: Any, body: Any) -> bool:
        return False


def _now() -> datetime:
    return datetime.now(UTC)


_GOOD = ua.StatusCode()
_new = object.__new__


def _datavalue(pub: _Published, value: Any, now: datetime) -> ua.DataValue:
    """``value`` (typed by :meth:`ImageView.typed`: bool, int or float) as the node's
    DataValue. The Variant is made without ``Variant.__post_init__``, which guesses and
    checks the type of any value and took most of the time of a data-change notification
    (2.5 against 0.7 us): its result for a scalar of a known type is these four fields."""
    var = _new(ua.Variant)
    var.Value = value
    var.VariantType = pub.vtype
    var.Dimensions = None
    var.is_array = False
    return ua.DataValue(var, StatusCode=_GOOD, SourceTimestamp=now, ServerTimestamp=now)


def _text(pub: _Published, value: Any) -> ua.DataValue:
    label = ua.LocalizedText(enum_text(pub.tag, value))
    return ua.DataValue(ua.Variant(label, ua.VariantType.LocalizedText))


def _free_port(host: str) -> int:
    """An ephemeral TCP port on ``host`` (the endpoint URL must carry the real port)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


__all__ = ["OpcUaFrontend", "Role", "required_role"]
