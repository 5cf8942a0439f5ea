"""OPC UA users: password hashes, roles, the user manager and the failed-login limiter.

Password hashes are strings of the form (``motion-server hash-password`` prints one)::

    scrypt$<n>$<r>$<p>$<salt, base64>$<key, base64>

scrypt from :mod:`hashlib` (:mod:`motion_server.safety.passwords`) with a random 16-byte
salt and a 32-byte key; the default cost is n = 2**14, r = 8, p = 1. Verification
compares in constant time.

Roles (a :class:`~motion_server.safety.roles.Role` per user, from the site map's
``[[opcua.users]]`` or the users secret file; the same roles as Modbus/TCP Security's):

- ``viewer``: read, browse, subscribe; no writes;
- ``operator``: also write instruction operands and triggers (``Execute``) and hand-wheel
  inputs;
- ``admin``: also the ``Clock`` tags (mode, step).

Anonymous sessions (only when the site map sets ``allow_anonymous``) get the role
``anonymous_role`` of the site map (viewer by default).

Failed logins are counted per client address: after ``max_failures`` failures within
``window`` seconds, that address is refused for ``lockout`` seconds (even with the right
password). Failures are logged with the user name and address, never the password.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import secrets
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from asyncua import ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.server.internal_session import InternalSession
from asyncua.server.user_managers import UserManager

from ..safety.client import ClientInfo, writing_as
from ..safety.login_limit import LoginLimiter
from ..safety.passwords import hash_password, parse_hash, verify_password
from ..safety.roles import Role

log = logging.getLogger("motion_server.opcua")

# the hash format and its cost bounds live in one place (the config's checks use them too)
__all__ = [
    "Account",
    "Directory",
    "LoginLimiter",
    "PeerSession",
    "hash_password",
    "parse_hash",
    "verify_password",
]


@dataclass(frozen=True)
class Account:
    """One user: name, role and password hash."""

    name: str
    role: Role
    password_hash: str


#: the asyncua role our roles map to: never Admin, so no client may add or delete nodes
_UA_ROLE = UserRole.User


class Directory(UserManager):
    """The asyncua user manager: checks user name and password against the accounts, and
    answers anonymous sessions only when allowed. ``role_of(user)`` gives the role of a
    session's user."""

    def __init__(
        self,
        accounts: Iterable[Account],
        allow_anonymous: bool = False,
        anonymous_role: Role = Role.VIEWER,
        limiter: LoginLimiter | None = None,
    ) -> None:
        self.accounts = {a.name: a for a in accounts}
        self.allow_anonymous = allow_anonymous
        self.anonymous_role = anonymous_role
        self.limiter = limiter or LoginLimiter()
        #: the address of the session being activated (set by :class:`PeerSession`)
        self.peer = "?"
        # a hash to verify against for unknown names, so their timing matches a known one
        self._dummy = hash_password(secrets.token_hex(8))

    def get_user(
        self,
        iserver: Any,
        username: str | None = None,
        password: str | None = None,
        certificate: Any = None,
    ) -> User | None:
        peer = self.peer
        if username is None:
            # ``certificate`` is the channel's client certificate (b"" on the None
            # endpoint), not an identity: X509 identity tokens are not offered at all
            if not self.allow_anonymous:
                log.info("OPC UA: anonymous login from %s refused", peer)
                return None
            # asyncua's Anonymous role may not even read: anonymous sessions get the User
            # role without a name, and our own role from ``anonymous_role``
            return User(role=_UA_ROLE, name=None)
        if self.limiter.locked(peer):
            log.warning("OPC UA: login of %r from %s refused: too many failures", username, peer)
            return None
        account = self.accounts.get(username)
        ok = verify_password(password or "", account.password_hash if account else self._dummy)
        if account is None or not ok:
            self.limiter.failed(peer)
            log.warning("OPC UA: failed login of %r from %s", username, peer)
            return None
        self.limiter.succeeded(peer)
        log.info("OPC UA: %s (%s) logged in from %s", username, account.role.name.lower(), peer)
        return User(role=_UA_ROLE, name=username)

    def role_of(self, user: User | None) -> Role | None:
        """The role of a session's user (None: no role, may not write)."""
        if user is None:
            return None
        if user.role != _UA_ROLE:
            return None  # asyncua's internal session (Admin), or a session not activated
        if user.name is None:
            return self.anonymous_role if self.allow_anonymous else None
        account = self.accounts.get(user.name or "")
        return account.role if account is not None else Role.VIEWER


class PeerSession(InternalSession):
    """An asyncua session that tells the :class:`Directory` which client address is
    logging in (asyncua names external sessions after the peer address), and serves its
    writes :func:`writing_as` its client, so the audit log and the per-connection
    watchdogs know who wrote. Each session is one connection (a fresh number)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        host, port = _peer(self.name)
        self.client = ClientInfo("opcua", host, port, next(_connection_numbers))

    def client_info(self) -> ClientInfo:
        """The session's client with the user logged in (``anonymous`` without a name)
        and that user's role."""
        user = self.user.name if self.user is not None else None
        manager = self.iserver.user_manager
        role = manager.role_of(self.user) if isinstance(manager, Directory) else None
        return dataclasses.replace(
            self.client, user=user or "anonymous", role=role.label if role is not None else ""
        )

    async def write(self, params: ua.WriteParameters) -> list[ua.StatusCode]:
        with writing_as(self.client_info()):
            return await super().write(params)

    async def close_session(self, delete_subs: bool = True) -> None:
        """Close, and always delete the session's subscriptions: a CloseSession with
        DeleteSubscriptions false would leave them publishing for their whole lifetime
        (minutes) and counting against ``max_subscriptions``, so a client could exhaust
        them. (asyncua deletes them on a lost connection too; no transfer after close.)"""
        await super().close_session(True)

    def activate_session(
        self, params: ua.ActivateSessionParameters, peer_certificate: bytes | None
    ) -> ua.ActivateSessionResult:
        manager = self.iserver.user_manager
        if isinstance(manager, Directory):
            manager.peer = _host(self.name)
        return super().activate_session(params, peer_certificate)


def _host(name: Any) -> str:
    """The client host of asyncua's session name (the peer address tuple)."""
    return _peer(name)[0]


def _peer(name: Any) -> tuple[str, int]:
    """Host and port of asyncua's session name (the peer address tuple)."""
    if isinstance(name, tuple) and name:
        port = name[1] if len(name) > 1 and isinstance(name[1], int) else 0
        return str(name[0]), port
    return str(name), 0


#: OPC UA connection numbers (sessions), unique for the server's life
_connection_numbers = itertools.count(1)
