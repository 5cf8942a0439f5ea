"""OPC UA operation limits and per-session quotas, enforced and published.

asyncua 2.1 writes 10000 into every ``Server.ServerCapabilities.OperationLimits``
variable and enforces none of them: one Read may carry as many nodes as a message holds
(4 MiB of ReadValueIds is about 200,000 nodes and a second of the front-end's loop),
and any session may create subscriptions and monitored items until the server-wide
``max_subscriptions`` is reached, or add items to, and delete, another session's
subscriptions (its subscription service looks subscriptions up by id alone).

Here (numbers from the site map's ``[opcua]``, 0 meaning no limit, as in the
specification):

- :class:`OperationScreen` counts the operations of a request before asyncua decodes
  them (it reads the array length from the encoded body) and answers
  ``BadTooManyOperations`` above the limit: Read, Write, Browse,
  TranslateBrowsePathsToNodeIds, RegisterNodes and UnregisterNodes, Call, HistoryRead,
  AddNodes / AddReferences / DeleteNodes / DeleteReferences, and CreateMonitoredItems,
  ModifyMonitoredItems, SetMonitoringMode, DeleteMonitoredItems (``max_monitored_items_per_call``).
  TranslateBrowsePathsToNodeIds is also limited in the elements of all its paths
  together (``max_browse_path_elements_per_request``, ``BadTooManyOperations``): the
  path limit alone let 100 paths of 2,000 elements (3 MB) hold the process for seconds.
  The count walks the encoding and stops at the limit, so it costs no more than a
  request the limit allows.
- :class:`QuotaSession` gives each session at most ``max_subscriptions_per_session``
  subscriptions and all the sessions of one client address together at most
  ``max_subscriptions_per_client`` (``BadTooManySubscriptions``), and at most
  ``max_monitored_items_per_session`` monitored items (each item past the quota gets
  ``BadTooManyMonitoredItems``); it lets a session act on its own subscriptions only
  (``BadSubscriptionIdInvalid`` otherwise), and answers a browse path of more than
  ``max_browse_path_elements`` elements with ``BadQueryTooComplex`` (that path's result;
  OPC 10000-4 lists it among TranslateBrowsePathsToNodeIds' operation results: "the
  requested operation requires too many resources in the server").
- :func:`publish_capabilities` writes the limits into ``Server.ServerCapabilities``
  (``OperationLimits`` and the per-session quotas), so clients can split their requests.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from asyncua import Server, ua
from asyncua.common.utils import Buffer, ServiceError
from asyncua.server.internal_session import InternalSession
from asyncua.server.internal_subscription import InternalSubscription
from asyncua.ua.ua_binary import Primitives, extensionobject_from_binary, nodeid_from_binary

from ..config import OpcUaSection
from .opcua_users import PeerSession

Codes = ua.StatusCodes
ids = ua.ObjectIds


@dataclass(frozen=True)
class OperationLimits:
    """The most operations one request may carry (0: no limit) and the per-session quotas."""

    read: int = 0
    write: int = 0
    browse: int = 0
    translate: int = 0
    register: int = 0
    call: int = 0
    history_read: int = 0
    node_management: int = 0
    monitored_items_per_call: int = 0
    subscriptions_per_session: int = 0
    subscriptions_per_client: int = 0
    monitored_items_per_session: int = 0
    browse_path_elements: int = 0
    browse_path_elements_per_request: int = 0

    @classmethod
    def of(cls, cfg: OpcUaSection) -> OperationLimits:
        return cls(
            read=cfg.max_nodes_per_read,
            write=cfg.max_nodes_per_write,
            browse=cfg.max_nodes_per_browse,
            translate=cfg.max_nodes_per_translate_browse_paths,
            register=cfg.max_nodes_per_register_nodes,
            call=cfg.max_nodes_per_method_call,
            history_read=cfg.max_nodes_per_history_read,
            node_management=cfg.max_nodes_per_node_management,
            monitored_items_per_call=cfg.max_monitored_items_per_call,
            subscriptions_per_session=cfg.max_subscriptions_per_session,
            subscriptions_per_client=cfg.max_subscriptions_per_client,
            monitored_items_per_session=cfg.max_monitored_items_per_session,
            browse_path_elements=cfg.max_browse_path_elements,
            browse_path_elements_per_request=cfg.max_browse_path_elements_per_request,
        )


# -- counting operations in an encoded request ---------------------------------------------
Skip = Callable[[Buffer], Any]
_U32: Skip = Primitives.UInt32.unpack
_I32: Callable[[Buffer], int] = Primitives.Int32.unpack
_F64: Skip = Primitives.Double.unpack
_BOOL: Skip = Primitives.Boolean.unpack
_DATE: Skip = Primitives.DateTime.unpack
_NODE: Skip = nodeid_from_binary
_EXT: Skip = extensionobject_from_binary
_ITEMS = "monitored_items_per_call"

#: request encoding id -> (limit, the fields before the operations array)
SERVICES: dict[int, tuple[str, tuple[Skip, ...]]] = {
    ids.ReadRequest_Encoding_DefaultBinary: ("read", (_F64, _U32)),
    ids.WriteRequest_Encoding_DefaultBinary: ("write", ()),
    # View (ViewId, Timestamp, ViewVersion), RequestedMaxReferencesPerNode
    ids.BrowseRequest_Encoding_DefaultBinary: ("browse", (_NODE, _DATE, _U32, _U32)),
    ids.TranslateBrowsePathsToNodeIdsRequest_Encoding_DefaultBinary: ("translate", ()),
    ids.RegisterNodesRequest_Encoding_DefaultBinary: ("register", ()),
    ids.UnregisterNodesRequest_Encoding_DefaultBinary: ("register", ()),
    ids.CallRequest_Encoding_DefaultBinary: ("call", ()),
    # HistoryReadDetails, TimestampsToReturn, ReleaseContinuationPoints
    ids.HistoryReadRequest_Encoding_DefaultBinary: ("history_read", (_EXT, _U32, _BOOL)),
    ids.AddNodesRequest_Encoding_DefaultBinary: ("node_management", ()),
    ids.AddReferencesRequest_Encoding_DefaultBinary: ("node_management", ()),
    ids.DeleteNodesRequest_Encoding_DefaultBinary: ("node_management", ()),
    ids.DeleteReferencesRequest_Encoding_DefaultBinary: ("node_management", ()),
    # SubscriptionId, TimestampsToReturn / MonitoringMode
    ids.CreateMonitoredItemsRequest_Encoding_DefaultBinary: (_ITEMS, (_U32, _U32)),
    ids.ModifyMonitoredItemsRequest_Encoding_DefaultBinary: (_ITEMS, (_U32, _U32)),
    ids.SetMonitoringModeRequest_Encoding_DefaultBinary: (_ITEMS, (_U32, _U32)),
    ids.DeleteMonitoredItemsRequest_Encoding_DefaultBinary: (_ITEMS, (_U32,)),
}


def operations(typeid: ua.NodeId, body: Buffer) -> tuple[str, int] | None:
    """(limit name, number of operations) of an encoded request; None for a service
    without an operation limit. ``body`` (after the request header) is not consumed."""
    if typeid.NamespaceIndex != 0 or not isinstance(typeid.Identifier, int):
        return None
    service = SERVICES.get(typeid.Identifier)
    if service is None:
        return None
    limit, prefix = service
    buf = body.copy()
    try:
        for skip in prefix:
            skip(buf)
        count: int = Primitives.Int32.unpack(buf)
    except Exception:
        return None  # asyncua answers what does not decode
    return limit, max(count, 0)


_TRANSLATE = ids.TranslateBrowsePathsToNodeIdsRequest_Encoding_DefaultBinary


def browse_path_elements(body: Buffer, limit: int) -> int:
    """The elements of the browse paths of an encoded TranslateBrowsePathsToNodeIds
    request (``body`` after the request header, not consumed), counted until more than
    ``limit`` (the walk stops there). A body that does not decode counts what it held."""
    buf = body.copy()
    total = 0
    try:
        for _ in range(max(_I32(buf), 0)):
            nodeid_from_binary(buf)  # StartingNode
            count = max(_I32(buf), 0)  # RelativePath.Elements
            total += count
            if total > limit:
                return total
            for _ in range(count):
                nodeid_from_binary(buf)  # ReferenceTypeId
                buf.skip(2 + 2)  # IsInverse, IncludeSubtypes, TargetName.NamespaceIndex
                size = _I32(buf)  # TargetName.Name
                if size > 0:
                    buf.skip(size)
    except Exception:
        pass  # asyncua answers what does not decode
    return total


class OperationScreen:
    """The request screen of :class:`~.opcua_wire.GuardedProcessor`: more operations
    than the limit in one request is a ``BadTooManyOperations`` ServiceFault."""

    def __init__(self, limits: OperationLimits) -> None:
        self.limits = limits
        #: requests refused, per limit name (diagnostics, tests)
        self.refused: dict[str, int] = {}

    def __call__(self, typeid: ua.NodeId, body: Buffer, session: InternalSession) -> None:
        found = operations(typeid, body)
        if found is None:
            return
        name, count = found
        limit = getattr(self.limits, name)
        if limit and count > limit:
            self._refuse(name)
        elements = self.limits.browse_path_elements_per_request
        translate = name == "translate" and typeid.Identifier == _TRANSLATE
        if translate and elements and browse_path_elements(body, elements) > elements:
            self._refuse("browse_path_elements_per_request")

    def _refuse(self, name: str) -> None:
        self.refused[name] = self.refused.get(name, 0) + 1
        raise ServiceError(Codes.BadTooManyOperations)


# -- per-session quotas and ownership ---------------------------------------------------------
class QuotaSession(PeerSession):
    """A :class:`~.opcua_users.PeerSession` held to its quotas, acting on its own
    subscriptions only."""

    def __init__(
        self,
        *args: Any,
        limits: OperationLimits,
        peers: dict[ua.NodeId, str] | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, **kwargs)
        self.limits = limits
        #: the client address of every open session, by session id (shared by the
        #: front-end's sessions): whose subscriptions count against a client's quota
        self.peers = peers if peers is not None else {}
        self.peers[self.session_id] = self.client.address

    async def close_session(self, delete_subs: bool = True) -> None:
        try:
            await super().close_session(delete_subs)
        finally:
            self.peers.pop(self.session_id, None)

    def _client_held(self) -> int:
        """Subscriptions of every session from this session's client address."""
        address, peers = self.client.address, self.peers
        subs = self.subscription_service.subscriptions.values()
        return sum(1 for s in subs if peers.get(s.session_id) == address)

    def _own(self) -> list[InternalSubscription]:
        return [
            s
            for s in self.subscription_service.subscriptions.values()
            if s.session_id == self.session_id
        ]

    def _mine(self, sub_id: int) -> bool:
        sub = self.subscription_service.subscriptions.get(sub_id)
        return sub is not None and sub.session_id == self.session_id

    def _require(self, sub_id: int) -> None:
        if not self._mine(sub_id):
            raise ServiceError(Codes.BadSubscriptionIdInvalid)

    def _split(self, sub_ids: Iterable[int]) -> tuple[list[int], list[int]]:
        """Positions of this session's subscriptions and of the others."""
        mine: list[int] = []
        other: list[int] = []
        for i, sub_id in enumerate(sub_ids):
            (mine if self._mine(sub_id) else other).append(i)
        return mine, other

    async def create_subscription(
        self,
        params: ua.CreateSubscriptionParameters,
        callback: Callable[..., Any],
        request_callback: Callable[..., Any] | None = None,
    ) -> ua.CreateSubscriptionResult:
        quota = self.limits.subscriptions_per_session
        if quota and len(self._own()) >= quota:
            raise ServiceError(Codes.BadTooManySubscriptions)
        quota = self.limits.subscriptions_per_client
        if quota and self._client_held() >= quota:
            raise ServiceError(Codes.BadTooManySubscriptions)
        return await super().create_subscription(params, callback, request_callback)

    async def translate_browsepaths_to_nodeids(
        self, params: list[ua.BrowsePath]
    ) -> list[ua.BrowsePathResult]:
        limit = self.limits.browse_path_elements
        if not limit:
            return await super().translate_browsepaths_to_nodeids(params)
        short = [i for i, p in enumerate(params) if len(p.RelativePath.Elements) <= limit]
        done = await super().translate_browsepaths_to_nodeids([params[i] for i in short])
        too_complex = ua.BrowsePathResult(StatusCode=ua.StatusCode(Codes.BadQueryTooComplex))
        return _merge(len(params), short, done, too_complex)

    async def create_monitored_items(
        self, params: ua.CreateMonitoredItemsParameters
    ) -> list[ua.MonitoredItemCreateResult]:
        self._require(params.SubscriptionId)
        quota = self.limits.monitored_items_per_session
        items = params.ItemsToCreate
        if not quota:
            return await super().create_monitored_items(params)
        held = sum(len(s.monitored_item_srv._monitored_items) for s in self._own())
        room = max(quota - held, 0)
        results: list[ua.MonitoredItemCreateResult] = []
        if room:
            head = dataclasses.replace(params, ItemsToCreate=items[:room])
            results = list(await super().create_monitored_items(head))
        for _ in items[room:]:
            results.append(
                ua.MonitoredItemCreateResult(
                    StatusCode=ua.StatusCode(Codes.BadTooManyMonitoredItems)
                )
            )
        return results

    async def modify_monitored_items(
        self, params: ua.ModifyMonitoredItemsParameters
    ) -> list[ua.MonitoredItemModifyResult]:
        self._require(params.SubscriptionId)
        return await super().modify_monitored_items(params)

    async def delete_monitored_items(
        self, params: ua.DeleteMonitoredItemsParameters
    ) -> list[ua.StatusCode]:
        self._require(params.SubscriptionId)
        return await super().delete_monitored_items(params)

    async def set_monitoring_mode(
        self, params: ua.SetMonitoringModeParameters
    ) -> list[ua.StatusCode]:
        self._require(params.SubscriptionId)
        return await super().set_monitoring_mode(params)

    def modify_subscription(
        self, params: ua.ModifySubscriptionParameters
    ) -> ua.ModifySubscriptionResult:
        self._require(params.SubscriptionId)
        return super().modify_subscription(params)

    def republish(self, params: ua.RepublishParameters) -> ua.NotificationMessage:
        self._require(params.SubscriptionId)
        return super().republish(params)

    async def delete_subscriptions(self, ids: list[int]) -> list[ua.StatusCode]:
        mine, _ = self._split(ids)
        done = await super().delete_subscriptions([ids[i] for i in mine]) if mine else []
        return _merge(len(ids), mine, done, ua.StatusCode(Codes.BadSubscriptionIdInvalid))

    async def set_publishing_mode(
        self, params: ua.SetPublishingModeParameters
    ) -> list[ua.StatusCode]:
        sub_ids = params.SubscriptionIds
        mine, _ = self._split(sub_ids)
        part = dataclasses.replace(params, SubscriptionIds=[sub_ids[i] for i in mine])
        done = await super().set_publishing_mode(part) if mine else []
        return _merge(len(sub_ids), mine, done, ua.StatusCode(Codes.BadSubscriptionIdInvalid))

    def publish(
        self, acks: Iterable[ua.SubscriptionAcknowledgement] | None = None
    ) -> tuple[int, list[ua.StatusCode]]:
        acks = list(acks or [])
        mine, _ = self._split(a.SubscriptionId for a in acks)
        count, done = super().publish([acks[i] for i in mine])
        bad = ua.StatusCode(Codes.BadSubscriptionIdInvalid)
        return count, _merge(len(acks), mine, done, bad)

    async def transfer_subscriptions(
        self, params: ua.TransferSubscriptionsParameters, callback: Callable[..., Any]
    ) -> list[ua.TransferResult]:
        # a session's subscriptions go with it (see opcua_wire): no other session's to take
        return [
            ua.TransferResult(StatusCode=ua.StatusCode(Codes.BadUserAccessDenied))
            for _ in params.SubscriptionIds
        ]


