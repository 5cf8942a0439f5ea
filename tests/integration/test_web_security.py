"""The web view's security over real sockets (docs/web.md § "Security"): login per role,
the session cookie's attributes, CSRF tokens on POSTs, the WebSocket's Origin, roles on
writes and commands, and bad requests answered with an error, never a crash."""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import websockets

from motion_server.testing import MotionServer
from tests.web_support import USERS, Http, next_text, users_map


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[MotionServer]:
    work: Path = tmp_path_factory.mktemp("web-security")
    srv = MotionServer.start(work, users_map(work), clock="manual", opcua=False, web=True)
    try:
        yield srv
    finally:
        srv.finish()


def test_ready_file_names_the_web_view(server: MotionServer) -> None:
    assert server.web_url.startswith("http://127.0.0.1:")
    assert server.info["web"]["port"] == int(server.web_url.rsplit(":", 1)[1].strip("/"))


@pytest.mark.parametrize("user", sorted(USERS))
def test_login_gives_each_user_its_role(server: MotionServer, user: str) -> None:
    http = Http(server.web_url)
    assert http.get("/api/session")[0] == 401  # no anonymous access on this map
    assert http.get("/api/model")[0] == 401
    status, body = http.login(user)
    assert status == 200, body
    assert body["user"] == user and body["role"] == USERS[user][1] and body["csrf"]
    cookie = http.set_cookie().lower()
    assert "httponly" in cookie and "samesite=strict" in cookie
    status, again = http.get("/api/session")
    assert status == 200 and again["role"] == USERS[user][1]
    status, model = http.get("/api/model")
    assert status == 200 and "MAJ_1" in {i["name"] for i in model["instructions"]}


def test_wrong_password_and_unknown_user_are_refused(server: MotionServer) -> None:
    http = Http(server.web_url)
    assert http.post("/api/login", {"user": "ada", "password": "nope"})[0] == 401
    assert http.post("/api/login", {"user": "nobody", "password": "x"})[0] == 401
    assert not http.cookie
    assert "nope" not in server.log()  # a password is never logged


