"""Browser-test support: Debian's chromium under Playwright, and a contract stub.

- :func:`chromium` launches ``/usr/bin/chromium`` (Debian's package) through Playwright's
  Python driver, pinned in pyproject to the release whose bundled Chromium has the same
  major version; :data:`SKIP_REASON` says plainly why the browser tests cannot run here.
- :class:`ContractStub` serves the real page (``motion_server/frontends/web_static``)
  behind a small Starlette app that speaks the protocol of docs/web.md § "Protocol" with
  data the test chooses: exact trend frames (gaps included), status messages, and a record
  of every command the page sent. The page's own logic (capture, gaps, trigger, cursors,
  CSV, role gates) is tested against it deterministically; the end-to-end cases run against
  the real server in test_web_browser.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import secrets
import shutil
import socket
import struct
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

#: Debian's chromium; Playwright is pointed at it and never downloads a browser
CHROMIUM = os.environ.get("MOTION_SERVER_CHROMIUM", "/usr/bin/chromium")
#: the Chromium major the pinned Playwright (1.64.1) bundles, so the CDP protocols match
CHROMIUM_MAJOR = 156
#: flags this machine needs: root without a sandbox, no GPU, a small /dev/shm
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"]
#: the page's files as shipped in the package
STATIC = Path(str(resources.files("motion_server.frontends") / "web_static"))
#: the Content-Security-Policy the contract asks the server to send
CSP = "default-src 'self'; connect-src 'self'; frame-ancestors 'none'"
MAGIC = 0x4D535452


def _skip_reason() -> str | None:
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install -e '.[test]' installs the pinned one)"
    if not (Path(CHROMIUM).exists() or shutil.which(CHROMIUM)):
        return f"{CHROMIUM} is missing (Debian: apt-get install chromium; `make test` does it)"
    return None


SKIP_REASON = _skip_reason()


@contextlib.contextmanager
def chromium() -> Iterator[Any]:
    """A Playwright Browser on Debian's chromium (headless); checks the major version."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            major = int(browser.version.split(".")[0])
            if major != CHROMIUM_MAJOR:
                raise RuntimeError(
                    f"chromium {browser.version} does not match the pinned Playwright "
                    f"(bundles {CHROMIUM_MAJOR}); pin the playwright release that bundles "
                    f"{major} in pyproject's test extras"
                )
            yield browser
        finally:
            browser.close()


def frame(layout_id: int, rows: Sequence[Sequence[float]], gaps_before: int = 0) -> bytes:
    """A binary trend frame as docs/web.md § "Protocol" defines it; row = (tick, values…)."""
    nchan = len(rows[0]) - 1 if rows else 0
    out = [struct.pack("<IHHIIII", MAGIC, 1, nchan, layout_id, len(rows), gaps_before, 0)]
    for row in rows:
        out.append(struct.pack("<Q", int(row[0])))
        out.append(struct.pack(f"<{nchan}d", *(float(v) for v in row[1:])))
    return b"".join(out)


STUB_MODEL: dict[str, Any] = {
    "controller": {"name": "stub", "period_us": 2000, "clock": "MANUAL"},
    "axes": [
        {
            "name": name,
            "type": "servo",
            "tags": {
                f: f"{name}.{f}"
                for f in ("AxisState", "ActualPosition", "ActualVelocity", "PositionError")
            },
        }
        for name in ("Axis1", "Axis2")
    ],
    "groups": [{"name": "Group1", "tags": {"GroupState": "Group1.GroupState"}}],
    "instructions": [
        {
            "name": "MAJ_1",
            "type": "MAJ",
            "family": "logix",
            "bits": ["EN", "DN", "ER", "PC", "IP"],
            "operands": [
                {"name": "Axis", "tag": "MAJ_1.Axis", "type": "DINT", "writable": True},
                {"name": "Speed", "tag": "MAJ_1.Speed", "type": "REAL", "writable": True},
            ],
            "trigger": "MAJ_1.Execute",
        }
    ],
    "channels": [
        "Axis1.ActualPosition",
        "Axis1.ActualVelocity",
        "Axis2.ActualPosition",
        "MAJ_1.DN",
        "MAJ_1.IP",
    ],
}
USERS = {"viewer": "viewer", "operator": "operator", "admin": "admin"}


