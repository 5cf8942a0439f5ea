"""Helpers of the web view's tests: a site map with users, an HTTP session with its
cookie and CSRF token, a WebSocket with the page's Origin, and trend frame reading."""

from __future__ import annotations

import http.client
import json
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import websockets

from motion_server.frontends.web_stream import parse_frame
from motion_server.safety.passwords import hash_password

#: user -> (password, role) of the map :func:`users_map` writes
USERS = {
    "vera": ("viewer-pass-1", "viewer"),
    "otto": ("operator-pass-2", "operator"),
    "ada": ("admin-pass-3", "admin"),
}


def demo_text() -> str:
    return resources.files("motion_server.data").joinpath("demo.toml").read_text("utf-8")


def users_map(directory: Path, anonymous: bool = False) -> Path:
    """The demo map with :data:`USERS`, the audit log on and (unless ``anonymous``) no
    anonymous access to the web view."""
    text = demo_text()
    if not anonymous:
        old = 'enabled = true\nhost = "127.0.0.1"\nport = 8080\nallow_anonymous = true'
        assert old in text
        text = text.replace(old, old.replace("allow_anonymous = true", "allow_anonymous = false"))
    for name, (password, role) in USERS.items():
        text += (
            f'\n[[opcua.users]]\nname = "{name}"\nrole = "{role}"\n'
            f'password_hash = "{hash_password(password)}"\n'
        )
    text += "\n[audit]\nenabled = true\n"  # audit.jsonl in the server's data directory
    path = directory / "web-site.toml"
    path.write_text(text, "utf-8")
    return path


class Http:
    """A browser's HTTP side: the session cookie and the CSRF token, kept."""

    def __init__(self, url: str) -> None:
        parts = urlsplit(url)
        self.host = parts.hostname or "127.0.0.1"
        self.port = parts.port or 80
        self.origin = f"{parts.scheme}://{parts.netloc}"
        self.cookie = ""
        self.csrf = ""
        self.last_headers: list[tuple[str, str]] = []

    def request(
        self,
        method: str,
        path: str,
        body: Any = None,
        csrf: bool = True,
        raw: bytes | None = None,
    ) -> tuple[int, Any]:
        conn = http.client.HTTPConnection(self.host, self.port, timeout=30)
        headers = {"Origin": self.origin}
        if self.cookie:
            headers["Cookie"] = f"ms_session={self.cookie}"
        if csrf and self.csrf:
            headers["X-CSRF-Token"] = self.csrf
        data = raw if raw is not None else None if body is None else json.dumps(body).encode()
        if data is not None:
            headers["Content-Type"] = "application/json"
        conn.request(method, path, body=data, headers=headers)
        resp = conn.getresponse()
        payload = resp.read()
        self.last_headers = resp.getheaders()
        for name, value in self.last_headers:
            if name.lower() == "set-cookie" and value.startswith("ms_session="):
                self.cookie = value.split(";", 1)[0].split("=", 1)[1]
        conn.close()
        try:
            out = json.loads(payload)
        except ValueError:
            out = payload.decode("utf-8", "replace")
        if isinstance(out, dict) and "csrf" in out:
            self.csrf = out["csrf"]
        return resp.status, out

    def get(self, path: str) -> tuple[int, Any]:
        return self.request("GET", path)

    def post(self, path: str, body: Any, csrf: bool = True) -> tuple[int, Any]:
        return self.request("POST", path, body, csrf)

    def login(self, user: str) -> tuple[int, Any]:
        return self.post("/api/login", {"user": user, "password": USERS[user][0]})

    def set_cookie(self) -> str:
        return next(v for k, v in self.last_headers if k.lower() == "set-cookie")

    def ws_url(self) -> str:
        return f"ws://{self.host}:{self.port}/ws"

    def connect(self, origin: str | None = None, **kw: Any) -> Any:
        """``async with http.connect() as ws:`` the page's WebSocket."""
        headers = {"Cookie": f"ms_session={self.cookie}"} if self.cookie else {}
        return websockets.connect(
            self.ws_url(),
            origin=origin or self.origin,  # type: ignore[arg-type]
            additional_headers=headers,
            max_size=None,
            **kw,
        )


async def next_text(ws: Any, kind: str, timeout: float = 10.0) -> dict[str, Any]:
    """The next text message of ``kind`` (frames and other messages skipped)."""
    import asyncio

    async def wait() -> dict[str, Any]:
        while True:
            msg = await ws.recv()
            if isinstance(msg, str):
                data = json.loads(msg)
                if data.get("type") == kind:
                    return dict(data)

    return await asyncio.wait_for(wait(), timeout)


__all__ = ["USERS", "Http", "next_text", "parse_frame", "users_map"]
