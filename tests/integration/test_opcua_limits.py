"""OPC UA operation limits and per-session quotas (real sockets, secure channels).

The site sets every limit small (``LIMITS``): a request carrying one operation more than
its limit is answered ``BadTooManyOperations`` (OPC 10000-4, 7.38.2: the service result
when "the request could not be processed because it specified too many operations");
one carrying exactly the limit is served. The limits are published where clients look
for them (``Server.ServerCapabilities.OperationLimits``, ``MaxSubscriptionsPerSession``,
``MaxMonitoredItemsPerSubscription``). A session holds at most its quota of
subscriptions (``BadTooManySubscriptions``) and monitored items (each item past it:
``BadTooManyMonitoredItems``) and touches only its own subscriptions.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio
from asyncua import Client, ua

from motion_server import config
from motion_server.frontends.opcua_limits import CAPABILITIES, OperationLimits
from motion_server.runtime import Runtime
from tests.opcua_support import SITE, USERS, running, secure_client, user_hashes

pytestmark = pytest.mark.asyncio(loop_scope="module")
Codes = ua.StatusCodes
NS_URI = "urn:motion-server:opcua-test"
LIMITS = {
    "max_nodes_per_read": 5,
    "max_nodes_per_write": 4,
    "max_nodes_per_browse": 3,
    "max_nodes_per_translate_browse_paths": 3,
    "max_nodes_per_register_nodes": 3,
    "max_nodes_per_method_call": 2,
    "max_nodes_per_history_read": 2,
    "max_nodes_per_node_management": 2,
    "max_monitored_items_per_call": 6,
    "max_subscriptions_per_session": 2,
    "max_monitored_items_per_session": 8,
}


def limits_site(data_dir: Path) -> config.SiteMap:
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in user_hashes().items()
    )
    text = SITE.format(
        data_dir=data_dir, anonymous="false", none_endpoint="false", lockout=0.0, users=users
    )
    fields = "".join(f"{name} = {value}\n" for name, value in LIMITS.items())
    return config.parse(text.replace("[opcua]\n", "[opcua]\n" + fields, 1), "limits.toml")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rt(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Runtime]:
    async with running(limits_site(tmp_path_factory.mktemp("opcua"))) as runtime:
        yield runtime


@pytest.fixture(scope="module")
def client_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("client")


async def connect(rt: Runtime, client_dir: Path, user: str = "admin") -> Client:
    client = await secure_client(rt, client_dir, user)
    await client.connect()
    return client


async def outcome(call: Awaitable[Any]) -> int:
    """The service result of a request: 0 (Good) or the ServiceFault's code."""
    try:
        await call
    except ua.UaStatusCodeError as exc:
        return int(exc.code)
    return 0


def node(ns: int, name: str) -> ua.NodeId:
    return ua.NodeId(name, ns)


