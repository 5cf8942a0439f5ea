"""EtherNet/IP front-end: the map's owners as native Logix tags (``docs/ethernetip.md``).

A Logix HMI, pylogix or pycomm3 reads and writes ``MAG_1.DN``, ``Axis2.ActualPosition``
or a whole ``MAG_1`` here as it would on a ControlLogix 5580: symbolic tags over CIP
(Read/Write Tag and their fragmented forms, Read-Modify-Write, Multiple Service Packet,
the Symbol object's tag list, the Template object's UDTs, Forward Open and connected
messaging, Identity). The types and tags come from :mod:`motion_server.tagmap.logix_types`
(the same catalog as the Modbus map and the OPC UA model); values are read from the shared
image at request time and writes go through the judged write queue, as Modbus writes do:
the same judge, the same audit lines.

Built on cm-ethernetip (encapsulation, sessions, CPF, the Message Router, the Connection
Manager, Identity); :mod:`.ethernetip_cip` replaces its tag services, and
:class:`EnipAdapter` its connection loop, which had no limit on connections, no idle or
frame timeout, let an undecodable header end the task with an exception, and registered a
new session on every RegisterSession of a connection without dropping the last.

Access (``[ethernetip.access]``, :class:`EnipAccess`): EtherNet/IP has no users, so the
site map decides what a client may do: read only by default (``role = "viewer"``), or the
writes its network's rule lists. A refused write answers CIP status 0x0F (privilege
violation) and is audited with its reason. Connections from networks not allowed, and past
``max_sessions``, are closed at once; a connection is closed after ``idle_timeout`` seconds
without a complete request and when a frame takes longer than :data:`FRAME_TIMEOUT` to
arrive whole. An encapsulation header that cannot be decoded closes the connection (its
length cannot be trusted); an unknown command is answered "invalid command" (0x0001).
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import itertools
import logging
import struct
import zlib
from typing import Any

from ethernetip.cip.encapsulation import EncapsulationCommand, EncapsulationStatus
from ethernetip.cip.identity_info import IdentityInfo
from ethernetip.protocol.eip_adapter import EipAdapter, _build_error_response
from ethernetip.protocol.messages import (
    RegisterSessionMessage,
    SendRRDataMessage,
    SendUnitDataMessage,
    UnregisterSessionMessage,
)

from ..config import EthernetIpAccessSection, EthernetIpSection
from ..safety.access import peer_address
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo, writing_as
from ..safety.roles import Role, required_role
from ..tagmap import Tag, TagMap
from ..tagmap.logix_types import LogixMap, LogixTag, build_logix_map
from .ethernetip_cip import Status, TagDispatcher
from .link import Ticket, WriteRefused
from .view import ImageView, outcome

log = logging.getLogger("motion_server.frontends.ethernetip")

#: seconds a frame may take to arrive whole once its header came, and a reply to leave
FRAME_TIMEOUT = 10.0
#: seconds a write's reply waits for the scan's acknowledgement (manual clock, Clock.Step)
WRITE_TIMEOUT = 30.0
HEADER = 24
#: reply bytes a connection may have queued before the front-end waits for the client
SEND_BUFFER = 64 * 1024
_KNOWN = {int(c) for c in EncapsulationCommand}
_connection_numbers = itertools.count(1)

Network = ipaddress.IPv4Network | ipaddress.IPv6Network


class EnipAccess:
    """Who may connect and write (``[ethernetip.access]``, shaped as ``[modbus.access]``)."""

    def __init__(self, section: EthernetIpAccessSection, tagmap: TagMap) -> None:
        self.allow = tuple(ipaddress.ip_network(n, strict=False) for n in section.allow)
        self.role = Role.named(section.role)
        self.max_sessions = section.max_sessions
        self.idle_timeout = section.idle_timeout
        self.rules: list[tuple[tuple[Network, ...], frozenset[str]]] = []
        for rule in section.rules:
            names = {t.name for entry in rule.write for t in tagmap.named(entry) if t.writable}
            nets = tuple(ipaddress.ip_network(n, strict=False) for n in rule.networks)
            self.rules.append((nets, frozenset(names)))

    def connection_refused(self, host: str) -> str | None:
        if not self.allow:
            return None
        addr = peer_address(host)
        if addr is None or not any(addr in net for net in self.allow):
            return f"{host} is not in the allowed networks"
        return None

    def write_refused(self, host: str, tags: list[Tag]) -> str | None:
        """Why ``host`` may not write ``tags`` (None: it may)."""
        addr = peer_address(host)
        for nets, names in self.rules:
            if addr is not None and any(addr in net for net in nets):
                for tag in tags:
                    if tag.name not in names:
                        return f"{host} may not write {tag.name}"
                    if required_role(tag) > Role.OPERATOR:
                        return f"{host} may not write {tag.name} (Clock: admin only)"
                return None
        if self.role == Role.VIEWER:
            return "EtherNet/IP is read only here ([ethernetip.access] role viewer)"
        for tag in tags:
            if required_role(tag) > self.role:
                return f"role {self.role.label} may not write {tag.name} (Clock: admin only)"
        return None


def identity_of(site_name: str) -> IdentityInfo:
    """A ControlLogix 5580-class identity: vendor 1 (Rockwell Automation), device type
    14 (programmable logic controller), revision 33.011, a serial number from the site."""
    return IdentityInfo(
        vendor_id=1,
        device_type=0x0E,
        product_code=166,
        major_revision=33,
        minor_revision=11,
        serial_number=zlib.crc32(site_name.encode()) & 0xFFFFFFFF,
        product_name="1756-L85E/B motion-server",
        status=0x3060,  # owned, configured, run mode (what pycomm3 reads as the keyswitch)
    )


class EnipAdapter(EipAdapter):
    """cm-ethernetip's adapter with a bounded, timed connection loop (module docstring)."""

    def __init__(self, frontend: EthernetIpFrontend, dispatcher: TagDispatcher) -> None:
        super().__init__(dispatcher, frontend.identity)
        self.frontend = frontend
        self.tags = dispatcher
        self.connection_id_lookup = dispatcher.connections.reply_id
        self.server: asyncio.Server | None = None

    async def listen(self, host: str = "127.0.0.1", port: int = 44818) -> None:
        # the library binds AF_INET only; a site may bind an IPv6 address
        self.server = await asyncio.start_server(self._handle_client, host, port)
        self._server = self.server
        self.port = self.server.sockets[0].getsockname()[1]

    async def _handle_client(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        fe = self.frontend
        peer = writer.get_extra_info("peername") or ("", 0)
        local = (writer.get_extra_info("sockname") or ("0.0.0.0", 0))[0]
        client = ClientInfo("ethernetip", str(peer[0]), int(peer[1]), next(_connection_numbers))
        reason = fe.access.connection_refused(client.address)
        if reason is None and len(fe.clients) >= fe.access.max_sessions:
            reason = f"session limit {fe.access.max_sessions} reached"
        if reason is not None:
            fe.refused_connections += 1
            log.info("EtherNet/IP connection from %s refused: %s", client.address, reason)
            if fe.audit is not None:
                fe.audit.connection(client, "connect", "refused", reason)
            writer.transport.abort()
            return
        fe.clients[client.connection] = writer
        session = 0
        result, why = "closed", ""
        idle = fe.access.idle_timeout or None
        try:
            while True:
                try:
                    # asyncio.timeout, not wait_for: wait_for (3.11) wraps every read in a
                    # task of its own, which costs more than serving a tag read
                    async with asyncio.timeout(idle):
                        head = await reader.readexactly(HEADER)
                except TimeoutError:
                    result, why = "idle timeout", f"no request for {idle:g} s"
                    break
                command, length = struct.unpack_from("<HH", head)
                try:
                    async with asyncio.timeout(FRAME_TIMEOUT):
                        body = await reader.readexactly(length)
                except TimeoutError:
                    result, why = "frame timeout", f"frame incomplete after {FRAME_TIMEOUT:g} s"
                    break
                frame = head + body
                if command not in _KNOWN:
                    writer.write(_invalid_command(frame))
                    async with asyncio.timeout(FRAME_TIMEOUT):
                        await writer.drain()
                    continue
                try:
                    msg, _ = self._manager.try_parse(frame, peer)
                except Exception as exc:  # a header or payload the library cannot decode
                    result, why = "bad frame", f"undecodable encapsulation frame ({exc})"
                    break
                if msg is None:
                    result, why = "bad frame", "undecodable encapsulation frame"
                    break
                if isinstance(msg, RegisterSessionMessage) and session:
                    self._sessions.unregister(session)  # one session per connection
                    session = 0
                reply = await self._serve(msg, session, local, client)
                if isinstance(msg, RegisterSessionMessage) and reply is not None:
                    status, handle = (
                        struct.unpack_from("<I", reply, 8)[0],
                        struct.unpack_from("<I", reply, 4)[0],
                    )
                    if status == EncapsulationStatus.SUCCESS:
                        session = handle
                elif isinstance(msg, UnregisterSessionMessage):
                    session = 0
                if reply is not None:
                    writer.write(reply)
                    if writer.transport.get_write_buffer_size() > SEND_BUFFER:
                        async with asyncio.timeout(FRAME_TIMEOUT):  # a client not reading
                            await writer.drain()
        except asyncio.IncompleteReadError:
            pass  # the client closed, in a frame or between two
        except TimeoutError:
            result, why = "send timeout", f"replies not taken for {FRAME_TIMEOUT:g} s"
        except (ConnectionError, OSError) as exc:
            result, why = "closed", str(exc) or type(exc).__name__
        finally:
            if session:
                self._sessions.unregister(session)
            self.tags.connections.close_owned(client.connection)
            fe.clients.pop(client.connection, None)
            if result != "closed":
                log.info("EtherNet/IP connection %s closed: %s (%s)", client.key, result, why)
            if fe.audit is not None and result != "closed":
                fe.audit.connection(client, "disconnect", result, why)
            writer.close()

    async def _serve(self, msg: Any, session: int, local: str, client: ClientInfo) -> bytes | None:
        """One message's reply; a write's reply waits for the scan when the view says so
        (manual clock, Clock.Step)."""
        tags = self.tags
        tickets: list[Ticket] = []  # this request's (other connections' run meanwhile)
        tags.tickets = tickets
        tags.connections.current = client.connection
        tags.write_check = lambda tag, updates: self._check(client, tag, updates)
        with writing_as(client):
            try:
                reply: bytes | None = self._dispatch_message(msg, session, local)
            except Exception as exc:  # a request the library's parsers choke on
                log.info("EtherNet/IP request from %s refused: %s", client.key, exc)
                reply = _cip_error(msg, session, Status.NOT_ENOUGH_DATA)
            tags.tickets = []
            failed = False
            for ticket in tickets:
                if not ticket.waits:
                    continue
                try:
                    async with asyncio.timeout(WRITE_TIMEOUT):
                        await outcome(ticket)
                except (WriteRefused, TimeoutError) as exc:
                    log.warning("EtherNet/IP write by %s: %s", client.key, exc)
                    failed = True
        if failed:
            # the scan refused the write or the command it carried failed (a snapshot
            # that does not exist): the request fails as a whole, as Modbus answers 04
            reply = _cip_error(msg, session, Status.DEVICE_STATE_CONFLICT)
        return reply

    def _check(
        self, client: ClientInfo, tag: LogixTag, updates: list[tuple[str, Any]]
    ) -> str | None:
        fe = self.frontend
        reason = fe.access.write_refused(client.address, [tag.tags[f] for f, _ in updates])
        if reason is not None:
            log.info("EtherNet/IP write by %s refused: %s", client.key, reason)
            if fe.audit is not None:
                with writing_as(client):
                    fe.audit.refused(reason, tag=", ".join(f"{tag.name}.{f}" for f, _ in updates))
        return reason


def _invalid_command(frame: bytes) -> bytes:
    """The reply to an encapsulation command the server does not know: the same header
    with status 0x0001 (invalid or unsupported command) and no data."""
    out = bytearray(frame[:HEADER])
    struct.pack_into("<H", out, 2, 0)  # no data; session and sender context stay
    struct.pack_into("<I", out, 8, int(EncapsulationStatus.INVALID_COMMAND))
    return bytes(out)


def _cip_error(msg: Any, session: int, status: int) -> bytes | None:
    """A CIP error reply to a request the parsers refused (general status ``status``)."""
    if isinstance(msg, SendRRDataMessage):
        data = msg.cip_data
        service = data[0] if data else 0
        from ethernetip.cip.cpf import CpfItem, CpfItemType, encode_cpf
        from ethernetip.protocol.eip_adapter import _build_response

        mr = bytes((service | 0x80, 0, status, 0))
        cpf = encode_cpf(
            [CpfItem(CpfItemType.NULL_ADDRESS, b""), CpfItem(CpfItemType.UNCONNECTED_DATA, mr)]
        )
        return bytes(
            _build_response(
                EncapsulationCommand.SEND_RR_DATA, session, msg.sender_context, bytes(6) + cpf
            )
        )
    if isinstance(msg, SendUnitDataMessage):
        data = msg.cip_data
        seq = data[:2] if len(data) >= 2 else b"\x00\x00"
        service = data[2] if len(data) > 2 else 0
        return bytes(
            SendUnitDataMessage(
                session_handle=session,
                sender_context=msg.sender_context,
                connection_id=msg.connection_id,
                cip_data=seq + bytes((service | 0x80, 0, status, 0)),
            ).to_bytes()
        )
    header = getattr(msg, "header", None)
    if header is None:
        return None
    return bytes(
        _build_error_response(
            header.command, session, header.sender_context, EncapsulationStatus.INCORRECT_DATA
        )
    )


class EthernetIpFrontend:
    """The EtherNet/IP listener of one front-end process."""

    def __init__(
        self,
        view: ImageView,
        section: EthernetIpSection,
        audit: AuditLog | None = None,
        site_name: str = "motion-server",
    ) -> None:
        self.view = view
        self.section = section
        self.audit = audit
        self.access = EnipAccess(section.access, view.map)
        site = site_name
        self.identity = identity_of(site)
        self.logix: LogixMap = build_logix_map(view.map)
        self.dispatcher = TagDispatcher(self.logix, view, self.identity, site)
        self.adapter = EnipAdapter(self, self.dispatcher)
        self.clients: dict[int, asyncio.StreamWriter] = {}
        self.refused_connections = 0

    async def start(self) -> None:
        await self.adapter.listen(self.section.host, self.section.port)
        log.info(
            "EtherNet/IP on %s:%d (slot %d): %d Logix tags of %d types; writes: %s",
            self.section.host,
            self.port,
            self.section.slot,
            len(self.logix.tags),
            len(self.logix.structures),
            "by rule" if self.access.rules else f"role {self.access.role.label}",
        )

    @property
    def port(self) -> int:
        return int(self.adapter.port)

    async def stop(self) -> None:
        server = self.adapter.server
        if server is not None:
            server.close()
        for writer in list(self.clients.values()):
            with contextlib.suppress(Exception):
                writer.transport.abort()
        if server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(server.wait_closed(), 2.0)


__all__ = ["EnipAccess", "EthernetIpFrontend", "identity_of"]
