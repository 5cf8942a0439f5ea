"""The web view front-end (``python -m motion_server.frontends web``): one page, a JSON
API and a WebSocket, served by Starlette on uvicorn in the web process.

What it serves, its security and its protocol are in ``docs/web.md``; this module holds
the routes. Reads come from the shared image (:class:`~.view.ImageView`), writes go
through the same judge, write queue and audit log as Modbus and OPC UA, on the web's own
channel to the scan, each under the client's identity (:func:`writing_as`). Trends come
from the scan's per-cycle ring (:mod:`.web_stream`). Every answer carries the security
headers (:class:`_Headers`); a bad request gets a one-line error, never a traceback.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import itertools
import json
import logging
import socket
import time
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import uvicorn
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Message, Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..config import OpcUaUser, SiteMap
from ..instructions.schema import TagType
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo, writing_as
from ..safety.roles import Role, required_role
from ..tagmap import ClockMode, Tag, TagAccessError
from .view import ImageView, WriteRefused, outcome
from .web_auth import COOKIE, Session, Sessions, csrf_ok, is_loopback
from .web_model import build_model, status_tags, trendable
from .web_stream import TrendClient, TrendHub

log = logging.getLogger("motion_server.web")

STATIC = Path(__file__).with_name("web_static")
#: the largest request body and WebSocket message accepted
MAX_MESSAGE = 64 * 1024
#: seconds a write waits for the scan's acknowledgement (a clock step: for its cycles)
ACK_TIMEOUT = 60.0
#: cycles one clock step may ask for
MAX_STEP = 100_000
#: status messages per second a client may ask for
MAX_STATUS_HZ = 50.0
#: bytes of a connection's kernel send buffer (no autotuning to megabytes: a slow client
#: would see trends seconds old instead of a counted gap)
SEND_BUFFER = 128 * 1024
#: trend set changes a connection may ask for per second (each makes the scan take a set)
MAX_TREND_CHANGES = 10
#: messages waiting for a client beyond which status messages are skipped for it
STATUS_BACKLOG = 10
#: WebSocket connections served at once
MAX_CONNECTIONS = 64
SECURITY_HEADERS = [
    (b"content-security-policy", b"default-src 'self'; connect-src 'self'; frame-ancestors 'none'"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"cache-control", b"no-store"),
]
#: connection numbers of this process's clients (process.py starts them per generation)
_connection_numbers = itertools.count(1)


class HttpError(Exception):
    """A request refused with ``status`` and a one-line ``message``."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status
        self.message = message