def test_a_post_without_the_csrf_token_is_refused(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("otto")
    write = {"writes": {"MAJ_1.Speed": 12.5}}
    status, body = http.post("/api/write", write, csrf=False)
    assert status == 403 and "CSRF" in body["error"]
    token, http.csrf = http.csrf, "not-the-token"
    assert http.post("/api/write", write)[0] == 403
    http.csrf = token
    status, body = http.post("/api/write", write)
    assert status == 200 and body["results"] == {"MAJ_1.Speed": "ok"}
    assert server.read("MAJ_1.Speed") == pytest.approx(12.5)


def test_a_viewer_cannot_write_trigger_or_step(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("vera")
    before = server.read("MAJ_1.Speed")
    assert http.post("/api/write", {"writes": {"MAJ_1.Speed": before + 1.0}})[0] == 403
    assert http.post("/api/trigger", {"instruction": "MAJ_1"})[0] == 403
    assert http.post("/api/clock", {"action": "step", "cycles": 1})[0] == 403
    assert server.read("MAJ_1.Speed") == before
    assert server.read("MAJ_1.Execute") is False


def test_an_operator_may_not_drive_the_clock(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("otto")
    cycle = server.read("Clock.Cycle")
    status, body = http.post("/api/clock", {"action": "step", "cycles": 5})
    assert status == 403 and "admin" in body["error"]
    status, body = http.post("/api/write", {"writes": {"Clock.StepCycles": 3}})
    assert status == 200 and "admin" in body["results"]["Clock.StepCycles"]
    assert server.read("Clock.Cycle") == cycle


async def test_a_cross_origin_websocket_is_refused(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("vera")
    for origin in ("http://evil.example", "http://127.0.0.1:1", "null"):
        with pytest.raises(websockets.InvalidStatus) as refused:
            async with http.connect(origin=origin):
                pass
        assert refused.value.response.status_code == 403
    cookie, http.cookie = http.cookie, ""  # the page's origin, no session
    with pytest.raises(websockets.InvalidStatus) as refused:
        async with http.connect():
            pass
    assert refused.value.response.status_code == 403
    http.cookie = cookie
    async with http.connect() as ws:
        hello = await next_text(ws, "hello")
        assert hello["user"] == "vera" and hello["role"] == "viewer"


def test_bad_http_requests_get_an_error(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("otto")
    status, body = http.request("POST", "/api/write", raw=b"{not json")
    assert status == 400 and "JSON" in body["error"]
    status, body = http.request("POST", "/api/write", raw=b"[1, 2]")
    assert status == 400
    status, body = http.request("POST", "/api/write", raw=b" " * (65 * 1024))
    assert status == 413
    status, body = http.post("/api/write", {"writes": {"NoSuch.Tag": 1}})
    assert status == 200 and "unknown tag" in body["results"]["NoSuch.Tag"]
    status, body = http.post("/api/write", {"writes": {"MAJ_1.Speed": "fast"}})
    assert "expected a number" in body["results"]["MAJ_1.Speed"]
    status, body = http.post("/api/write", {"writes": {"Axis1.ActualPosition": 1.0}})
    assert "read-only" in body["results"]["Axis1.ActualPosition"]
    assert http.get("/api/session")[0] == 200  # still serving


async def test_bad_websocket_messages_get_an_error(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("vera")
    async with http.connect() as ws:
        await next_text(ws, "hello")
        for bad in ("{nope", "[]", json.dumps({"type": "launch"})):
            await ws.send(bad)
            assert (await next_text(ws, "error"))["message"]
        await ws.send(json.dumps({"type": "trend", "channels": ["No.Such"]}))
        assert "unknown channel" in (await next_text(ws, "error"))["message"]
        many = [
            f"Axis{a}.{f}"
            for a in (1, 2, 3, 4)
            for f in (
                "ActualPosition",
                "CommandPosition",
                "ActualVelocity",
                "CommandVelocity",
                "PositionError",
            )
        ]
        await ws.send(json.dumps({"type": "trend", "channels": many[:17]}))
        assert "at most 16" in (await next_text(ws, "error"))["message"]
        await ws.send(b"\x00binary")
        assert "JSON text" in (await next_text(ws, "error"))["message"]
        for _ in range(11):  # each change makes the scan take a set: limited per second
            await ws.send(json.dumps({"type": "trend", "channels": ["Axis1.ActualPosition"]}))
        assert "changes a second" in (await next_text(ws, "error"))["message"]
        await ws.send(json.dumps({"type": "status", "hz": 20}))
        status = await next_text(ws, "status")
        assert "Axis1.ActualPosition" in status["values"]
    async with http.connect() as ws:  # larger than 64 KiB: closed with 1009 ...
        await next_text(ws, "hello")
        await ws.send("x" * (65 * 1024))
        with pytest.raises(websockets.ConnectionClosed) as closed:
            await asyncio.wait_for(ws.recv(), 10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009
    async with http.connect() as ws:  # ... and the web view still serves
        assert (await next_text(ws, "hello"))["role"] == "viewer"


def test_a_cross_origin_post_is_refused_even_with_the_token(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("otto")
    own = http.origin
    http.origin = "http://evil.example"
    status, body = http.post("/api/write", {"writes": {"MAJ_1.Speed": 3.0}})
    assert status == 403 and "cross-origin" in body["error"]
    assert http.post("/api/login", {"user": "otto", "password": "operator-pass-2"})[0] == 403
    http.origin = own
    assert http.post("/api/write", {"writes": {"MAJ_1.Speed": 3.0}})[0] == 200


def test_logins_are_audited_without_the_password(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.post("/api/login", {"user": "otto", "password": "guess-1"})
    http.login("otto")
    give_up = time.monotonic() + 10
    while True:
        audit = (server.workdir / "audit.jsonl").read_text("utf-8")
        logins = [json.loads(x) for x in audit.splitlines() if '"event":"login"' in x]
        if len(logins) >= 2 or time.monotonic() > give_up:
            break
        time.sleep(0.1)
    assert {(r["user"], r["result"]) for r in logins} >= {("otto", "refused"), ("otto", "accepted")}
    assert "guess-1" not in audit and "operator-pass-2" not in audit
