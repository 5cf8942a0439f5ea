"""The cam tables' array views on OPC UA: ``Cams.<name>.MasterValues`` (Float[capacity]),
``SlaveValues`` (Float[]) and ``SegmentTypes`` (Int32[]).

A view has no value of its own: a Read composes it from the image slots of the table's
element tags (``Master[0]``, ``Master[1]`` ...), from the same snapshot as every other
value of the request; a Write becomes one batch of writes of those element tags, judged
and queued for the scan exactly as writes of the tags themselves (all or nothing: one bad
element refuses the whole write). The role needed is the element tags' (operator).

Writes answer (besides the codes of a tag write: BadUserAccessDenied, BadOutOfRange,
BadResourceUnavailable):

- ``BadTypeMismatch``: not a one-dimensional array of the view's type (Float, Int32),
  or, without an IndexRange, not ``capacity`` elements long;
- ``BadIndexRangeInvalid``: an IndexRange that is not ``i`` or ``i:j`` (i < j);
- ``BadIndexRangeNoData``: an IndexRange beyond the table's capacity;
- ``BadIndexRangeDataMismatch``: a value whose length is not the IndexRange's.

A Read with an IndexRange gets that slice of the array (BadIndexRangeNoData beyond it).
"""

from __future__ import annotations

import re
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np
from asyncua import ua

from ..tagmap.cams import ArrayView, cam_tables
from .opcua_space import VARIANT_TYPES
from .view import ImageView

_RANGE = re.compile(r"^(\d+)(?::(\d+))?$")


class RangeError(ValueError):
    """An IndexRange the view cannot serve: ``code`` is the status to answer."""

    def __init__(self, code: int) -> None:
        super().__init__(ua.StatusCode(code).name)
        self.code = code


def index_range(text: str, size: int) -> slice:
    """The elements an OPC UA NumericRange (``"3"`` or ``"2:5"``, one dimension) names
    in an array of ``size`` elements; :class:`RangeError` when it is invalid or beyond."""
    m = _RANGE.match(text.strip())
    if m is None:
        raise RangeError(ua.StatusCodes.BadIndexRangeInvalid)
    lo = int(m.group(1))
    hi = int(m.group(2)) if m.group(2) is not None else lo
    if m.group(2) is not None and hi <= lo:
        raise RangeError(ua.StatusCodes.BadIndexRangeInvalid)
    if lo >= size:
        raise RangeError(ua.StatusCodes.BadIndexRangeNoData)
    return slice(lo, min(hi, size - 1) + 1)


@dataclass
class ServedView:
    """One array view: its element tags' image slots and its node's Value attribute."""

    view: ArrayView
    slots: np.ndarray
    vtype: ua.VariantType
    attval: Any = None
    #: the values last notified to monitored items
    last: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def value(self, values: np.ndarray) -> list[Any]:
        raw = values[self.slots]
        if self.vtype == ua.VariantType.Float:
            return [float(v) for v in raw]
        return [int(v) for v in raw]

    def datavalue(self, values: np.ndarray, now: datetime, part: slice | None = None) -> Any:
        items = self.value(values)
        if part is not None:
            items = items[part]
        var = ua.Variant(items, self.vtype)
        return ua.DataValue(var, SourceTimestamp=now, ServerTimestamp=now)


class ArrayViews:
    """The array views of a tag map, served by one OPC UA front-end."""

    def __init__(self, image: ImageView) -> None:
        self.image = image
        #: the views by node id (empty until :meth:`serve`)
        self.by_node: dict[str, ServedView] = {}

    def serve(
        self, nodes: dict[Any, Any], ns: int, current: Callable[[], tuple[np.ndarray, datetime]]
    ) -> None:
        """Answer reads of every view's Value from ``current()`` (the snapshot and time
        of the Read being answered)."""
        image = self.image
        for cam in cam_tables(image.map):
            for v in cam.views:
                slots = np.array([image.slot(t) for t in v.tags], dtype=np.intp)
                self.by_node[v.node_id] = ServedView(v, slots, VARIANT_TYPES[v.type])
        values, _ = current()
        for node_id, sv in self.by_node.items():
            node = nodes.get(ua.NodeId(node_id, ns))
            if node is None:
                continue
            sv.attval = node.attributes.get(ua.AttributeIds.Value)
            sv.last = values[sv.slots].copy()
            if sv.attval is None:
                continue

            def read(nodeid: Any, attr: Any, sv: ServedView = sv) -> Any:
                snap, now = current()
                return sv.datavalue(snap, now)

            sv.attval.value_callback = read

    def read_range(self, node_id: str, text: str, values: np.ndarray, now: datetime) -> Any:
        """The DataValue of a Read with IndexRange ``text`` of view ``node_id``."""
        sv = self.by_node[node_id]
        try:
            part = index_range(text, len(sv.slots))
        except RangeError as exc:
            return ua.DataValue(StatusCode_=ua.StatusCode(exc.code))
        return sv.datavalue(values, now, part)

    def updates(self, wv: ua.WriteValue) -> list[tuple[Any, Any]]:
        """The element writes a Write of a view asks for; :class:`RangeError` with the
        status code when it cannot be one."""
        sv = self.by_node[wv.NodeId.Identifier]
        var = wv.Value.Value if wv.Value is not None else None
        if var is None or var.VariantType != sv.vtype or not var.is_array:
            raise RangeError(ua.StatusCodes.BadTypeMismatch)
        items = var.Value
        if not isinstance(items, list) or (var.Dimensions and len(var.Dimensions) > 1):
            raise RangeError(ua.StatusCodes.BadTypeMismatch)
        tags = sv.view.tags
        if wv.IndexRange:
            part = index_range(wv.IndexRange, len(tags))
            if len(items) != part.stop - part.start:
                raise RangeError(ua.StatusCodes.BadIndexRangeDataMismatch)
            tags = tags[part]
        elif len(items) != len(tags):
            raise RangeError(ua.StatusCodes.BadTypeMismatch)
        return list(zip(tags, items, strict=True))

    async def notify(
        self, values: np.ndarray, now: datetime, log_failure: Callable[[str], None]
    ) -> None:
        """Notify the monitored items of the views whose elements changed."""
        for sv in self.by_node.values():
            att = sv.attval
            if att is None:
                continue
            current = values[sv.slots]
            if np.array_equal(current, sv.last):
                continue
            sv.last = current.copy()
            if not att.datachange_callbacks:
                continue
            dv = sv.datavalue(values, now)
            for handle, callback in list(att.datachange_callbacks.items()):
                try:
                    await _call(callback(handle, dv))
                except Exception:
                    log_failure(sv.view.node_id)


async def _call(result: Awaitable[Any] | None) -> None:
    if result is not None:
        await result