def _merge(n: int, mine: list[int], done: list[Any], other: Any) -> list[Any]:
    """Results in request order: ``done`` at the positions ``mine``, ``other`` elsewhere."""
    out = [other] * n
    for i, result in zip(mine, done, strict=True):
        out[i] = result
    return out


# -- publishing -------------------------------------------------------------------------------
#: ServerCapabilities variable -> the limit it shows
CAPABILITIES: dict[int, str] = {
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerRead: "read",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerWrite: "write",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerBrowse: "browse",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerTranslateBrowsePathsToNodeIds: (
        "translate"
    ),
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerRegisterNodes: "register",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerMethodCall: "call",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerHistoryReadData: "history_read",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerHistoryReadEvents: "history_read",
    ids.Server_ServerCapabilities_OperationLimits_MaxNodesPerNodeManagement: "node_management",
    ids.Server_ServerCapabilities_OperationLimits_MaxMonitoredItemsPerCall: (
        "monitored_items_per_call"
    ),
    ids.Server_ServerCapabilities_MaxSubscriptionsPerSession: "subscriptions_per_session",
    # a subscription cannot hold more than its session may
    ids.Server_ServerCapabilities_MaxMonitoredItemsPerSubscription: "monitored_items_per_session",
}


async def publish_capabilities(server: Server, cfg: OpcUaSection) -> None:
    """Write the limits of ``cfg`` into ``Server.ServerCapabilities`` (UInt32 values, as
    the specification types them)."""
    limits = OperationLimits.of(cfg)
    values = {node: getattr(limits, name) for node, name in CAPABILITIES.items()}
    values[ids.Server_ServerCapabilities_MaxSessions] = cfg.max_sessions
    values[ids.Server_ServerCapabilities_MaxSubscriptions] = cfg.max_subscriptions
    for node, value in values.items():
        dv = ua.DataValue(ua.Variant(value, ua.VariantType.UInt32))
        await server.write_attribute_value(ua.NodeId(node), dv)
