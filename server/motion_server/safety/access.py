"""Modbus access control: client networks, read-only mode, write permission by range.

From ``[modbus.access]`` and the tag map:

- ``allow``: the networks a client may connect from (empty: any); others are closed at
  once.
- ``read_only``: every write is refused.
- ``rules``: the first rule whose ``networks`` hold the client decides what it may write:
  the registers of the tags its ``write`` entries name (a folder such as ``Instructions``,
  an owner such as ``MAJ_1``, a tag ``MAJ_1.Speed``, or a register range ``5000-5999``).
  A client no rule matches may write every writable tag.
- ``max_connections``, ``idle_timeout``: enforced by the front-end.
- ``role``: what a plain Modbus TCP client may write (:mod:`.roles`). Plain Modbus has no
  identity, so its role is the site's choice: unset, it is admin on a map that defines
  no users (``[[opcua.users]]``, the users secret file) and no TLS roles
  (``[modbus.tls]`` enabled), as before roles existed, and operator on one that does: a
  site that authenticates its admins does not hand the Clock tags (mode, step,
  snapshots, communication faults) to whoever reaches the plain port. A site that wants
  more sets ``role = "admin"`` explicitly; :func:`plain_role` decides, and the front-end
  says at start which role plain clients have and why.

A refused write answers exception 02 (illegal data address), as a write to a read-only
register does, and is audited with its reason.
"""

from __future__ import annotations

import ipaddress
import re
from dataclasses import dataclass

from ..config import ModbusAccessSection, SiteMap
from ..tagmap import TagMap
from .roles import Role

Network = ipaddress.IPv4Network | ipaddress.IPv6Network

_RANGE = re.compile(r"^\s*(\d+)\s*-\s*(\d+)\s*$")


def peer_address(host: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    """A peer's address as the access rules match it (an IPv4-mapped IPv6 address as
    IPv4, a zone index dropped); None when ``host`` is not an address."""
    try:
        addr = ipaddress.ip_address(host.split("%")[0])
    except ValueError:
        return None
    if isinstance(addr, ipaddress.IPv6Address) and addr.ipv4_mapped is not None:
        return addr.ipv4_mapped
    return addr


def writable_registers(tagmap: TagMap, entries: list[str]) -> frozenset[int]:
    """The registers ``entries`` (folders, owners, tags, ranges) let a client write."""
    out: set[int] = set()
    for entry in entries:
        m = _RANGE.match(entry)
        if m:
            out.update(range(int(m.group(1)), int(m.group(2)) + 1))
            continue
        for tag in tagmap.named(entry):
            if tag.writable:
                out.update(range(tag.address, tag.address + tag.count))
    return frozenset(out)


@dataclass(frozen=True)
class PlainRole:
    """The role of plain Modbus TCP clients and why, in words for the start-up line."""

    role: Role
    why: str
    #: the map defines users or TLS roles (a role above operator deserves a warning)
    secured: bool = False


def plain_role(site: SiteMap, has_users: bool) -> PlainRole:
    """The role of plain Modbus TCP clients on ``site``; ``has_users``: OPC UA users are
    configured (the site map's or the users secret file's; a generated first user does
    not count: the demo keeps plain Modbus admin)."""
    reasons = []
    if has_users:
        reasons.append("OPC UA users")
    if site.modbus.tls.enabled:
        reasons.append("Modbus/TLS roles")
    secured = bool(reasons)
    explicit = site.modbus.access.role
    if explicit is not None:
        return PlainRole(Role.named(explicit), "[modbus.access] role", secured)
    if secured:
        why = f"the site map defines {' and '.join(reasons)}; [modbus.access] role grants more"
        return PlainRole(Role.OPERATOR, why, secured)
    return PlainRole(Role.ADMIN, "no users and no TLS roles are defined", secured)


@dataclass(frozen=True)
class _Rule:
    networks: tuple[Network, ...]
    registers: frozenset[int]


class AccessPolicy:
    """Who may connect and write. ``AccessPolicy(section, tagmap, plain)``: ``plain``
    is the role of plain Modbus TCP clients (:func:`plain_role`; default admin)."""

    def __init__(
        self, section: ModbusAccessSection, tagmap: TagMap, plain: PlainRole | None = None
    ) -> None:
        self.section = section
        #: the role of plain Modbus TCP clients (TLS clients have their certificate's)
        self.plain = plain if plain is not None else PlainRole(Role.ADMIN, "no roles given")
        self.allow = tuple(ipaddress.ip_network(n, strict=False) for n in section.allow)
        self.read_only = section.read_only
        self.max_connections = section.max_connections
        self.idle_timeout = section.idle_timeout
        self.rules = tuple(
            _Rule(
                tuple(ipaddress.ip_network(n, strict=False) for n in r.networks),
                writable_registers(tagmap, r.write),
            )
            for r in section.rules
        )

    def connection_refused(self, host: str) -> str | None:
        """Why a client at ``host`` may not connect (None: it may)."""
        if not self.allow:
            return None
        addr = peer_address(host)
        if addr is None or not any(addr in net for net in self.allow):
            return f"{host} is not in the allowed networks"
        return None

    def write_refused(self, host: str, address: int, count: int) -> str | None:
        """Why ``host`` may not write registers ``address``..+``count`` (None: it may)."""
        if self.read_only:
            return "the server is read-only"
        addr = peer_address(host)
        for rule in self.rules:
            if addr is not None and any(addr in net for net in rule.networks):
                bad = next(
                    (a for a in range(address, address + count) if a not in rule.registers),
                    None,
                )
                if bad is not None:
                    return f"{host} may not write register {bad}"
                return None
        return None