@dataclass
class ContractStub:
    """The page behind a scripted server (see the module docstring)."""

    anonymous_role: str | None = None
    calls: list[tuple[str, Any]] = field(default_factory=list)
    layouts: list[list[str]] = field(default_factory=list)
    ws_origins: list[str | None] = field(default_factory=list)
    port: int = 0

    def __post_init__(self) -> None:
        self.sessions: dict[str, dict[str, Any]] = {}
        self.layout_id = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._queue: asyncio.Queue[Any] | None = None
        self._server: Any = None
        self._thread: threading.Thread | None = None

    # -- the app ---------------------------------------------------------------------------
    def _app(self) -> Any:
        from starlette.applications import Starlette
        from starlette.requests import Request
        from starlette.responses import FileResponse, JSONResponse, Response
        from starlette.routing import Route, WebSocketRoute
        from starlette.websockets import WebSocket, WebSocketDisconnect

        stub = self

        def session_of(request: Request) -> dict[str, Any] | None:
            sid = request.cookies.get("ms_session")
            if sid and sid in stub.sessions:
                return stub.sessions[sid]
            if stub.anonymous_role:
                return {"user": None, "role": stub.anonymous_role, "csrf": "anon"}
            return None

        async def index(request: Request) -> Response:
            return FileResponse(STATIC / "index.html")

        async def static(request: Request) -> Response:
            name = request.path_params["name"]
            path = STATIC / name
            if "/" in name or not path.is_file():
                return JSONResponse({"error": "not found"}, 404)
            return FileResponse(path)

        async def session(request: Request) -> Response:
            s = session_of(request)
            if s is None:
                return JSONResponse({"error": "log in"}, 401)
            return JSONResponse(s)

        async def login(request: Request) -> Response:
            body = await request.json()
            user = body.get("user")
            if USERS.get(user) != body.get("password"):
                return JSONResponse({"error": "unknown user or wrong password"}, 401)
            sid = secrets.token_hex(16)
            stub.sessions[sid] = {"user": user, "role": user, "csrf": secrets.token_hex(8)}
            res = JSONResponse(stub.sessions[sid])
            res.set_cookie("ms_session", sid, httponly=True, samesite="strict")
            return res

        def guarded(path: str, least: str) -> Any:
            rank = {"viewer": 0, "operator": 1, "admin": 2}

            async def handler(request: Request) -> Response:
                s = session_of(request)
                if s is None:
                    return JSONResponse({"error": "log in"}, 401)
                if request.headers.get("x-csrf-token") != s["csrf"]:
                    return JSONResponse({"error": "missing or wrong CSRF token"}, 403)
                body = await request.json()
                if rank[s["role"]] < rank[least]:
                    stub.calls.append((f"refused {path}", body))
                    return JSONResponse({"error": f"{s['role']} may not {path}"}, 403)
                stub.calls.append((path, body))
                if path == "write":
                    return JSONResponse({"results": dict.fromkeys(body["writes"], "ok")})
                if path in ("trigger", "snapshot", "clock"):
                    return JSONResponse({"result": "ok"})
                if path == "logout":
                    stub.sessions.pop(request.cookies.get("ms_session", ""), None)
                return JSONResponse({"ok": True})

            return handler

        async def model(request: Request) -> Response:
            if session_of(request) is None:
                return JSONResponse({"error": "log in"}, 401)
            return JSONResponse(STUB_MODEL)

        async def ws(websocket: WebSocket) -> None:
            origin = websocket.headers.get("origin")
            stub.ws_origins.append(origin)
            host = websocket.headers.get("host")
            sid = websocket.cookies.get("ms_session")
            known = sid in stub.sessions or stub.anonymous_role is not None
            if origin != f"http://{host}" or not known:
                await websocket.close(code=1008)  # before accept: the handshake gets 403
                return
            await websocket.accept()
            queue: asyncio.Queue[Any] = asyncio.Queue()
            stub._queue = queue

            async def reader() -> None:
                try:
                    while True:
                        msg = json.loads(await websocket.receive_text())
                        if msg.get("type") == "trend":
                            stub.layout_id += 1
                            stub.layouts.append(msg["channels"])
                            await queue.put(
                                {
                                    "type": "trend-layout",
                                    "id": stub.layout_id,
                                    "channels": msg["channels"],
                                }
                            )
                finally:
                    queue.put_nowait(None)  # the page went: end the sender too

            task = asyncio.create_task(reader())
            try:
                while True:
                    item = await queue.get()
                    if item is None:
                        break
                    if item == "close":
                        await websocket.close()
                        break
                    if isinstance(item, bytes):
                        await websocket.send_bytes(item)
                    else:
                        await websocket.send_text(json.dumps(item))
            except (WebSocketDisconnect, RuntimeError):
                pass
            finally:
                task.cancel()

        def csp(app: Any) -> Any:
            async def wrapped(scope: Any, receive: Any, send: Any) -> None:
                async def send_csp(message: Any) -> None:
                    if message["type"] == "http.response.start":
                        message.setdefault("headers", [])
                        message["headers"] = [
                            *message["headers"],
                            (b"content-security-policy", CSP.encode()),
                        ]
                    await send(message)

                await app(scope, receive, send_csp)

            return wrapped

        app = Starlette(
            routes=[
                Route("/", index),
                Route("/static/{name:path}", static),
                Route("/api/session", session),
                Route("/api/login", login, methods=["POST"]),
                Route("/api/logout", guarded("logout", "viewer"), methods=["POST"]),
                Route("/api/model", model),
                Route("/api/write", guarded("write", "operator"), methods=["POST"]),
                Route("/api/trigger", guarded("trigger", "operator"), methods=["POST"]),
                Route("/api/clock", guarded("clock", "admin"), methods=["POST"]),
                Route("/api/snapshot", guarded("snapshot", "admin"), methods=["POST"]),
                WebSocketRoute("/ws", ws),
            ]
        )
        return csp(app)

    # -- running it ------------------------------------------------------------------------
    def __enter__(self) -> ContractStub:
        import uvicorn

        sock = socket.socket()
        sock.bind(("127.0.0.1", 0))
        self.port = sock.getsockname()[1]
        config = uvicorn.Config(self._app(), log_level="warning", lifespan="off")
        self._server = uvicorn.Server(config)
        ready = threading.Event()

        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            ready.set()
            loop.run_until_complete(self._server.serve(sockets=[sock]))

        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        ready.wait(10)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._server is not None:
            self._server.should_exit = True
            self._server.force_exit = True
        if self._thread is not None:
            self._thread.join(10)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def drop(self) -> None:
        """Close the page's WebSocket from the server's side (a restarted front-end)."""
        self.send("close")

    def forget_sessions(self) -> None:
        """Forget every session, as a restarted front-end does."""
        self.sessions.clear()

    def send(self, item: bytes | str | dict[str, Any]) -> None:
        """Send a frame or a JSON message to the page's WebSocket (the latest one)."""
        assert self._loop is not None and self._queue is not None, "no page connected"
        self._loop.call_soon_threadsafe(self._queue.put_nowait, item)
