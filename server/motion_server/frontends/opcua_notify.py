"""Data-change notifications: the monitored items' lean path, and their encoding.

:func:`lean_datachange_callback`, :class:`SharedValues` and :func:`in_batches` replace
parts of asyncua's monitored-item service for the publisher's load (each says which and
why); the OPC UA front-end installs them in every subscription it creates.


asyncua encodes a PublishResponse with its generic serializers: for every
``MonitoredItemNotification`` the dataclass serializer of ``DataValue`` walks its six
optional fields, converts both timestamps from ``datetime`` and packs the Variant
through the type-dispatching ``variant_to_binary``. A response of 1,000 notifications
took about 8 ms of the front-end's event loop, ten times a second under the benchmark's
subscription load, and every request that arrived meanwhile waited.

:func:`encoded_datachanges` builds the same bytes with precompiled ``struct`` formats
for the DataValues the publisher makes (a scalar of one of the tag types, a status code,
two timestamps, no picoseconds) and falls back to asyncua's serializer for any other
DataValue. The body is handed to asyncua as an ``ExtensionObject`` whose TypeId is the
DataChangeNotification's binary encoding: asyncua writes an ExtensionObject as it is
(TypeId, encoding byte, ByteString body), which is exactly what it writes for a
DataChangeNotification object, so the client decodes the same notification.

:func:`install` puts this in a subscription's ``_pop_triggered_datachanges`` (the
asyncua method that turns the queued data changes into the next NotificationMessage).
A republished message is the same ExtensionObject, encoded again as is.
"""

from __future__ import annotations

import asyncio
import dataclasses
import struct
from collections.abc import Iterable
from datetime import datetime
from typing import Any

from asyncua import ua
from asyncua.server.monitored_item_service import MonitoredItemValues
from asyncua.ua.ua_binary import struct_to_binary

__all__ = [
    "CREATE_BATCH",
    "SharedValues",
    "encode_datavalue",
    "encoded_datachanges",
    "in_batches",
    "install",
    "lean_datachange_callback",
    "value_changed",
]

#: the binary encoding of a DataChangeNotification inside an ExtensionObject
DATA_CHANGE_TYPE_ID = ua.NodeId(ua.ObjectIds.DataChangeNotification_Encoding_DefaultBinary)

#: struct formats of the scalar Variant types the tag map uses
_SCALARS: dict[ua.VariantType, str] = {
    ua.VariantType.Boolean: "?",
    ua.VariantType.SByte: "b",
    ua.VariantType.Byte: "B",
    ua.VariantType.Int16: "h",
    ua.VariantType.UInt16: "H",
    ua.VariantType.Int32: "i",
    ua.VariantType.UInt32: "I",
    ua.VariantType.Int64: "q",
    ua.VariantType.UInt64: "Q",
    ua.VariantType.Float: "f",
    ua.VariantType.Double: "d",
}
#: the DataValue encoding mask of a value, a status code and both timestamps (OPC UA
#: Part 6, 5.2.2.17: Value 0x01, StatusCode 0x02, SourceTimestamp 0x04, ServerTimestamp
#: 0x08)
_FULL_MASK = 0x01 | 0x02 | 0x04 | 0x08
#: per Variant type: (ClientHandle, mask, Variant encoding byte, value, status code,
#: source and server timestamps) and the Variant encoding byte
_FULL: dict[ua.VariantType, tuple[struct.Struct, int]] = {
    vtype: (struct.Struct("<IBB" + fmt + "Iqq"), vtype.value) for vtype, fmt in _SCALARS.items()
}
_PLAIN = frozenset({bool, int, float})
_int32 = struct.Struct("<i")
_uint32 = struct.Struct("<I")


class _Stamps:
    """FILETIME of the last timestamp seen: a publishing pass stamps every value of the
    pass with one ``datetime`` object, converted once."""

    __slots__ = ("moment", "ticks")

    def __init__(self) -> None:
        self.moment: datetime | None = None
        self.ticks = 0

    def __call__(self, moment: datetime) -> int:
        if moment is not self.moment:
            self.ticks = ua.datetime_to_win_epoch(moment)
            self.moment = moment
        return self.ticks


def _notification(handle: int, dv: ua.DataValue, stamps: _Stamps) -> bytes:
    """One MonitoredItemNotification: ClientHandle, then the DataValue. The DataValues
    the publisher makes (a scalar, a status code, both timestamps) are packed at once;
    any other goes through asyncua's serializer."""
    var = dv.Value
    status, source, server = dv.StatusCode, dv.SourceTimestamp, dv.ServerTimestamp
    if (
        var is not None
        and status is not None
        and source is not None
        and server is not None
        and not var.is_array
        and var.Dimensions is None
        and dv.SourcePicoseconds is None
        and dv.ServerPicoseconds is None
        and type(var.Value) in _PLAIN
    ):
        full = _FULL.get(var.VariantType)
        if full is not None:
            fmt, code = full
            try:
                src, srv = stamps(source), stamps(server)
                return fmt.pack(handle, _FULL_MASK, code, var.Value, status.value, src, srv)
            except (struct.error, OverflowError):  # out of the type's range: asyncua says so
                pass
    return _uint32.pack(handle) + struct_to_binary(dv)


def encode_datavalue(dv: ua.DataValue) -> bytes:
    """The binary encoding of ``dv`` (as asyncua's ``struct_to_binary`` makes it)."""
    return _notification(0, dv, _Stamps())[4:]


