"""The web view's sessions (motion_server.frontends.web_auth): a flood of requests
without a cookie cannot end the sessions of users who logged in; a password travels
only under TLS or on loopback; anonymous access only where the site map allows it."""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.frontends import web_auth
from motion_server.safety.roles import Role


def site(**web: object) -> config.SiteMap:
    demo = config.load(None, {})
    return demo.model_copy(update={"web": demo.web.model_copy(update=web)})


def test_anonymous_requests_do_not_evict_logged_in_users(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(web_auth, "MAX_SESSIONS", 10)
    sessions = web_auth.Sessions(site(), [], tls=False)
    users = [sessions.login(f"user{i}", Role.OPERATOR) for i in range(5)]
    for _ in range(1000):
        sessions.anonymous_session()
    assert all(sessions.get(s.id) is s for s in users)
    more = [sessions.login(f"late{i}", Role.VIEWER) for i in range(5)]  # the room is theirs
    assert all(sessions.get(s.id) is s for s in users + more)
    assert sessions.anonymous_session() is None  # full of users: no anonymous one now


def test_where_a_password_may_travel() -> None:
    assert web_auth.Sessions(site(host="127.0.0.1"), [], tls=False).password_allowed
    assert not web_auth.Sessions(site(host="0.0.0.0"), [], tls=False).password_allowed
    assert web_auth.Sessions(site(host="0.0.0.0"), [], tls=True).password_allowed


def test_anonymous_access_beyond_loopback_needs_allow_insecure_remote() -> None:
    assert web_auth.Sessions(site(host="0.0.0.0"), [], tls=False).anonymous is None
    remote = web_auth.Sessions(
        site(host="0.0.0.0", allow_insecure_remote=True, anonymous_role="viewer"), [], False
    )
    assert remote.anonymous == Role.VIEWER
    assert web_auth.Sessions(site(allow_anonymous=False), [], tls=False).anonymous is None
