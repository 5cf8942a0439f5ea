"""Who is on the web view: users, sessions, CSRF tokens and the failed-login limiter.

Users and roles are OPC UA's (``[[opcua.users]]`` and the users secret file, scrypt
hashes: :mod:`motion_server.safety.passwords`). A login creates a session held here, in
the web process: a random id (the ``ms_session`` cookie: HttpOnly, SameSite=Strict,
Secure under TLS) and a random CSRF token every POST must carry in ``X-CSRF-Token``.
Sessions end on logout, after :data:`IDLE_TIMEOUT` s without a request, or
:data:`ABSOLUTE_TIMEOUT` s after the login; a restarted web process forgets them (the
page logs in again).

Anonymous access (``[web] allow_anonymous``) gives a session without a user and with
``anonymous_role``, honoured on a loopback bind only unless ``allow_insecure_remote``.
A password is never accepted over plain HTTP on an address other than loopback.

Failed logins are counted per client address as on OPC UA. User names are logged,
passwords never.
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import secrets
import time
from dataclasses import dataclass

from ..config import OpcUaUser, SiteMap
from ..safety.login_limit import LoginLimiter
from ..safety.passwords import verify_password
from ..safety.roles import Role

log = logging.getLogger("motion_server.web")

#: seconds without a request after which a session ends
IDLE_TIMEOUT = 30 * 60.0
#: seconds after the login after which a session ends, however busy
ABSOLUTE_TIMEOUT = 12 * 3600.0
#: sessions kept at most (the oldest go first)
MAX_SESSIONS = 1000
COOKIE = "ms_session"


def is_loopback(host: str) -> bool:
    """True for a loopback bind or peer address (127.0.0.0/8, ::1)."""
    try:
        return ipaddress.ip_address(host.split("%")[0]).is_loopback
    except ValueError:
        return host == "localhost"


class SessionsFull(RuntimeError):
    """No room for another anonymous session."""


@dataclass
class Session:
    """One browser's login (``user`` None: anonymous)."""

    id: str
    user: str | None
    role: Role
    csrf: str
    created: float
    seen: float


class Sessions:
    """The users, the sessions and the site's anonymous rule."""

    def __init__(self, site: SiteMap, users: list[OpcUaUser], tls: bool) -> None:
        cfg = site.web
        self.tls = tls
        self.loopback = is_loopback(cfg.host)
        self._users = {u.name: u for u in users}
        self.anonymous: Role | None = None
        if cfg.allow_anonymous:
            if self.loopback or cfg.allow_insecure_remote:
                self.anonymous = Role.named(cfg.anonymous_role)
            else:
                log.warning(
                    "web: allow_anonymous ignored: %s is not a loopback address "
                    "(set allow_insecure_remote as well to allow it)",
                    cfg.host,
                )
        if not users and self.anonymous is None:
            log.warning(
                "web: no user configured and no anonymous access: nobody can log in "
                "([[opcua.users]] or the users secret file; OPC UA's generated admin "
                "exists only when OPC UA is served)"
            )
        ua = site.opcua
        self.limiter = LoginLimiter(
            ua.max_login_failures, ua.login_window_s, ua.login_lockout_s, protocol="web", log=log
        )
        self._sessions: dict[str, Session] = {}

    @property
    def password_allowed(self) -> bool:
        """A password may travel: under TLS, or on a loopback bind."""
        return self.tls or self.loopback

    def get(self, sid: str | None) -> Session | None:
        """The live session of cookie ``sid`` (None: none, or it ended)."""
        if not sid:
            return None
        s = self._sessions.get(sid)
        if s is None:
            return None
        now = time.monotonic()
        if now - s.seen > IDLE_TIMEOUT or now - s.created > ABSOLUTE_TIMEOUT:
            del self._sessions[sid]
            return None
        s.seen = now
        return s

    def anonymous_session(self) -> Session | None:
        """A new anonymous session when the site allows it (and there is room)."""
        if self.anonymous is None:
            return None
        try:
            return self._new(None, self.anonymous)
        except SessionsFull:
            return None

    def check(self, user: str, password: str) -> Role | None:
        """The role of ``user`` when ``password`` is right (slow: scrypt; call it in a
        thread)."""
        account = self._users.get(user)
        if account is None:
            # the same work as a known user: the answer's time tells nothing
            verify_password(password, _DUMMY_HASH)
            return None
        if not verify_password(password, account.password_hash):
            return None
        return Role.named(account.role)

    def login(self, user: str, role: Role) -> Session:
        return self._new(user, role)

    def logout(self, sid: str | None) -> None:
        if sid:
            self._sessions.pop(sid, None)

    def _new(self, user: str | None, role: Role) -> Session:
        if len(self._sessions) >= MAX_SESSIONS:
            # anonymous ones go first: requests without a cookie (anyone's, as many as
            # they like) must not end the sessions of users who logged in
            anonymous = [s for s in self._sessions.values() if s.user is None]
            pool = anonymous or (list(self._sessions.values()) if user is not None else [])
            if not pool:  # full of logged-in users: no anonymous session now
                raise SessionsFull("too many sessions: try again later")
            oldest = min(pool, key=lambda s: s.seen)
            del self._sessions[oldest.id]
        now = time.monotonic()
        s = Session(secrets.token_urlsafe(32), user, role, secrets.token_urlsafe(32), now, now)
        self._sessions[s.id] = s
        return s


def csrf_ok(session: Session, token: str | None) -> bool:
    """The request's ``X-CSRF-Token`` is the session's (compared in constant time)."""
    return token is not None and hmac.compare_digest(session.csrf, token)


#: a hash of a random password: what an unknown user's password is checked against
_DUMMY_HASH = (
    "scrypt$16384$8$1$AAAAAAAAAAAAAAAAAAAAAA==$AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA="
)
