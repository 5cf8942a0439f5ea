"""Audit log: every accepted and every refused client write, as JSON lines.

One line per event, for example::

    {"time": "2025-01-31T10:00:00.123456+00:00", "cycle": 1200, "event": "write",
     "result": "accepted", "protocol": "modbus", "address": "127.0.0.1", "port": 50412,
     "connection": 3, "user": "", "role": "", "tag": "MAJ_1.Speed", "old": 10.0,
     "new": 25.0}

``result`` is ``accepted`` or ``refused`` (then ``reason`` says why and ``registers``,
``tag`` or, for an OPC UA node outside the tag map, ``node`` says what); ``event`` is
``write``, ``connect`` or ``disconnect`` (connections refused by the allowlist or the
limit, idle timeouts, Modbus/TCP Security handshakes, OPC UA protocol faults).
``user`` is the OPC UA user name or the common name of a Modbus/TCP Security client
certificate (plain Modbus has none); ``role`` is the client's role (``viewer``,
``operator``, ``admin``; empty for plain Modbus). No credential is ever written: values
are those of tags, user names and certificate names only, never a password, a key or a
certificate. The file rotates by size
(``logging.handlers.RotatingFileHandler``: ``max_bytes``, ``backups``); it and its
rotations are created readable and writable by their owner only (0600).

Every line is valid UTF-8, whatever a client sent: asyncua decodes an OPC UA String
that is not UTF-8 with ``surrogateescape`` (a NodeId with the byte 0xFF arrives as
``"\\udcff"``), which no UTF-8 file takes; such bytes are written escaped, ``\\xff``,
and any other character UTF-8 cannot carry as its ``\\u`` escape (before, the line of
such a refused write was lost).
"""

from __future__ import annotations

import contextlib
import json
import logging
import logging.handlers
import math
import os
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ..config import AuditSection
from ..tagmap import Tag
from ..tagmap.codec import Value
from .client import ClientInfo, current_client


def escaped(text: str) -> str:
    r"""``text`` as UTF-8 can carry it: bytes that were not UTF-8 (decoded with
    ``surrogateescape``) as ``\xNN``, any other lone surrogate as ``\uXXXX``."""
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        pass
    try:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # surrogates that are no escaped bytes
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


def _plain(value: Any) -> Any:
    """A JSON-safe form of a tag value (non-finite floats as strings)."""
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    return escaped(str(value))


class PrivateRotatingFileHandler(logging.handlers.RotatingFileHandler):
    """A rotating file created 0600 (and an existing one made so): the audit log names
    clients, users and values, which are not everybody's to read. ``logging`` opens the
    file (and each new one after a rotation) with the process umask."""

    def _open(self) -> Any:
        fd = os.open(self.baseFilename, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
        with contextlib.suppress(OSError):  # a file of another owner keeps its mode
            os.fchmod(fd, 0o600)
        return open(fd, self.mode, encoding=self.encoding, errors=self.errors)


class AuditLog:
    """Writes audit lines to ``path`` (rotated), or to ``sink`` (tests)."""

    def __init__(
        self,
        path: str | Path | None = None,
        max_bytes: int = 10_000_000,
        backups: int = 5,
        cycle: Callable[[], int] = lambda: 0,
        sink: Callable[[str], None] | None = None,
    ) -> None:
        self.cycle = cycle
        self.lines = 0
        self._handler: logging.Handler | None = None
        self._sink = sink
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            # errors: a line another process formatted may hold lone surrogates; in a
            # JSON string their escape (backslash, u, four hex digits) is valid JSON
            handler = PrivateRotatingFileHandler(
                path,
                maxBytes=max_bytes,
                backupCount=backups,
                encoding="utf-8",
                errors="backslashreplace",
            )
            handler.setFormatter(logging.Formatter("%(message)s"))
            self._handler = handler

    @classmethod
    def from_config(
        cls, section: AuditSection, data_dir: str | Path, cycle: Callable[[], int]
    ) -> AuditLog | None:
        if not section.enabled:
            return None
        path = Path(section.path)
        if not path.is_absolute():
            path = Path(data_dir) / path
        return cls(path, section.max_bytes, section.backups, cycle)

    def close(self) -> None:
        if self._handler is not None:
            self._handler.close()
            self._handler = None

    def write_line(self, line: str) -> None:
        """Write a line another process formatted (the supervisor writes the front-ends')."""
        self.lines += 1
        if self._sink is not None:
            self._sink(line)
        if self._handler is not None:
            self._handler.emit(
                logging.LogRecord("motion_server.audit", logging.INFO, "", 0, line, None, None)
            )

    # -- events ---------------------------------------------------------------------------
    def emit(self, client: ClientInfo, event: str, result: str, **fields: Any) -> None:
        record = {
            "time": datetime.now(UTC).isoformat(),
            "cycle": self.cycle(),
            "event": event,
            "result": result,
            "protocol": client.protocol,
            "address": escaped(client.address),
            "port": client.port,
            "connection": client.connection,
            "user": escaped(client.user),
            "role": client.role,
            **{k: _plain(v) for k, v in fields.items()},
        }
        self.write_line(json.dumps(record, separators=(",", ":"), ensure_ascii=False))

    def accepted(self, tag: Tag, old: Value, new: Value) -> None:
        """A :class:`~motion_server.tagmap.TagImage` observer: one accepted tag write."""
        self.emit(current_client(), "write", "accepted", tag=tag.name, old=old, new=new)

    def refused(self, reason: str, **what: Any) -> None:
        """A refused write (``registers="5000+2"``, ``tag=...`` or ``node="i=2261"``) by
        the current client."""
        self.emit(current_client(), "write", "refused", reason=reason, **what)

    def connection(self, client: ClientInfo, event: str, result: str, reason: str = "") -> None:
        self.emit(client, event, result, reason=reason)