class _Headers:
    """ASGI middleware: the security headers on every HTTP answer."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *SECURITY_HEADERS]}
            await send(message)

        await self.app(scope, receive, with_headers)


class WebApp:
    """The routes of the web view over one image view."""

    def __init__(
        self,
        view: ImageView,
        site: SiteMap,
        users: list[OpcUaUser],
        audit: AuditLog | None,
        hub: TrendHub,
        tls: bool,
    ) -> None:
        self.view = view
        self.site = site
        self.audit = audit
        self.hub = hub
        self.tls = tls
        self.sessions = Sessions(site, users, tls)
        self.model = build_model(site, view.map)
        self.model_body = json.dumps(self.model, separators=(",", ":")).encode("utf-8")
        self._trendable = {t.name for t in view.map if trendable(t)}
        status = status_tags(view.map)
        self._status_names = [t.name for t in status]
        self._status_slots = np.array([view.slot(t) for t in status], dtype=np.int64)
        self._status_types = [t.type for t in status]
        self._diag = {
            name: view.slot(name)
            for name in (
                "Diagnostics.CycleTime",
                "Diagnostics.Overruns",
                "Diagnostics.FrontendRestarts",
            )
            if name in view.map
        }
        self.connections = 0
        routes = [
            Route("/", self.index),
            Route("/api/session", self.session_info),
            Route("/api/login", self.login, methods=["POST"]),
            Route("/api/logout", self.logout, methods=["POST"]),
            Route("/api/model", self.get_model),
            Route("/api/write", self.write, methods=["POST"]),
            Route("/api/trigger", self.trigger, methods=["POST"]),
            Route("/api/clock", self.clock, methods=["POST"]),
            Route("/api/snapshot", self.snapshot, methods=["POST"]),
            WebSocketRoute("/ws", self.websocket),
            Mount("/static", StaticFiles(directory=STATIC, check_dir=False), name="static"),
        ]
        self.app = _Headers(
            Starlette(routes=routes, exception_handlers={HttpError: self._error})  # type: ignore[dict-item]
        )

    # -- plumbing -------------------------------------------------------------------------
    async def _error(self, request: Request, exc: HttpError) -> Response:
        return JSONResponse({"error": exc.message}, exc.status)

    def _session(self, request: Request | WebSocket) -> Session | None:
        return self.sessions.get(request.cookies.get(COOKIE))

    def _require(self, request: Request, role: Role, post: bool = True) -> Session:
        """The request's session, with at least ``role`` and (a POST) the CSRF token."""
        session = self._session(request)
        if session is None:
            session = self._anonymous(request)
        if session is None:
            raise HttpError(401, "log in first")
        if post:
            self._same_origin(request)
        if post and not csrf_ok(session, request.headers.get("x-csrf-token")):
            raise HttpError(403, "missing or wrong X-CSRF-Token")
        if session.role < role:
            raise HttpError(403, f"role {session.role.label} may not do this ({role.label} needed)")
        return session

    def _same_origin(self, request: Request) -> None:
        """403 for a POST a browser sent from another origin (an Origin header that is
        not this server's); a client that sends none (not a browser) passes, the CSRF
        token still applies."""
        origin = request.headers.get("origin")
        if origin is not None and not self.origin_ok(request):
            raise HttpError(403, "cross-origin request refused")

    def _anonymous(self, request: Request) -> Session | None:
        """An anonymous session when allowed (its cookie is set on the answer)."""
        session = self.sessions.anonymous_session()
        if session is not None:
            request.state.new_session = session
        return session

    def _respond(self, request: Request, body: Any, status: int = 200) -> Response:
        response = JSONResponse(body, status)
        new = getattr(request.state, "new_session", None)
        if new is not None:
            self._set_cookie(response, new)
        return response

    def _set_cookie(self, response: Response, session: Session) -> None:
        response.set_cookie(
            COOKIE,
            session.id,
            httponly=True,
            samesite="strict",
            secure=self.tls,
            path="/",
        )

    async def _json(self, request: Request) -> dict[str, Any]:
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_MESSAGE):
            raise HttpError(413, f"request body larger than {MAX_MESSAGE} bytes")
        body = b""
        async for chunk in request.stream():
            body += chunk
            if len(body) > MAX_MESSAGE:
                raise HttpError(413, f"request body larger than {MAX_MESSAGE} bytes")
        try:
            data = json.loads(body)
        except (ValueError, UnicodeDecodeError):
            raise HttpError(400, "the body is not JSON") from None
        if not isinstance(data, dict):
            raise HttpError(400, "the body must be a JSON object")
        return data

    def _client(self, request: Request | WebSocket, session: Session) -> ClientInfo:
        peer = request.client
        return ClientInfo(
            "web",
            peer.host if peer else "",
            peer.port if peer else 0,
            next(_connection_numbers),
            session.user or "",
            session.role.label,
        )

    def _who(self, session: Session) -> dict[str, Any]:
        return {"user": session.user, "role": session.role.label, "csrf": session.csrf}

    # -- pages and session ----------------------------------------------------------------
    async def index(self, request: Request) -> Response:
        page = STATIC / "index.html"
        if page.is_file():
            return FileResponse(page)
        return PlainTextResponse("motion-server web view: the page is not installed", 503)

    async def session_info(self, request: Request) -> Response:
        session = self._session(request) or self._anonymous(request)
        if session is None:
            return JSONResponse({"error": "log in first"}, 401)
        return self._respond(request, self._who(session))

    async def login(self, request: Request) -> Response:
        peer = request.client.host if request.client else ""
        if not self.sessions.password_allowed:
            raise HttpError(
                403,
                "login refused: a password is never sent over plain HTTP to a non-loopback "
                "address; configure [web] cert_file and key_file (HTTPS)",
            )
        self._same_origin(request)
        data = await self._json(request)
        user, password = data.get("user"), data.get("password")
        if not isinstance(user, str) or not isinstance(password, str):
            raise HttpError(400, 'expected {"user": str, "password": str}')
        limiter = self.sessions.limiter
        if limiter.locked(peer):
            raise HttpError(401, "too many failed logins from this address: try again later")
        role = await asyncio.to_thread(self.sessions.check, user, password)
        port = request.client.port if request.client else 0
        if role is None:
            limiter.failed(peer)
            log.warning("web: failed login for user %r from %s", user[:64], peer)
            if self.audit is not None:
                who = ClientInfo("web", peer, port, 0, user[:64])
                self.audit.connection(who, "login", "refused", "wrong user name or password")
            raise HttpError(401, "wrong user name or password")
        limiter.succeeded(peer)
        self.sessions.logout(request.cookies.get(COOKIE))
        session = self.sessions.login(user, role)
        if self.audit is not None:
            who = ClientInfo("web", peer, port, 0, user, role.label)
            self.audit.connection(who, "login", "accepted")
        log.info("web: %s logged in from %s (%s)", user, peer, role.label)
        response = JSONResponse(self._who(session))
        self._set_cookie(response, session)
        return response

    async def logout(self, request: Request) -> Response:
        self._require(request, Role.VIEWER)
        self.sessions.logout(request.cookies.get(COOKIE))
        response = JSONResponse({})
        response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict", secure=self.tls)
        return response

    async def get_model(self, request: Request) -> Response:
        self._require(request, Role.VIEWER, post=False)
        response = Response(self.model_body, media_type="application/json")
        new = getattr(request.state, "new_session", None)
        if new is not None:
            self._set_cookie(response, new)
        return response

    # -- commands -------------------------------------------------------------------------
    def _judge(self, session: Session, name: Any, value: Any) -> tuple[Tag | None, str]:
        """(tag, "") when ``session`` may write ``value`` to ``name``; else (tag, why)."""
        if not isinstance(name, str) or name not in self.view.map:
            return None, f"unknown tag {str(name)[:100]!r}"
        tag = self.view.map.tag(name)
        if not tag.writable:
            return tag, f"{name} is read-only"
        need = required_role(tag)
        if session.role < need:
            return tag, f"role {session.role.label} may not write {name} ({need.label} needed)"
        is_bool = tag.type == TagType.BOOL
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not number and not (is_bool and isinstance(value, bool)):
            return tag, f"{name}: expected a number{' or a bool' * is_bool}"
        try:
            self.view.judge(tag, value)
        except TagAccessError as exc:
            return tag, str(exc)
        return tag, ""

    async def _write(
        self, session: Session, request: Request, values: dict[str, Any], wait: bool = False
    ) -> None:
        """Write ``values`` (already judged) as one batch; WriteRefused when the scan
        refuses it, TimeoutError when it does not answer. ``wait``: until the image shows
        it, even when the protocol answer need not wait (a trigger's low level must be
        scanned before the high one is written)."""
        with writing_as(self._client(request, session)):
            ticket = self.view.write_many(values.items())
        if ticket.waits or wait:
            await asyncio.wait_for(outcome(ticket), ACK_TIMEOUT)

    async def write(self, request: Request) -> Response:
        session = self._require(request, Role.OPERATOR)
        data = await self._json(request)
        writes = data.get("writes")
        if not isinstance(writes, dict) or not writes:
            raise HttpError(400, 'expected {"writes": {tag: value, ...}}')
        if len(writes) > 1000:
            raise HttpError(400, "at most 1000 tags per write")
        results: dict[str, str] = {}
        refused = False
        with writing_as(self._client(request, session)):
            for name, value in writes.items():
                _, why = self._judge(session, name, value)
                results[str(name)] = why or "ok"
                if why:
                    refused = True
                    if self.audit is not None:
                        self.audit.refused(why, tag=str(name)[:100])
        if refused:
            for name, result in results.items():
                if result == "ok":
                    results[name] = "not written"
            return self._respond(request, {"results": results})
        try:
            await self._write(session, request, writes)
        except (WriteRefused, TimeoutError, TagAccessError) as exc:
            why = str(exc) or "the scan did not answer in time"
            return self._respond(request, {"results": dict.fromkeys(results, why)})
        return self._respond(request, {"results": results})

    async def trigger(self, request: Request) -> Response:
        session = self._require(request, Role.OPERATOR)
        data = await self._json(request)
        name = data.get("instruction")
        instances = {i["name"]: i for i in self.model["instructions"]}
        if not isinstance(name, str) or name not in instances:
            raise HttpError(400, f"unknown instruction {str(name)[:100]!r}")
        trigger = instances[name]["trigger"]
        if not trigger:
            raise HttpError(400, f"{name} has no trigger")
        note = ""
        try:
            if self.view.read(trigger):
                await self._write(session, request, {trigger: False}, wait=True)
                if self.view.mode == ClockMode.MANUAL:
                    note = " (manual clock: step the clock to see the edge)"
            await self._write(session, request, {trigger: True})
        except (WriteRefused, TimeoutError, TagAccessError) as exc:
            return self._respond(request, {"result": str(exc) or "the scan did not answer"})
        return self._respond(request, {"result": "ok" + note})

    async def clock(self, request: Request) -> Response:
        session = self._require(request, Role.ADMIN)
        data = await self._json(request)
        action = data.get("action")
        try:
            if action == "step":
                cycles = data.get("cycles", 1)
                if isinstance(cycles, bool) or not isinstance(cycles, int):
                    raise HttpError(400, "cycles: expected an integer")
                if not 1 <= cycles <= MAX_STEP:
                    raise HttpError(400, f"cycles: {cycles} out of range 1..{MAX_STEP}")
                if self.view.mode != ClockMode.MANUAL:
                    raise HttpError(409, "step needs the manual clock: pause first")
                await self._write(session, request, {"Clock.StepCycles": cycles})
                await self._write(session, request, {"Clock.Step": False}, wait=True)
                await self._write(session, request, {"Clock.Step": True})
            elif action == "pause":
                await self._write(session, request, {"Clock.Mode": int(ClockMode.MANUAL)})
            elif action == "run":
                mode = ClockMode[self.site.controller.clock.upper()]
                if mode == ClockMode.MANUAL:
                    mode = ClockMode.REALTIME
                await self._write(session, request, {"Clock.Mode": int(mode)})
            else:
                raise HttpError(400, 'action: expected "step", "pause" or "run"')
        except (WriteRefused, TimeoutError, TagAccessError) as exc:
            return self._respond(request, {"result": str(exc) or "the scan did not answer"})
        return self._respond(request, {"result": "ok", "tick": self.view.tick})

    async def snapshot(self, request: Request) -> Response:
        session = self._require(request, Role.ADMIN)
        data = await self._json(request)
        action, number = data.get("action"), data.get("number", 0)
        if action not in ("save", "restore"):
            raise HttpError(400, 'action: expected "save" or "restore"')
        if isinstance(number, bool) or not isinstance(number, int) or number < 0:
            raise HttpError(400, "number: expected an integer ≥ 0")
        command = "Clock.SnapshotSave" if action == "save" else "Clock.SnapshotRestore"
        try:
            await self._write(
                session, request, {"Clock.Snapshot": number, command: False}, wait=True
            )
            await self._write(session, request, {command: True})
        except (WriteRefused, TimeoutError, TagAccessError) as exc:
            return self._respond(request, {"result": str(exc) or "the scan did not answer"})
        return self._respond(request, {"result": "ok"})

    # -- WebSocket ------------------------------------------------------------------------
    def origin_ok(self, ws: WebSocket | Request) -> bool:
        """The request's Origin is this server's own origin, for a Host this server
        answers to (a DNS name pointed at it by someone else is not)."""
        origin = ws.headers.get("origin", "")
        host = ws.headers.get("host", "")
        scheme = "https" if self.tls else "http"
        if not origin or not host or origin != f"{scheme}://{host}":
            return False
        name = urlsplit(f"//{host}").hostname or ""
        bind = self.site.web.host
        if name in self.site.web.allowed_hosts or name == bind:
            return True
        if is_loopback(bind):
            return name == "localhost" or is_loopback(name)
        if bind in ("0.0.0.0", "::"):
            return _is_ip(name) or name == "localhost"
        return False

    async def websocket(self, ws: WebSocket) -> None:
        peer = ws.client.host if ws.client else ""
        if not self.origin_ok(ws):
            log.warning("web: WebSocket from %s refused: origin %r", peer, ws.headers.get("origin"))
            await ws.close(code=1008)
            return
        session = self._session(ws) or self.sessions.anonymous_session()
        if session is None:
            await ws.close(code=1008)
            return
        if self.connections >= MAX_CONNECTIONS:
            await ws.close(code=1013)
            return
        self.connections += 1
        try:
            await ws.accept()
            await self._serve_ws(ws, session)
        finally:
            self.connections -= 1

    async def _serve_ws(self, ws: WebSocket, session: Session) -> None:
        client = TrendClient()
        client.say({"type": "hello", "user": session.user, "role": session.role.label})
        status_task: asyncio.Task[None] | None = None
        changes: collections.deque[float] = collections.deque()
        sender = asyncio.create_task(self._send_loop(ws, client))
        try:
            while True:
                try:
                    message = await ws.receive()
                except (WebSocketDisconnect, RuntimeError):
                    return
                if message["type"] == "websocket.disconnect":
                    return
                text = message.get("text")
                if text is None:
                    client.say({"type": "error", "message": "expected a JSON text message"})
                    continue
                try:
                    msg = json.loads(text)
                    if not isinstance(msg, dict):
                        raise ValueError
                except ValueError:
                    client.say({"type": "error", "message": "expected a JSON object"})
                    continue
                kind = msg.get("type")
                if kind == "status":
                    hz = msg.get("hz", 20)
                    if isinstance(hz, bool) or not isinstance(hz, (int, float)):
                        client.say({"type": "error", "message": "status: hz must be a number"})
                        continue
                    if status_task is not None:
                        status_task.cancel()
                        status_task = None
                    if hz > 0:
                        rate = min(float(hz), MAX_STATUS_HZ)
                        status_task = asyncio.create_task(self._status_loop(client, rate))
                elif kind == "trend":
                    now = time.monotonic()
                    while changes and now - changes[0] > 1.0:
                        changes.popleft()
                    if len(changes) >= MAX_TREND_CHANGES:
                        limit = f"trend: at most {MAX_TREND_CHANGES} changes a second"
                        client.say({"type": "error", "message": limit})
                        continue
                    changes.append(now)
                    self._trend(client, msg.get("channels"))
                else:
                    client.say({"type": "error", "message": f"unknown message type {kind!r}"})
        finally:
            self.hub.remove(client)
            for task in (status_task, sender):
                if task is not None:
                    task.cancel()
                    with contextlib.suppress(asyncio.CancelledError, Exception):
                        await task

    def _trend(self, client: TrendClient, channels: Any) -> None:
        if not isinstance(channels, list) or not all(isinstance(c, str) for c in channels):
            client.say({"type": "error", "message": "trend: channels must be a list of tag names"})
            return
        unknown = [c for c in channels if c not in self._trendable]
        if unknown:
            listed = ", ".join(repr(c[:100]) for c in unknown[:5])
            client.say({"type": "error", "message": f"trend: unknown channel(s) {listed}"})
            return
        names = list(dict.fromkeys(channels))
        try:
            self.hub.set_channels(client, names, [self.view.slot(c) for c in names])
        except ValueError as exc:
            client.say({"type": "error", "message": f"trend: {exc}"})

    async def _send_loop(self, ws: WebSocket, client: TrendClient) -> None:
        while True:
            item = await client.next()
            if isinstance(item, bytes):
                await ws.send_bytes(item)
            else:
                await ws.send_text(json.dumps(item, separators=(",", ":")))

    async def _status_loop(self, client: TrendClient, hz: float) -> None:
        last: np.ndarray | None = None
        view = self.view
        while True:
            if client.queue.qsize() > STATUS_BACKLOG:
                # the client reads too slowly: skip, and send every value next time (a
                # message of changes only would leave it with stale ones)
                last = None
                await asyncio.sleep(1.0 / hz)
                continue
            values = view.values()
            now = values[self._status_slots]
            if last is None:
                changed = np.arange(len(now))
            else:
                changed = np.nonzero(now != last)[0]
            last = now
            typed = {
                self._status_names[i]: _typed(self._status_types[i], float(now[i]))
                for i in changed.tolist()
            }
            snap = view.snapshot()
            diag = {k: float(values[s]) for k, s in self._diag.items()}
            client.say(
                {
                    "type": "status",
                    "tick": snap.tick,
                    "cycle_us": diag.get("Diagnostics.CycleTime", 0.0),
                    "overruns": int(diag.get("Diagnostics.Overruns", 0)),
                    "clock": ClockMode(view.mode).name,
                    "frontends": {"restarts": int(diag.get("Diagnostics.FrontendRestarts", 0))},
                    "values": typed,
                }
            )
            await asyncio.sleep(1.0 / hz)