def requests(client: Client, ns: int, sub_id: int) -> dict[str, Callable[[int], Awaitable[Any]]]:
    """One request per limit, with ``n`` operations."""
    uc = client.uaclient
    cycle = node(ns, "Clock.Cycle")
    speed = node(ns, "Instructions.MAJ_1.Speed")
    objects = ua.NodeId(ua.ObjectIds.ObjectsFolder)

    def read(n: int) -> Awaitable[Any]:
        ids = [ua.ReadValueId(NodeId=cycle, AttributeId=ua.AttributeIds.Value)] * n
        return uc.read(ua.ReadParameters(NodesToRead=ids))

    def write(n: int) -> Awaitable[Any]:
        dv = ua.DataValue(ua.Variant(10.0, ua.VariantType.Float))
        item = ua.WriteValue(NodeId=speed, AttributeId=ua.AttributeIds.Value, Value=dv)
        return uc.write(ua.WriteParameters(NodesToWrite=[item] * n))

    def browse(n: int) -> Awaitable[Any]:
        desc = ua.BrowseDescription(NodeId=objects, ResultMask=ua.BrowseResultMask.All)
        return uc.browse(ua.BrowseParameters(NodesToBrowse=[desc] * n))

    def translate(n: int) -> Awaitable[Any]:
        step = ua.RelativePathElement(
            ReferenceTypeId=ua.NodeId(ua.ObjectIds.HierarchicalReferences),
            IncludeSubtypes=True,
            TargetName=ua.QualifiedName("Server", 0),
        )
        path = ua.BrowsePath(StartingNode=objects, RelativePath=ua.RelativePath(Elements=[step]))
        return uc.translate_browsepaths_to_nodeids([path] * n)

    def call(n: int) -> Awaitable[Any]:
        method = ua.CallMethodRequest(
            ObjectId=ua.NodeId(ua.ObjectIds.Server),
            MethodId=ua.NodeId(ua.ObjectIds.Server_GetMonitoredItems),
            InputArguments=[ua.Variant(sub_id, ua.VariantType.UInt32)],
        )
        return uc.call([method] * n)

    def history(n: int) -> Awaitable[Any]:
        item = ua.HistoryReadValueId(NodeId=cycle)
        params = ua.HistoryReadParameters(
            HistoryReadDetails=ua.ReadRawModifiedDetails(), NodesToRead=[item] * n
        )
        return uc.history_read(params)

    def add_nodes(n: int) -> Awaitable[Any]:
        return uc.add_nodes([ua.AddNodesItem(ParentNodeId=objects)] * n)

    def delete_refs(n: int) -> Awaitable[Any]:
        return uc.delete_references([ua.DeleteReferencesItem(SourceNodeId=objects)] * n)

    def create_items(n: int) -> Awaitable[Any]:
        item = ua.MonitoredItemCreateRequest(
            ItemToMonitor=ua.ReadValueId(NodeId=cycle, AttributeId=ua.AttributeIds.Value),
            MonitoringMode=ua.MonitoringMode.Reporting,
            RequestedParameters=ua.MonitoringParameters(QueueSize=1, SamplingInterval=100),
        )
        params = ua.CreateMonitoredItemsParameters(SubscriptionId=sub_id, ItemsToCreate=[item] * n)
        return uc.create_monitored_items(params)

    def delete_items(n: int) -> Awaitable[Any]:
        params = ua.DeleteMonitoredItemsParameters(SubscriptionId=sub_id, MonitoredItemIds=[1] * n)
        return uc.delete_monitored_items(params)

    def monitoring_mode(n: int) -> Awaitable[Any]:
        params = ua.SetMonitoringModeParameters(
            SubscriptionId=sub_id,
            MonitoringMode=ua.MonitoringMode.Sampling,
            MonitoredItemIds=[1] * n,
        )
        return uc.set_monitoring_mode(params)

    return {
        "max_nodes_per_read": read,
        "max_nodes_per_write": write,
        "max_nodes_per_browse": browse,
        "max_nodes_per_translate_browse_paths": translate,
        "max_nodes_per_register_nodes": lambda n: uc.register_nodes([cycle] * n),
        "max_nodes_per_register_nodes (unregister)": lambda n: uc.unregister_nodes([cycle] * n),
        "max_nodes_per_method_call": call,
        "max_nodes_per_history_read": history,
        "max_nodes_per_node_management": add_nodes,
        "max_nodes_per_node_management (delete references)": delete_refs,
        "max_monitored_items_per_call": create_items,
        "max_monitored_items_per_call (delete)": delete_items,
        "max_monitored_items_per_call (monitoring mode)": monitoring_mode,
    }


async def test_the_limits_are_published_in_the_server_capabilities(
    rt: Runtime, client_dir: Path
) -> None:
    assert rt.opcua is not None
    client = await connect(rt, client_dir, "viewer")
    try:
        limits = OperationLimits.of(rt.opcua.config)
        for node_id, name in CAPABILITIES.items():
            value = await client.get_node(ua.NodeId(node_id)).read_value()
            assert value == getattr(limits, name) != 0, name
        assert limits.read == LIMITS["max_nodes_per_read"]
        ids = ua.ObjectIds
        sessions = client.get_node(ua.NodeId(ids.Server_ServerCapabilities_MaxSessions))
        assert await sessions.read_value() == rt.opcua.config.max_sessions
    finally:
        await client.disconnect()


