"""Data-change notifications encoded once, by hand, for the publish responses.

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

import struct
from collections.abc import Iterable
from datetime import datetime
from typing import Any

from asyncua import ua
from asyncua.ua.ua_binary import struct_to_binary

__all__ = ["encode_datavalue", "encoded_datachanges", "install"]

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