def _typed(tag_type: TagType, raw: float) -> bool | int | float:
    if tag_type == TagType.BOOL:
        return raw != 0.0
    if tag_type.is_float:
        return raw
    return int(raw)


def _is_ip(name: str) -> bool:
    try:
        socket.inet_pton(socket.AF_INET6 if ":" in name else socket.AF_INET, name)
    except OSError:
        return False
    return True


class WebFrontend:
    """The web view on uvicorn: :meth:`start` binds and serves, :meth:`stop` ends."""

    def __init__(
        self,
        view: ImageView,
        site: SiteMap,
        users: list[OpcUaUser],
        audit: AuditLog | None,
        hub: TrendHub,
    ) -> None:
        cfg = site.web
        self.cfg = cfg
        self.tls = bool(cfg.cert_file)
        self.web = WebApp(view, site, users, audit, hub, self.tls)
        self.hub = hub
        self.port = 0
        self._sock: socket.socket | None = None
        self._server: uvicorn.Server | None = None
        self._loop_task: asyncio.Task[None] | None = None

    @property
    def url(self) -> str:
        host = self.cfg.host
        if host in ("0.0.0.0", "::"):
            host = "127.0.0.1"
        if ":" in host:
            host = f"[{host}]"
        return f"{'https' if self.tls else 'http'}://{host}:{self.port}/"

    async def start(self) -> None:
        """Bind and serve (OSError: the address, the port, a certificate file)."""
        cfg = self.cfg
        config = uvicorn.Config(
            self.web.app,
            host=cfg.host,
            port=cfg.port,
            ssl_certfile=cfg.cert_file or None,
            ssl_keyfile=cfg.key_file or None,
            ws="websockets-sansio",
            ws_max_size=MAX_MESSAGE,
            ws_per_message_deflate=False,
            lifespan="off",
            access_log=False,
            log_config=None,  # the server's own log format (launch.setup_logging)
            log_level="warning",
            server_header=False,
        )
        config.load()
        family = socket.AF_INET6 if ":" in cfg.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        # the connections inherit it: a client that reads slowly has at most this much
        # of old trend data waiting in the kernel, then frames are dropped (and counted)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER)
        try:
            sock.bind((cfg.host, cfg.port))
            sock.listen(128)
        except OSError:
            sock.close()
            raise
        sock.setblocking(False)
        self._sock = sock
        self.port = sock.getsockname()[1]
        server = uvicorn.Server(config)
        server.lifespan = config.lifespan_class(config)
        await server.startup(sockets=[sock])
        self._server = server
        self._loop_task = asyncio.create_task(server.main_loop())
        self.hub.start()
        log.info("web view on %s", self.url)

    async def stop(self) -> None:
        await self.hub.stop()
        server = self._server
        if server is None:
            return
        server.should_exit = True
        server.force_exit = True
        if self._loop_task is not None:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await asyncio.wait_for(self._loop_task, 2.0)
        with contextlib.suppress(Exception):
            sockets = [self._sock] if self._sock else None
            await asyncio.wait_for(server.shutdown(sockets=sockets), 3.0)
