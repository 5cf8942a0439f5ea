"""Who is writing: the client of the request a front-end is serving.

A front-end wraps each request in :func:`writing_as`; the watchdogs (per-connection
heartbeats) and the audit log read :func:`current_client`. It is a context variable, so
requests served by concurrent asyncio tasks never see each other's client.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar
from dataclasses import dataclass


@dataclass(frozen=True)
class ClientInfo:
    """One client connection. ``connection`` is unique per connection for the server's
    life (a reconnect from the same address is a new connection); ``user`` is the OPC UA
    user name or, for Modbus/TCP Security, the common name of the client certificate
    (empty for plain Modbus TCP, which has none); ``role`` is the client's role
    (``viewer``, ``operator``, ``admin``; empty for plain Modbus TCP)."""

    protocol: str
    address: str
    port: int = 0
    connection: int = 0
    user: str = ""
    role: str = ""

    @property
    def key(self) -> str:
        return f"{self.protocol}:{self.connection}:{self.address}:{self.port}"


_CLIENT: ContextVar[ClientInfo | None] = ContextVar("motion_server_client", default=None)

#: the client of writes made by the server itself, tests or a local tool
LOCAL = ClientInfo("local", "")


def current_client() -> ClientInfo:
    """The client of the request being served (:data:`LOCAL` outside a request)."""
    return _CLIENT.get() or LOCAL


@contextlib.contextmanager
def writing_as(client: ClientInfo) -> Iterator[ClientInfo]:
    """Serve the writes of this block on behalf of ``client``."""
    token = _CLIENT.set(client)
    try:
        yield client
    finally:
        _CLIENT.reset(token)
