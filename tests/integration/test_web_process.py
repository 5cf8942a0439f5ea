"""The web view as a process of the server (docs/web.md): restarted on its port when it
dies while motion goes on; no password over plain HTTP beyond loopback; HTTPS with a
configured certificate (the cookie then Secure, the WebSocket over wss:)."""

from __future__ import annotations

import http.client
import json
import os
import signal
import socket
import ssl
import time
from pathlib import Path

import pytest
import websockets

from motion_server.frontends.certificates import pem_copy, server_certificate
from motion_server.testing import MotionServer
from tests.web_support import Http, demo_text, next_text, users_map


def _children(server: MotionServer) -> dict[str, int]:
    """role -> pid of the supervisor's front-end children."""
    out: dict[str, int] = {}
    pid = server.pid
    for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split():
        try:
            cmd = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"motion_server.frontends" in cmd:
            out[cmd[cmd.index(b"motion_server.frontends") + 1].decode()] = int(child)
    return out


def test_a_killed_web_process_is_restarted_on_its_port(tmp_path: Path) -> None:
    server = MotionServer.start(tmp_path, users_map(tmp_path), opcua=False, web=True)
    try:
        url = server.web_url
        http = Http(url)
        assert http.login("otto")[0] == 200
        before = server.read("Diagnostics.FrontendRestarts")
        mark = len(server.log())
        os.kill(_children(server)["web"], signal.SIGKILL)
        give_up = time.monotonic() + 120
        while "web view on" not in server.log()[mark:]:
            assert time.monotonic() < give_up, server.log_tail()
            time.sleep(0.1)
        assert f"web view on {url}" in server.log()[mark:]  # the same port
        server.step(1)  # the manual clock: diagnostics show with the next cycle
        assert server.read("Diagnostics.FrontendRestarts") == before + 1
        http = Http(url)  # sessions live in the web process: log in again
        assert http.login("otto")[0] == 200
    finally:
        server.finish()


def test_no_password_over_plain_http_beyond_loopback(tmp_path: Path) -> None:
    text = demo_text().replace(
        'enabled = true\nhost = "127.0.0.1"\nport = 8080',
        ('enabled = true\nhost = "0.0.0.0"\nport = 8080'),
    )
    site = tmp_path / "remote.toml"
    site.write_text(text, "utf-8")
    server = MotionServer.start(tmp_path, site, opcua=False, web=True)
    try:
        http = Http(server.web_url)
        # the demo's anonymous access is for loopback: dropped on 0.0.0.0
        assert http.get("/api/session")[0] == 401
        status, body = http.post("/api/login", {"user": "admin", "password": "whatever"})
        assert status == 403 and "HTTPS" in body["error"]
        assert "allow_anonymous ignored" in server.log()
    finally:
        server.finish()


async def test_https_with_a_configured_certificate(tmp_path: Path) -> None:
    found = server_certificate(tmp_path / "pki", "127.0.0.1", "web")
    cert, key = pem_copy(found.cert), found.key
    text = (
        users_map(tmp_path)
        .read_text("utf-8")
        .replace(
            "allow_anonymous = false",
            f'allow_anonymous = false\ncert_file = "{cert}"\nkey_file = "{key}"',
            1,
        )
    )
    site = tmp_path / "tls.toml"
    site.write_text(text, "utf-8")
    server = MotionServer.start(tmp_path, site, opcua=False, web=True)
    try:
        url = server.web_url
        assert url.startswith("https://")
        context = ssl.create_default_context(cafile=str(cert))
        context.check_hostname = False

        port = int(url.rsplit(":", 1)[1].strip("/"))
        conn = http.client.HTTPSConnection("127.0.0.1", port, context=context, timeout=30)
        body = json.dumps({"user": "ada", "password": "admin-pass-3"})
        conn.request("POST", "/api/login", body, {"Content-Type": "application/json"})
        resp = conn.getresponse()
        assert resp.status == 200, resp.read()
        cookie = resp.getheader("set-cookie") or ""
        assert "secure" in cookie.lower() and "samesite=strict" in cookie.lower()
        session = cookie.split(";", 1)[0]
        async with websockets.connect(
            f"wss://127.0.0.1:{port}/ws",
            ssl=context,
            origin=f"https://127.0.0.1:{port}",  # type: ignore[arg-type]
            additional_headers={"Cookie": session},
        ) as ws:
            assert (await next_text(ws, "hello"))["role"] == "admin"
        with pytest.raises(websockets.InvalidStatus):  # the http: origin is another one
            async with websockets.connect(
                f"wss://127.0.0.1:{port}/ws",
                ssl=context,
                origin=f"http://127.0.0.1:{port}",  # type: ignore[arg-type]
                additional_headers={"Cookie": session},
            ):
                pass
    finally:
        server.finish()


def test_a_web_port_in_use_leaves_the_server_serving_without_it(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        server = MotionServer.start(
            tmp_path, None, opcua=False, web=True, args=["--web-port", str(port)]
        )
        try:
            assert "web" not in server.info and server.web_url == ""
            assert "the web view cannot serve" in server.log()
            server.step(3)  # the controller and Modbus serve
        finally:
            server.finish()