async def test_each_operation_limit_is_answered_with_bad_too_many_operations(
    rt: Runtime, client_dir: Path
) -> None:
    client = await connect(rt, client_dir)
    try:
        ns = await client.get_namespace_index(NS_URI)
        sub = await client.create_subscription(100, None)
        for label, request in requests(client, ns, sub.subscription_id).items():
            limit = LIMITS[label.split(" ")[0]]
            assert await outcome(request(limit + 1)) == Codes.BadTooManyOperations, label
            # exactly the limit is served (node management is for admins of asyncua only)
            served = Codes.BadUserAccessDenied if "node_management" in label else 0
            assert await outcome(request(limit)) == served, label
        await sub.delete()
    finally:
        await client.disconnect()


async def test_a_session_holds_at_most_its_quota_of_subscriptions_and_items(
    rt: Runtime, client_dir: Path
) -> None:
    a = await connect(rt, client_dir, "viewer")
    b = await connect(rt, client_dir, "viewer")
    try:
        ns = await a.get_namespace_index(NS_URI)
        nodes = [a.get_node(node(ns, f"Axes.Axis1.{f}")) for f in ("ActualPosition",) * 6]
        first = await a.create_subscription(100, None)
        second = await a.create_subscription(100, None)
        with pytest.raises(ua.UaStatusCodeError) as refused:
            await a.create_subscription(100, None)
        assert refused.value.code == Codes.BadTooManySubscriptions
        other = await b.create_subscription(100, None)  # another session is not held back
        assert all(isinstance(h, int) for h in await first.subscribe_data_change(nodes))
        results = await second.subscribe_data_change(nodes[:4])  # 6 + 4 > 8
        assert [isinstance(r, int) for r in results] == [True, True, False, False]
        assert all(r.value == Codes.BadTooManyMonitoredItems for r in results[2:])
        assert all(isinstance(h, int) for h in await other.subscribe_data_change(nodes))
    finally:
        await a.disconnect()
        await b.disconnect()


async def test_a_session_touches_only_its_own_subscriptions(rt: Runtime, client_dir: Path) -> None:
    a = await connect(rt, client_dir, "viewer")
    b = await connect(rt, client_dir, "viewer")
    try:
        ns = await a.get_namespace_index(NS_URI)
        sub = await a.create_subscription(100, None)
        handle = await sub.subscribe_data_change(a.get_node(node(ns, "Clock.Cycle")))
        theirs = sub.subscription_id
        codes = await b.uaclient.delete_subscriptions([theirs])
        assert [c.value for c in codes] == [Codes.BadSubscriptionIdInvalid]
        item = ua.MonitoredItemCreateRequest(
            ItemToMonitor=ua.ReadValueId(
                NodeId=node(ns, "Clock.Cycle"), AttributeId=ua.AttributeIds.Value
            ),
            MonitoringMode=ua.MonitoringMode.Reporting,
        )
        steal = ua.CreateMonitoredItemsParameters(SubscriptionId=theirs, ItemsToCreate=[item])
        assert await outcome(b.uaclient.create_monitored_items(steal)) == (
            Codes.BadSubscriptionIdInvalid
        )
        drop = ua.DeleteMonitoredItemsParameters(SubscriptionId=theirs, MonitoredItemIds=[handle])
        assert await outcome(b.uaclient.delete_monitored_items(drop)) == (
            Codes.BadSubscriptionIdInvalid
        )
        assert [c.value for c in await a.uaclient.delete_subscriptions([theirs])] == [0]
    finally:
        await a.disconnect()
        await b.disconnect()
