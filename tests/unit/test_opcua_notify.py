"""Data-change notifications encoded by hand: byte for byte what asyncua writes for the
same notification, and decoded by asyncua into the same values."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from asyncua import ua
from asyncua.ua.ua_binary import extensionobject_to_binary, struct_from_binary, struct_to_binary

from motion_server.frontends.opcua_notify import (
    encode_datavalue,
    encoded_datachanges,
    install,
)

NOW = datetime(2026, 3, 1, 12, 30, 15, 123456, tzinfo=UTC)
LATER = NOW + timedelta(milliseconds=2)

#: one value of every Variant type the tag map uses, at the edges of its range
SCALARS: list[tuple[Any, ua.VariantType]] = [
    (True, ua.VariantType.Boolean),
    (False, ua.VariantType.Boolean),
    (-128, ua.VariantType.SByte),
    (127, ua.VariantType.SByte),
    (-32768, ua.VariantType.Int16),
    (-(2**31), ua.VariantType.Int32),
    (2**31 - 1, ua.VariantType.Int32),
    (2**32 - 1, ua.VariantType.UInt32),
    (123.4567, ua.VariantType.Float),
    (-0.1, ua.VariantType.Double),
    (float("inf"), ua.VariantType.Double),
    (1e308, ua.VariantType.Double),
]


def datavalues() -> list[ua.DataValue]:
    out = [
        ua.DataValue(ua.Variant(v, t), SourceTimestamp=NOW, ServerTimestamp=NOW) for v, t in SCALARS
    ]
    out += [
        # two timestamps, one of them absent, no status code, a bad status code
        ua.DataValue(
            ua.Variant(2.5, ua.VariantType.Double), SourceTimestamp=NOW, ServerTimestamp=LATER
        ),
        ua.DataValue(ua.Variant(7, ua.VariantType.Int32), ServerTimestamp=NOW),
        ua.DataValue(ua.Variant(7, ua.VariantType.Int32), StatusCode=None),
        ua.DataValue(
            ua.Variant(0.0, ua.VariantType.Double),
            StatusCode=ua.StatusCode(ua.StatusCodes.BadOutOfRange),
            SourceTimestamp=NOW,
            ServerTimestamp=NOW,
        ),
        # what the fast path does not pack: asyncua's serializer
        ua.DataValue(ua.Variant(ua.LocalizedText("Running"), ua.VariantType.LocalizedText)),
        ua.DataValue(
            ua.Variant([1.0, 2.0], ua.VariantType.Double), SourceTimestamp=NOW, ServerTimestamp=NOW
        ),
        ua.DataValue(
            ua.Variant(1.0, ua.VariantType.Double),
            SourceTimestamp=NOW,
            ServerTimestamp=NOW,
            SourcePicoseconds=10,
        ),
        ua.DataValue(StatusCode=ua.StatusCode(ua.StatusCodes.BadNodeIdUnknown)),
    ]
    return out


@pytest.mark.parametrize("dv", datavalues(), ids=lambda dv: repr(dv.Value)[:40])
def test_a_datavalue_is_encoded_as_asyncua_encodes_it(dv: ua.DataValue) -> None:
    assert encode_datavalue(dv) == struct_to_binary(dv)


def test_a_notification_is_the_extension_object_asyncua_writes() -> None:
    items = [
        ua.MonitoredItemNotification(ClientHandle=handle, Value=dv)
        for handle, dv in enumerate(datavalues(), start=4_000_000_000 - 5)
    ]
    ours = encoded_datachanges(items)
    theirs = ua.DataChangeNotification(MonitoredItems=items)
    assert struct_to_binary(ours) == extensionobject_to_binary(theirs)


def test_a_client_decodes_the_notification_it_was_sent() -> None:
    items = [
        ua.MonitoredItemNotification(ClientHandle=h, Value=dv)
        for h, dv in enumerate(datavalues()[:12])
    ]
    response = ua.PublishResponse()
    response.Parameters.NotificationMessage.NotificationData.append(encoded_datachanges(items))
    decoded = struct_from_binary(ua.PublishResponse, ua.utils.Buffer(struct_to_binary(response)))
    (notification,) = decoded.Parameters.NotificationMessage.NotificationData
    assert isinstance(notification, ua.DataChangeNotification)
    assert [i.ClientHandle for i in notification.MonitoredItems] == list(range(12))
    for got, (value, vtype) in zip(notification.MonitoredItems, SCALARS, strict=True):
        assert got.Value.Value.VariantType == vtype
        if vtype == ua.VariantType.Float:  # a REAL: the value as 32 bits hold it
            assert got.Value.Value.Value == pytest.approx(value, rel=1e-7)
        else:
            assert got.Value.Value.Value == value
        assert got.Value.SourceTimestamp == NOW
        assert got.Value.ServerTimestamp == NOW


class _Subscription:
    """What :func:`install` uses of asyncua's InternalSubscription."""

    def __init__(self, client: bool) -> None:
        self.pub_request_callback = (lambda sid: None) if client else None
        self._triggered_datachanges: dict[int, list[ua.MonitoredItemNotification]] = {}

    def _pop_triggered_datachanges(self, result: ua.PublishResult) -> None:
        raise AssertionError("asyncua's own: not expected here")


