"""The CIP services of the EtherNet/IP front-end: Logix tags over the shared image.

:class:`TagDispatcher` is cm-ethernetip's ``LogixDispatcher`` (which keeps the Message
Router, the Connection Manager with Forward Open and Unconnected Send, and the Identity
object) with the Logix tag services replaced, because the library's, measured against
pylogix and pycomm3 and read in its source (0.1.0), do not serve our tags:

- its tags hold their own byte buffers (``Tag._data``); ours are read from the shared
  image at request time (:meth:`TagDispatcher.pack`), never a stale copy, and written
  through the judged write queue (:meth:`TagDispatcher.write_members`);
- its ``CipPath`` joins every symbolic segment with ``.`` and keeps one element id, so
  ``Cam1.Master[3]`` loses where the index stood, and ``on_unhandled`` looks the joined
  name up as one tag: every struct member answers 0x05 "path destination unknown"
  (:func:`parse_epath` keeps the segments in order);
- its Read Tag answers a structure with its template handle only, not ``0x02A0`` +
  handle as Logix does;
- its Template Read parses count then offset, where pycomm3 and pylogix send the offset
  (UDINT) first; its template names lack ``;n`` (pycomm3 then names no type), BOOL
  members get a byte each instead of a bit, and it has no attribute 3 (pylogix reads it);
- its Symbol browse starts after the requested instance (Logix starts at it), so the
  tag at each packet boundary is lost for pylogix, and says "read/write" for every tag;
- its Multiple Service Packet has no bound on the services or the reply size.

Every answer is a CIP general status as a Logix controller gives it (:class:`Status`).
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from ethernetip.cip import mr_codec
from ethernetip.cip.attribute import AttributeAccess, CipAttribute
from ethernetip.cip.cip_class import CipClass
from ethernetip.cip.data_types import CipDataType
from ethernetip.cip.identity_info import IdentityInfo
from ethernetip.cip.path import CipPath
from ethernetip.cip.service import CipServiceResponse
from ethernetip.cip.status import CipStatus
from ethernetip.connections.connection_manager import ConnectionManagerObject
from ethernetip.logix.logix_dispatcher import LogixDispatcher

from ..tagmap import BadValueError, ReadOnlyError
from ..tagmap.logix_types import (
    CipType,
    LogixMap,
    LogixTag,
    Member,
    Structure,
    template_definition,
)
from .link import ScanUnavailable, Ticket

log = logging.getLogger("motion_server.frontends.ethernetip")


class Status(IntEnum):
    """CIP general status codes a Logix controller answers with."""

    SUCCESS = 0x00
    RESOURCE_UNAVAILABLE = 0x02
    PATH_SEGMENT_ERROR = 0x04
    PATH_DESTINATION_UNKNOWN = 0x05
    PARTIAL_TRANSFER = 0x06
    SERVICE_NOT_SUPPORTED = 0x08
    INVALID_ATTRIBUTE_VALUE = 0x09
    PRIVILEGE_VIOLATION = 0x0F
    DEVICE_STATE_CONFLICT = 0x10
    REPLY_DATA_TOO_LARGE = 0x11
    NOT_ENOUGH_DATA = 0x13
    ATTRIBUTE_NOT_SUPPORTED = 0x14
    TOO_MUCH_DATA = 0x15
    INVALID_PARAMETER = 0x20
    GENERAL_ERROR = 0xFF


#: Logix's extended status words with general status 0xFF
BEYOND_END = 0x2105
TYPE_MISMATCH = 0x2107

READ_TAG = 0x4C
WRITE_TAG = 0x4D
READ_MODIFY_WRITE = 0x4E
READ_TAG_FRAGMENTED = 0x52
WRITE_TAG_FRAGMENTED = 0x53
MULTIPLE_SERVICE = 0x0A
GET_ATTRIBUTE_LIST = 0x03
GET_INSTANCE_ATTRIBUTE_LIST = 0x55
TAG_SERVICES = frozenset(
    {READ_TAG, WRITE_TAG, READ_MODIFY_WRITE, READ_TAG_FRAGMENTED, WRITE_TAG_FRAGMENTED}
)
SYMBOL_CLASS = 0x6B
TEMPLATE_CLASS = 0x6C
MESSAGE_ROUTER = 0x02
PROGRAM_NAME_CLASS = 0x64
WALL_CLOCK_CLASS = 0x8B
#: Wall Clock attribute: the current UTC time in microseconds since 1970 (ULINT)
UTC_MICROSECONDS = 11
SET_ATTRIBUTE_LIST = 0x04
#: a whole structure's type word in Read/Write Tag (then its handle)
STRUCT_TYPE = 0x02A0
#: reply data bytes at most (fits an unconnected reply: 504 bytes less the headers)
MAX_REPLY = 480
#: services in one Multiple Service Packet at most, and the reply bytes it may build
MAX_SERVICES = 200
MAX_MULTI_REPLY = 4000

Segment = tuple[str, int | str]


def parse_epath(raw: bytes) -> list[Segment] | None:
    """The segments of an EPATH in order (``("symbol", "MAG_1")``, ``("element", 3)``,
    ``("class", 0x6B)``, ``("instance", 5)``, ``("attribute", 1)``); None when a segment
    is not one of these or is cut short (answer 0x04)."""
    out: list[Segment] = []
    i = 0
    n = len(raw)
    while i < n:
        seg = raw[i]
        if seg == 0x91:
            if i + 2 > n:
                return None
            size = raw[i + 1]
            end = i + 2 + size
            if end > n:
                return None
            try:
                name = raw[i + 2 : end].decode("ascii")
            except UnicodeDecodeError:
                return None
            out.append(("symbol", name))
            i = end + (size & 1)
            continue
        if seg & 0xE0 != 0x20:
            return None
        kind = {0x00: "class", 0x04: "instance", 0x08: "element", 0x10: "attribute"}.get(seg & 0x1C)
        fmt = seg & 0x03
        if kind is None or fmt == 3:
            return None
        if fmt == 0:
            if i + 2 > n:
                return None
            value = raw[i + 1]
            i += 2
        elif fmt == 1:
            if i + 4 > n:
                return None
            value = struct.unpack_from("<H", raw, i + 2)[0]
            i += 4
        else:
            if i + 6 > n:
                return None
            value = struct.unpack_from("<I", raw, i + 2)[0]
            i += 6
        out.append((kind, value))
    return out


def error(service: int, status: int, *extended: int) -> CipServiceResponse:
    return CipServiceResponse.error(service, CipStatus.error(status, *extended))


@dataclass(frozen=True)
class Target:
    """What a tag path names: a whole tag, one member, or elements of an array member."""

    tag: LogixTag
    member: Member | None = None
    element: int = 0

    @property
    def start(self) -> int:
        """Byte offset of the target in the tag's structure."""
        if self.member is None:
            return 0
        return self.member.offset + self.element * self.member.type.size

    def span(self, count: int) -> int:
        """Bytes of ``count`` elements of the target (0 when they run past its end)."""
        m = self.member
        if m is None:
            return self.tag.structure.size if count == 1 else 0
        if m.length:
            return m.type.size * count if self.element + count <= m.length else 0
        return m.type.size if count == 1 else 0