def encoded_datachanges(items: Iterable[ua.MonitoredItemNotification]) -> ua.ExtensionObject:
    """A DataChangeNotification of ``items`` (no diagnostic infos), encoded."""
    stamps = _Stamps()
    parts = [_notification(item.ClientHandle, item.Value, stamps) for item in items]
    body = b"".join([_int32.pack(len(parts)), *parts, _int32.pack(0)])
    return ua.ExtensionObject(TypeId=DATA_CHANGE_TYPE_ID, Body=body)


def install(isub: Any) -> None:
    """Encode the data changes of subscription ``isub`` (an asyncua
    ``InternalSubscription`` serving a client) with :func:`encoded_datachanges`.
    Subscriptions of the server itself (no publish requests) keep the objects."""
    if isub.pub_request_callback is None:
        return

    def pop_triggered_datachanges(result: ua.PublishResult) -> None:
        # asyncua's InternalSubscription._pop_triggered_datachanges, but the
        # notification is appended encoded
        queued = isub._triggered_datachanges
        if queued:
            isub._triggered_datachanges = {}
            items = [item for sublist in queued.values() for item in sublist]
            result.NotificationMessage.NotificationData.append(encoded_datachanges(items))

    isub._pop_triggered_datachanges = pop_triggered_datachanges


#: monitored items created between two yields to the event loop
CREATE_BATCH = 16


def in_batches(create: Any) -> Any:
    """CreateMonitoredItems in batches with a yield in between: asyncua creates all the
    items of a request in one go (about 0.1 ms each), so a SCADA client subscribing to
    1,000 tags at once would stop the event loop, and the motion cycles, for 100 ms."""

    async def create_monitored_items(
        params: ua.CreateMonitoredItemsParameters,
    ) -> list[ua.MonitoredItemCreateResult]:
        items = params.ItemsToCreate
        if len(items) <= CREATE_BATCH:
            return list(await create(params))
        results: list[ua.MonitoredItemCreateResult] = []
        for start in range(0, len(items), CREATE_BATCH):
            part = dataclasses.replace(params, ItemsToCreate=items[start : start + CREATE_BATCH])
            results += await create(part)
            await asyncio.sleep(0)
        return results

    return create_monitored_items


def lean_datachange_callback(mis: Any) -> Any:
    """``MonitoredItemService.datachange_callback`` made lean, for a 1,000-tag subscription
    load (each step was measured there):

    - asyncua builds a default ``MonitoredItemNotification()`` for every change it is told
      of (a default DataValue and Variant, whose type it guesses) and then overwrites
      both of its fields; that was a fifth of the front-end's CPU. The notification is
      built once its fields are known.
    - Without a filter, the trigger is StatusValue: :func:`value_changed` is asyncua's
      ``_is_data_changed`` for it, short-cut when the status code is the same object
      (the publisher's DataValues share one).
    - The notification is queued as ``InternalSubscription._enqueue_event`` queues it
      (a new item's first change triggers a publish; then at most the item's queue size,
      the oldest dropped), with queue size 0 meaning 1 (see ``_patch_queue_size``),
      without the two coroutine layers in between.

    A filter (deadband, another trigger) takes asyncua's own checks."""
    upstream = mis.datachange_callback
    datachange = mis._monitored_datachange
    items = mis._monitored_items
    disabled = ua.MonitoringMode.Disabled

    async def datachange_callback(
        handle: int, value: ua.DataValue, error: ua.StatusCode | None = None
    ) -> None:
        if error:
            await upstream(handle, value, error)
            return
        mid = datachange[handle]
        mdata = items[mid]
        if mdata.mode == disabled:
            return
        mvalue = mdata.mvalue
        mvalue.set_current_datavalue(value)
        if mdata.filter:
            changed = mis._is_data_changed(
                mvalue, mdata.filter.Trigger
            ) and mis._is_deadband_exceeded(mvalue, mdata.filter)
        else:
            changed = value_changed(mvalue.get_old_datavalue(), value)
        if changed:
            event = ua.MonitoredItemNotification(ClientHandle=mdata.client_handle, Value=value)
            isub = mis.isub
            queue = isub._triggered_datachanges
            pending = queue.get(mid)
            if pending is None:
                queue[mid] = [event]
                await isub._trigger_publish()
                return
            if len(pending) >= (mdata.queue_size or 1):
                pending.pop(0)
            pending.append(event)

    return datachange_callback


def value_changed(old: ua.DataValue | None, new: ua.DataValue) -> bool:
    """asyncua's ``MonitoredItemService._is_data_changed`` with the StatusValue trigger:
    the status code or the value (type and value) differ."""
    if old is None:
        return True
    if old.StatusCode is not new.StatusCode and old.StatusCode != new.StatusCode:
        return True
    ov, nv = old.Value, new.Value
    if ov is nv:
        return False
    if ov is None or nv is None:
        return True
    return not (ov.VariantType == nv.VariantType and ov.Value == nv.Value)


class SharedValues(MonitoredItemValues):
    """A monitored item's last values without asyncua's defensive deep copy, which was
    most of the cost of a published change: neither the publisher nor asyncua's write
    path changes a DataValue after writing it (each write makes a new one)."""

    def set_current_datavalue(self, cur_val: ua.DataValue) -> None:
        self.old_dvalue = self.get_current_datavalue()
        self.current_dvalue = cur_val