def test_a_client_subscription_publishes_its_queued_changes_encoded() -> None:
    isub = _Subscription(client=True)
    install(isub)
    dv = ua.DataValue(
        ua.Variant(1.5, ua.VariantType.Double), SourceTimestamp=NOW, ServerTimestamp=NOW
    )
    first = ua.MonitoredItemNotification(ClientHandle=1, Value=dv)
    second = ua.MonitoredItemNotification(ClientHandle=2, Value=dv)
    isub._triggered_datachanges = {10: [first], 11: [second]}
    result = ua.PublishResult()
    isub._pop_triggered_datachanges(result)
    assert isub._triggered_datachanges == {}
    (data,) = result.NotificationMessage.NotificationData
    assert isinstance(data, ua.ExtensionObject)
    expected = ua.DataChangeNotification(MonitoredItems=[first, second])
    assert struct_to_binary(data) == extensionobject_to_binary(expected)
    empty = ua.PublishResult()
    isub._pop_triggered_datachanges(empty)  # nothing queued: no notification
    assert empty.NotificationMessage.NotificationData == []


def test_the_servers_own_subscriptions_keep_asyncuas_objects() -> None:
    isub = _Subscription(client=False)
    own = isub._pop_triggered_datachanges
    install(isub)
    assert isub._pop_triggered_datachanges == own


def _dv(value: Any, vtype: ua.VariantType, status: ua.StatusCode | None = None) -> ua.DataValue:
    return ua.DataValue(ua.Variant(value, vtype), StatusCode=status or ua.StatusCode())


GOOD = ua.StatusCode()
NAN = float("nan")
#: (old, new) pairs: same object, equal, different value, type, status; NaN; no old value
CHANGES: list[tuple[ua.DataValue | None, ua.DataValue]] = [
    (None, _dv(1.0, ua.VariantType.Double)),
    (_dv(1.0, ua.VariantType.Double, GOOD), _dv(1.0, ua.VariantType.Double, GOOD)),
    (_dv(1.0, ua.VariantType.Double), _dv(1.0, ua.VariantType.Double)),
    (_dv(1.0, ua.VariantType.Double), _dv(1.5, ua.VariantType.Double)),
    (_dv(1, ua.VariantType.Int32), _dv(1, ua.VariantType.UInt32)),
    (
        _dv(1.0, ua.VariantType.Double),
        _dv(1.0, ua.VariantType.Double, ua.StatusCode(ua.StatusCodes.BadOutOfRange)),
    ),
    (_dv(NAN, ua.VariantType.Double), _dv(NAN, ua.VariantType.Double)),
    (_dv(True, ua.VariantType.Boolean), _dv(True, ua.VariantType.Boolean)),
]


@pytest.mark.parametrize(("old", "new"), CHANGES)
def test_the_lean_change_check_is_asyncuas(old: ua.DataValue | None, new: ua.DataValue) -> None:
    from asyncua.server.monitored_item_service import MonitoredItemService, MonitoredItemValues

    from motion_server.frontends.opcua_notify import value_changed

    values = MonitoredItemValues()
    values.old_dvalue, values.current_dvalue = old, new
    trigger = ua.DataChangeTrigger.StatusValue
    assert value_changed(old, new) == MonitoredItemService._is_data_changed(values, trigger)
    same = _dv(2.0, ua.VariantType.Double)
    assert value_changed(same, same) is False
