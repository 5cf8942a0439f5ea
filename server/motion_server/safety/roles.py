"""Roles: what a client may write, the same on both protocols.

- ``viewer``: reads only;
- ``operator``: also the writable tags outside ``Clock`` (instruction operands and
  triggers, hand-wheel inputs, the Safety tags, the cam tables' points and Length);
- ``admin``: also the ``Clock`` tags (mode, step).

OPC UA users get theirs from ``[[opcua.users]]``; Modbus/TCP Security clients from their
certificate (``[modbus.tls]``). A plain Modbus TCP connection gets the site's plain role
(:func:`~.access.plain_role`: admin on a map without users or TLS roles, operator on one
with them, or ``[modbus.access] role``), on top of ``[modbus.access]``'s rules.
"""

from __future__ import annotations

from enum import IntEnum

from ..tagmap import Folder, Tag, TagMap


class Role(IntEnum):
    """What a client may write (each role includes the ones below it)."""

    VIEWER = 0
    OPERATOR = 1
    ADMIN = 2

    @property
    def label(self) -> str:
        """The site-map spelling: ``viewer``, ``operator``, ``admin``."""
        return self.name.lower()

    @classmethod
    def named(cls, name: str) -> Role:
        """The role spelled ``name`` in a site map (KeyError for another name)."""
        return cls[name.upper()]


def required_role(tag: Tag) -> Role:
    """The lowest role that may write ``tag`` (Clock control is for admins)."""
    return Role.ADMIN if tag.folder == Folder.CLOCK else Role.OPERATOR


class RoleRegisters:
    """The Modbus registers each role may write, from the tag map."""

    def __init__(self, tagmap: TagMap) -> None:
        admin: set[int] = set()
        for tag in tagmap:
            if tag.writable and required_role(tag) == Role.ADMIN:
                admin.update(range(tag.address, tag.address + tag.count))
        #: registers of tags only admins may write
        self.admin_only = frozenset(admin)

    def write_refused(self, role: Role, address: int, count: int) -> str | None:
        """Why ``role`` may not write registers ``address``..+``count`` (None: it may,
        as far as roles go; read-only registers are refused elsewhere)."""
        if role == Role.VIEWER:
            return "role viewer may not write"
        if role < Role.ADMIN:
            bad = next((a for a in range(address, address + count) if a in self.admin_only), None)
            if bad is not None:
                return f"role {role.label} may not write register {bad} (Clock: admin only)"
        return None