WriteHook = Callable[[LogixTag, list[tuple[str, Any]]], "str | None"]


class TagDispatcher(LogixDispatcher):
    """cm-ethernetip's Logix dispatcher serving :class:`~..tagmap.logix_types.LogixMap`
    tags from an :class:`~.view.ImageView` (see the module docstring)."""

    def __init__(
        self,
        logix: LogixMap,
        view: Any,
        identity: IdentityInfo,
        controller_name: str,
    ) -> None:
        super().__init__(identity=identity)
        self.logix = logix
        self.view = view
        slot = view.slot
        #: per tag: (offset, format, slot, kind) of every value member; kind 0 plain,
        #: 1 FLAGS (a UDINT in the image, a DINT here), 2 a BOOL bit of a hidden host
        self._plans: dict[str, list[tuple[int, str, int, int, int]]] = {}
        for t in logix.tags:
            plan = []
            for m in t.structure.members:
                if m.hidden or not m.fields:
                    continue
                if m.type == CipType.BOOL:
                    if m.name in ("EN", "DN", "ER", "PC", "IP", "AC") and t.structure.member(
                        "FLAGS"
                    ):
                        continue  # an alias of a FLAGS bit: FLAGS carries it
                    plan.append((m.offset, "", slot(t.tags[m.fields[0]]), 2, m.bit or 0))
                    continue
                for k, f in enumerate(m.fields):
                    kind = 1 if m.name == "FLAGS" else 0
                    off = m.offset + k * m.type.size
                    plan.append((off, m.type.fmt, slot(t.tags[f]), kind, 0))
            self._plans[t.name] = plan
        #: called with the tag and its (field, value) updates before a write: a reason
        #: to refuse it (privilege violation), or None
        self.write_check: WriteHook | None = None
        #: tickets of the writes of the request being served (the adapter awaits them)
        self.tickets: list[Ticket] = []
        self._resolved: dict[bytes, Target] = {}
        self._ranges: dict[tuple[str, int, int], list[tuple[int, str, int, int, int]]] = {}
        self._definitions = {s.instance: template_definition(s) for s in logix.structures}
        self._handles = {s.instance: s.handle for s in logix.structures}
        # the connection manager is ours to reach, so that a closed TCP connection takes
        # its Forward Open connections with it (the library's keeps them for ever)
        self.connections = OwnedConnections()
        self.connections.dispatch_request = self.dispatch
        self.register_class(self.connections.cip_class)
        # Program Name (class 0x64): the library names the program after the product;
        # pycomm3 shows it as the controller's name: the site's
        pn = CipClass(PROGRAM_NAME_CLASS, "Program Name", revision=1)
        pn.add_standard_instance_services()
        name = controller_name.encode("ascii", "replace")[:40]
        pn.create_instance(1).add_attribute(
            CipAttribute(
                1,
                CipDataType.STRING,
                AttributeAccess.GET_SINGLE | AttributeAccess.GET_ALL,
                struct.pack("<H", len(name)) + name,
            )
        )
        self.register_class(pn)

    # -- values -----------------------------------------------------------------------------
    def pack(self, tag: LogixTag) -> bytearray:
        """The tag's bytes as of the newest snapshot (with this front-end's pending
        writes), laid out as its structure."""
        out = bytearray(tag.structure.size)
        _fill(out, self._plans[tag.name], self.view.values(), 0)
        return out

    def pack_range(self, tag: LogixTag, start: int, end: int) -> tuple[bytearray, int]:
        """Bytes ``start``..``end`` of the tag (and of the values that overlap them),
        packed without the rest of the structure: ``(buffer, offset of its byte 0)``.
        A read of one member costs that member, not the whole structure."""
        key = (tag.name, start, end)
        plan = self._ranges.get(key)
        if plan is None:
            plan = [e for e in self._plans[tag.name] if e[0] < end and e[0] + _extent(e) > start]
            if len(self._ranges) < 100_000:
                self._ranges[key] = plan
        base = min([start, *(e[0] for e in plan)])
        top = max([end, *(e[0] + _extent(e) for e in plan)])
        out = bytearray(top - base)
        _fill(out, plan, self.view.values(), base)
        return out, base

    @staticmethod
    def member_value(m: Member, raw: bytes | bytearray, k: int = 0) -> Any:
        """Member ``m`` (element ``k``) decoded from a structure's bytes."""
        if m.type == CipType.BOOL:
            return bool(raw[m.offset] >> (m.bit or 0) & 1)
        return struct.unpack_from(m.type.fmt, raw, m.offset + k * m.type.size)[0]

    # -- dispatch ---------------------------------------------------------------------------
    def dispatch(self, service_code: int, path: CipPath, data: bytes) -> CipServiceResponse:
        raw = path.raw_path or b""
        if path.symbolic_name is not None or (
            path.class_id == SYMBOL_CLASS and path.instance_id and service_code in TAG_SERVICES
        ):
            return self._tag_service(service_code, raw, data)
        if path.class_id == SYMBOL_CLASS and service_code == GET_INSTANCE_ATTRIBUTE_LIST:
            return self._browse(service_code, path.instance_id or 0, data)
        if path.class_id == TEMPLATE_CLASS and path.instance_id:
            return self._template(service_code, path.instance_id, data)
        if path.class_id == MESSAGE_ROUTER and service_code == MULTIPLE_SERVICE:
            return self._multiple(service_code, data)
        if path.class_id == WALL_CLOCK_CLASS:
            return self._wall_clock(service_code, path.instance_id or 0, data)
        response: CipServiceResponse = super().dispatch(service_code, path, data)
        return response

    def _resolve(self, raw: bytes) -> Target | int:
        """The target of a tag path, else the general status to answer."""
        segments = parse_epath(raw)
        if not segments:
            return Status.PATH_SEGMENT_ERROR
        kind, value = segments[0]
        tag: LogixTag | None
        rest = segments[1:]
        if kind == "symbol":
            tag = self.logix.tag(str(value))
        elif kind == "class" and value == SYMBOL_CLASS and rest and rest[0][0] == "instance":
            tag = self.logix.by_instance(int(rest[0][1]))
            rest = rest[1:]
        else:
            return Status.PATH_SEGMENT_ERROR
        if tag is None:
            return Status.PATH_DESTINATION_UNKNOWN
        if not rest:
            return Target(tag)
        kind, value = rest[0]
        if kind == "element":  # our tags are not arrays: only element 0 is the tag
            if value != 0:
                return Status.PATH_DESTINATION_UNKNOWN
            rest = rest[1:]
            if not rest:
                return Target(tag)
            kind, value = rest[0]
        if kind != "symbol":
            return Status.PATH_SEGMENT_ERROR
        member = tag.structure.member(str(value))
        if member is None or member.hidden:
            return Status.PATH_DESTINATION_UNKNOWN
        rest = rest[1:]
        element = 0
        if rest:
            kind, value = rest[0]
            if kind != "element" or len(rest) > 1:
                return Status.PATH_DESTINATION_UNKNOWN  # a member of an atomic member
            element = int(value)
            if element >= max(member.length, 1):
                return Status.PATH_DESTINATION_UNKNOWN
        return Target(tag, member, element)

    def _tag_service(self, service: int, raw: bytes, data: bytes) -> CipServiceResponse:
        cached = self._resolved.get(raw)
        if cached is None:
            found = self._resolve(raw)
            if isinstance(found, int):
                return error(service, found)
            # paths that name something, as clients repeat them (a bounded number)
            if len(self._resolved) < 10_000:
                self._resolved[raw] = found
            cached = found
        target = cached
        if service == READ_TAG:
            return self._read(service, target, data, fragmented=False)
        if service == READ_TAG_FRAGMENTED:
            return self._read(service, target, data, fragmented=True)
        if service in (WRITE_TAG, WRITE_TAG_FRAGMENTED):
            return self._write(service, target, data)
        if service == READ_MODIFY_WRITE:
            return self._rmw(service, target, data)
        return error(service, Status.SERVICE_NOT_SUPPORTED)

    def _type_word(self, target: Target) -> bytes:
        if target.member is None:
            s = target.tag.structure
            return struct.pack("<HH", STRUCT_TYPE, self._handles[s.instance])
        return struct.pack("<H", int(target.member.type))

    def _read(
        self, service: int, target: Target, data: bytes, fragmented: bool
    ) -> CipServiceResponse:
        if len(data) < (6 if fragmented else 2):
            return error(service, Status.NOT_ENOUGH_DATA)
        count = struct.unpack_from("<H", data, 0)[0]
        offset = struct.unpack_from("<I", data, 2)[0] if fragmented else 0
        span = target.span(count)
        if span == 0:
            return error(service, Status.GENERAL_ERROR, BEYOND_END)
        m = target.member
        if m is None:
            body = bytes(self.pack(target.tag))
        elif m.type == CipType.BOOL:
            raw, base = self.pack_range(target.tag, m.offset, m.offset + 1)
            body = bytes((1 if raw[m.offset - base] >> (m.bit or 0) & 1 else 0,))
        else:
            raw, base = self.pack_range(target.tag, target.start, target.start + span)
            body = bytes(raw[target.start - base : target.start - base + span])
        if offset > len(body) or (fragmented and offset == len(body) and body):
            return error(service, Status.GENERAL_ERROR, BEYOND_END)
        head = self._type_word(target)
        room = MAX_REPLY - len(head)
        chunk = body[offset : offset + room]
        # what does not fit answers what fits with 0x06 (as Logix answers a plain read
        # too large for one reply); the client goes on with Read Tag Fragmented
        more = offset + len(chunk) < len(body)
        reply = head + chunk
        if more:
            return CipServiceResponse(
                service_code=service | 0x80, status=CipStatus.error(0x06), data=reply
            )
        return CipServiceResponse.success(service, reply)

    def _write(self, service: int, target: Target, data: bytes) -> CipServiceResponse:
        fragmented = service == WRITE_TAG_FRAGMENTED
        if len(data) < 4:
            return error(service, Status.NOT_ENOUGH_DATA)
        type_word = struct.unpack_from("<H", data, 0)[0]
        pos = 2
        if type_word == STRUCT_TYPE:
            if len(data) < 6:
                return error(service, Status.NOT_ENOUGH_DATA)
            handle = struct.unpack_from("<H", data, 2)[0]
            if target.member is not None or handle != self._handles[target.tag.structure.instance]:
                return error(service, Status.GENERAL_ERROR, TYPE_MISMATCH)
            pos = 4
        elif target.member is None or type_word != int(target.member.type):
            return error(service, Status.GENERAL_ERROR, TYPE_MISMATCH)
        count = struct.unpack_from("<H", data, pos)[0]
        pos += 2
        offset = 0
        if fragmented:
            if len(data) < pos + 4:
                return error(service, Status.NOT_ENOUGH_DATA)
            offset = struct.unpack_from("<I", data, pos)[0]
            pos += 4
        payload = data[pos:]
        span = target.span(count)
        if span == 0:
            return error(service, Status.GENERAL_ERROR, BEYOND_END)
        m = target.member
        if m is not None and m.type == CipType.BOOL:
            span = 1
        if not fragmented:
            # a Logix controller takes the elements the request names and ignores what
            # follows: pycomm3 1.2.16 sends every connected Write Tag twice in one packet
            # (its sequence count and the request again after the value)
            if len(payload) < span:
                return error(service, Status.NOT_ENOUGH_DATA)
            payload = payload[:span]
        elif offset + len(payload) > span:
            return error(service, Status.TOO_MUCH_DATA)
        old = self.pack(target.tag)
        new = bytearray(old)
        if m is not None and m.type == CipType.BOOL:
            if payload:
                bit = 1 << (m.bit or 0)
                new[m.offset] = (new[m.offset] | bit) if payload[0] else (new[m.offset] & ~bit)
        else:
            start = target.start + offset
            new[start : start + len(payload)] = payload
        return self.write_members(service, target, old, new)

    def _rmw(self, service: int, target: Target, data: bytes) -> CipServiceResponse:
        m = target.member
        if len(data) < 2:
            return error(service, Status.NOT_ENOUGH_DATA)
        size = struct.unpack_from("<H", data, 0)[0]
        if len(data) < 2 + 2 * size:
            return error(service, Status.NOT_ENOUGH_DATA)
        if m is None or m.type in (CipType.REAL, CipType.LREAL, CipType.BOOL):
            return error(service, Status.SERVICE_NOT_SUPPORTED)
        if size not in (1, 2, 4, 8) or size > m.type.size:
            return error(service, Status.INVALID_PARAMETER)
        or_mask = data[2 : 2 + size]
        and_mask = data[2 + size : 2 + 2 * size]
        old = self.pack(target.tag)
        new = bytearray(old)
        start = target.start
        for i in range(size):
            new[start + i] = (new[start + i] | or_mask[i]) & and_mask[i]
        return self.write_members(service, target, old, new)

    def write_members(
        self, service: int, target: Target, old: bytes | bytearray, new: bytes | bytearray
    ) -> CipServiceResponse:
        """Write what changed between ``old`` and ``new`` (a tag's bytes) through the
        judged write queue. A whole-structure write leaves the read-only members it
        changed alone (a client writes back what it read a moment ago); a write to a
        read-only member is a privilege violation."""
        tag = target.tag
        if target.member is not None and not target.member.writable:
            return error(service, Status.PRIVILEGE_VIOLATION)
        updates: list[tuple[str, Any]] = []
        for m in tag.structure.members:
            if m.hidden or not m.fields:
                continue
            for k, f in enumerate(m.fields if m.length else m.fields[:1]):
                before = self.member_value(m, old, k)
                after = self.member_value(m, new, k)
                if before == after or (before != before and after != after):  # NaN stays
                    continue
                if not m.writable:
                    if target.member is None:
                        continue
                    return error(service, Status.PRIVILEGE_VIOLATION)
                updates.append((f, after))
        if not updates:
            return CipServiceResponse.success(service)
        if self.write_check is not None:
            reason = self.write_check(tag, updates)
            if reason is not None:
                return error(service, Status.PRIVILEGE_VIOLATION)
        try:
            ticket = self.view.write_many([(tag.tags[f], v) for f, v in updates])
        except ReadOnlyError:
            return error(service, Status.PRIVILEGE_VIOLATION)
        except BadValueError as exc:
            log.info("EtherNet/IP write to %s refused: %s", tag.name, exc)
            return error(service, Status.INVALID_ATTRIBUTE_VALUE)
        except ScanUnavailable:
            return error(service, Status.RESOURCE_UNAVAILABLE)
        self.tickets.append(ticket)
        return CipServiceResponse.success(service)

    # -- Symbol browse, Template object, Multiple Service Packet ------------------------------
    def _browse(self, service: int, start: int, data: bytes) -> CipServiceResponse:
        """Get_Instance_Attribute_List of the Symbol class: every tag from instance
        ``start`` on (Logix starts at it), as many as fit; 0x06 when more follow."""
        if len(data) < 2:
            return error(service, Status.NOT_ENOUGH_DATA)
        count = struct.unpack_from("<H", data, 0)[0]
        if count > 16 or len(data) < 2 + 2 * count:
            return error(service, Status.NOT_ENOUGH_DATA)
        attrs = struct.unpack_from(f"<{count}H", data, 2)
        if any(a not in (1, 2, 3, 5, 6, 7, 8, 10) for a in attrs):
            return error(service, Status.ATTRIBUTE_NOT_SUPPORTED)
        out = bytearray()
        more = False
        for tag in self.logix.tags:
            if tag.instance < start:
                continue
            entry = bytearray(struct.pack("<I", tag.instance))
            s = tag.structure
            for a in attrs:
                if a == 1:
                    name = tag.name.encode("ascii")
                    entry += struct.pack("<H", len(name)) + name
                elif a == 2:
                    entry += struct.pack("<H", s.symbol_type)
                elif a == 7:
                    entry += struct.pack("<H", s.size)
                elif a == 8:
                    entry += struct.pack("<III", 0, 0, 0)
                elif a == 10:  # external access: 0 read/write, 2 read only
                    entry += bytes((0 if s.writable else 2,))
                else:
                    entry += struct.pack("<I", 0)
            if len(out) + len(entry) > MAX_REPLY:
                more = True
                break
            out += entry
        if more:
            return CipServiceResponse(
                service_code=service | 0x80, status=CipStatus.error(0x06), data=bytes(out)
            )
        return CipServiceResponse.success(service, bytes(out))

    def _template(self, service: int, instance: int, data: bytes) -> CipServiceResponse:
        s: Structure | None = self.logix.template(instance)
        if s is None:
            return error(service, Status.PATH_DESTINATION_UNKNOWN)
        definition = self._definitions[instance]
        if service == GET_ATTRIBUTE_LIST:
            if len(data) < 2:
                return error(service, Status.NOT_ENOUGH_DATA)
            count = struct.unpack_from("<H", data, 0)[0]
            if count > 16 or len(data) < 2 + 2 * count:
                return error(service, Status.NOT_ENOUGH_DATA)
            out = bytearray(struct.pack("<H", count))
            # attribute 4, the definition size in 32-bit words, is what pycomm3 and
            # pylogix derive the Template Read length from: (words * 4 - 23) rounds up to
            # the definition's length (a multiple of 4)
            values = {
                1: struct.pack("<H", self._handles[instance]),
                2: struct.pack("<H", len(s.members)),
                3: struct.pack("<H", 0),
                4: struct.pack("<I", len(definition) // 4 + 5),
                5: struct.pack("<I", s.size),
            }
            for a in struct.unpack_from(f"<{count}H", data, 2):
                if a in values:
                    out += struct.pack("<HH", a, 0) + values[a]
                else:
                    out += struct.pack("<HH", a, Status.ATTRIBUTE_NOT_SUPPORTED)
            return CipServiceResponse.success(service, bytes(out))
        if service == READ_TAG:  # Template Read: offset (UDINT), then byte count (UINT)
            if len(data) < 6:
                return error(service, Status.NOT_ENOUGH_DATA)
            offset = struct.unpack_from("<I", data, 0)[0]
            if offset >= len(definition):
                return error(service, Status.GENERAL_ERROR, BEYOND_END)
            chunk = definition[offset : offset + MAX_REPLY]
            if offset + len(chunk) < len(definition):
                return CipServiceResponse(
                    service_code=service | 0x80, status=CipStatus.error(0x06), data=chunk
                )
            return CipServiceResponse.success(service, chunk)
        return error(service, Status.SERVICE_NOT_SUPPORTED)

    def _wall_clock(self, service: int, instance: int, data: bytes) -> CipServiceResponse:
        """The Wall Clock object (pylogix ``GetPLCTime``): the host's UTC time, not the
        simulated one (``Clock.SimTime``). Setting it is refused: the server does not
        own the host's clock."""
        if instance != 1:
            return error(service, Status.PATH_DESTINATION_UNKNOWN)
        if service == SET_ATTRIBUTE_LIST:
            return error(service, Status.PRIVILEGE_VIOLATION)
        if service != GET_ATTRIBUTE_LIST:
            return error(service, Status.SERVICE_NOT_SUPPORTED)
        if len(data) < 2:
            return error(service, Status.NOT_ENOUGH_DATA)
        count = struct.unpack_from("<H", data, 0)[0]
        if count > 16 or len(data) < 2 + 2 * count:
            return error(service, Status.NOT_ENOUGH_DATA)
        out = bytearray(struct.pack("<H", count))
        for a in struct.unpack_from(f"<{count}H", data, 2):
            if a == UTC_MICROSECONDS:
                out += struct.pack("<HHQ", a, 0, time.time_ns() // 1000)
            else:
                out += struct.pack("<HH", a, Status.ATTRIBUTE_NOT_SUPPORTED)
        return CipServiceResponse.success(service, bytes(out))

    def _multiple(self, service: int, data: bytes) -> CipServiceResponse:
        """Multiple Service Packet, bounded: at most :data:`MAX_SERVICES` services and
        :data:`MAX_MULTI_REPLY` reply bytes (else 0x11 reply data too large)."""
        if len(data) < 2:
            return error(service, Status.NOT_ENOUGH_DATA)
        count = struct.unpack_from("<H", data, 0)[0]
        if count == 0 or len(data) < 2 + 2 * count:
            return error(service, Status.NOT_ENOUGH_DATA)
        if count > MAX_SERVICES:
            return error(service, Status.REPLY_DATA_TOO_LARGE)
        offsets = struct.unpack_from(f"<{count}H", data, 2)
        replies: list[bytes] = []
        total = 2 + 2 * count
        for i, start in enumerate(offsets):
            end = offsets[i + 1] if i + 1 < count else len(data)
            parsed = mr_codec.try_parse_request(data[start:end]) if start < end else None
            if parsed is None:
                resp = error(0, Status.PATH_SEGMENT_ERROR)
            else:
                svc, path, inner = parsed
                if svc == MULTIPLE_SERVICE:
                    resp = error(svc, Status.SERVICE_NOT_SUPPORTED)
                else:
                    resp = self.dispatch(svc, path, inner)
            buf = bytearray(8 + len(resp.data) + 2 * len(resp.status.additional_status))
            n = resp.encode(buf)
            replies.append(bytes(buf[:n]))
            total += n
            if total > MAX_MULTI_REPLY:
                return error(service, Status.REPLY_DATA_TOO_LARGE)
        out = bytearray(struct.pack("<H", count))
        at = 2 + 2 * count
        for r in replies:
            out += struct.pack("<H", at)
            at += len(r)
        for r in replies:
            out += r
        return CipServiceResponse.success(service, bytes(out))


class OwnedConnections(ConnectionManagerObject):
    """The library's Connection Manager, remembering which TCP connection opened each
    CIP connection: the library keeps a Forward Open connection until a Forward Close,
    so a client that drops its TCP connection leaves it behind for ever (memory) and
    its next Forward Open with the same serial numbers is refused as a duplicate."""

    def __init__(self) -> None:
        super().__init__()
        #: the TCP connection being served (set by the adapter around each request)
        self.current: int = 0
        self._owner: dict[int, int] = {}

    def _process_forward_open(self, request: Any, is_large: bool) -> CipServiceResponse:
        response: CipServiceResponse = super()._process_forward_open(request, is_large)
        if response.status.is_success and len(response.data) >= 4:
            self._owner[struct.unpack_from("<I", response.data, 0)[0]] = self.current
        return response

    def close_owned(self, owner: int) -> None:
        """Forget the CIP connections TCP connection ``owner`` opened."""
        for ot_id in [k for k, v in self._owner.items() if v == owner]:
            del self._owner[ot_id]
            conn = self.find_by_ot_id(ot_id)
            if conn is not None:
                self.remove_connection(conn)

    def reply_id(self, ot_id: int) -> int:
        """The T->O connection id to answer a SendUnitData on O->T ``ot_id`` with."""
        conn = self.find_by_ot_id(ot_id)
        return int(conn.to_connection_id) if conn is not None else 0


def _extent(entry: tuple[int, str, int, int, int]) -> int:
    """Bytes a pack-plan entry ``(offset, format, slot, kind, bit)`` covers: a bit
    (kind 2) its host byte, any other value its format's size."""
    return 1 if entry[3] == 2 else struct.calcsize(entry[1])


def _fill(
    out: bytearray, plan: Iterable[tuple[int, str, int, int, int]], values: Any, base: int
) -> None:
    """Pack each plan entry's value into ``out``, whose byte 0 is the structure's byte
    ``base``: bits OR-ed into their host byte (kind 2), DINTs (kind 1) as signed 32-bit
    words of the value's low 32 bits, REAL/LREAL as floats, the rest as integers."""
    for off, fmt, slot, kind, bit in plan:
        v = values[slot]
        off -= base
        if kind == 2:
            if v:
                out[off] |= 1 << bit
        elif kind == 1:
            i = int(v) & 0xFFFFFFFF
            struct.pack_into("<i", out, off, i - (1 << 32) if i & 0x80000000 else i)
        elif fmt in ("<f", "<d"):
            struct.pack_into(fmt, out, off, float(v))
        else:
            struct.pack_into(fmt, out, off, int(v))
