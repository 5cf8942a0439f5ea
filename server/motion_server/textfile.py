"""Reading a text file the server is given (site map, users file, retain file, snapshot)
without being made to hang or to swallow a disk: regular files only (opened without
blocking, so a FIFO or a device is refused, never waited on), at most a given size,
UTF-8. Each caller words the refusal as its own one-line error."""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from enum import IntEnum
from pathlib import Path


class Refusal(IntEnum):
    UNREADABLE = 1
    NOT_REGULAR = 2
    TOO_LARGE = 3
    NOT_UTF8 = 4


class TextFileError(Exception):
    """Why the file was refused. ``reason``: the system's words for UNREADABLE;
    ``size``: the size the file announced, when that was too large before reading;
    ``line``: the line of the first byte that is not UTF-8."""

    def __init__(self, refusal: Refusal, reason: str = "", size: int = 0, line: int = 0) -> None:
        super().__init__(reason or refusal.name.lower().replace("_", " "))
        self.refusal = refusal
        self.reason = reason
        self.size = size
        self.line = line


def read_text_file(path: str | Path, limit: int) -> str:
    """The text of ``path``. FileNotFoundError when there is no such file (callers decide
    what that means); :class:`TextFileError` for every other refusal."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        raise TextFileError(Refusal.UNREADABLE, _reason(exc)) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise TextFileError(Refusal.NOT_REGULAR)
        if info.st_size > limit:
            raise TextFileError(Refusal.TOO_LARGE, size=info.st_size)
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(limit + 1)
    except OSError as exc:
        raise TextFileError(Refusal.UNREADABLE, _reason(exc)) from None
    finally:
        os.close(fd)
    if len(data) > limit:  # it grew while we read
        raise TextFileError(Refusal.TOO_LARGE)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise TextFileError(Refusal.NOT_UTF8, line=line) from None


def explain(exc: TextFileError, words: Mapping[Refusal, str]) -> str:
    """The caller's words for ``exc``: ``words[refusal]`` with ``{reason}``, ``{size}``
    and ``{line}`` filled in."""
    return words[exc.refusal].format(reason=exc.reason, size=exc.size, line=exc.line)


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc)
