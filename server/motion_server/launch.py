"""What the supervisor tells a process it starts (the scan, a front-end): one JSON line
on the child's standard input. The pipe stays open afterwards as a lifeline: when it
reaches end of file, the supervisor is gone and the child stops. A child that is hung
cannot read its lifeline: :func:`follow_supervisor` also has the kernel kill it when the
supervisor ends, however it ends (SIGKILL, the OOM killer), so no process outlives it.

The site map travels as validated data (``SiteMap.model_dump``), so the child neither
reads files nor the environment again: every process serves exactly the map the
supervisor checked, with the command line's overrides applied.
"""

from __future__ import annotations

import ctypes
import json
import logging
import os
import signal
import sys
from dataclasses import asdict, dataclass, field
from typing import IO, Any

from .config import OpcUaUser, SiteMap

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


@dataclass
class LaunchSpec:
    """Everything a child process needs. ``channels``: channel number -> inherited file
    descriptor of its socket; ``image_fd``: the shared image (memfd)."""

    site: dict[str, Any]
    source: str
    log_level: str
    image_fd: int
    image_size: int
    channels: dict[int, int]
    fresh: bool = False
    users: list[dict[str, Any]] = field(default_factory=list)
    #: how many times this front-end was started before (connection numbers stay unique)
    generation: int = 0
    #: the supervisor's pid (0: started by something else)
    supervisor: int = 0
    #: the trend ring (:mod:`motion_server.image.trend`) of the web view: its memfd and
    #: size (-1, 0: none)
    trend_fd: int = -1
    trend_size: int = 0

    @classmethod
    def build(
        cls,
        site: SiteMap,
        log_level: str,
        image_fd: int,
        image_size: int,
        channels: dict[int, int],
        users: list[OpcUaUser] | None = None,
        **extra: Any,
    ) -> LaunchSpec:
        return cls(
            site=site.model_dump(mode="json"),
            source=site.source,
            log_level=log_level,
            image_fd=image_fd,
            image_size=image_size,
            channels=channels,
            users=[u.model_dump(mode="json") for u in users or []],
            **extra,
        )

    def encode(self) -> bytes:
        return (json.dumps(asdict(self), separators=(",", ":")) + "\n").encode("utf-8")

    @classmethod
    def read(cls, stream: IO[bytes]) -> LaunchSpec:
        line = stream.readline()
        if not line:
            raise SystemExit("motion-server: no launch spec on standard input")
        data = json.loads(line)
        data["channels"] = {int(k): int(v) for k, v in data["channels"].items()}
        return cls(**data)

    def site_map(self) -> SiteMap:
        return SiteMap.model_validate({**self.site, "source": self.source})

    def opcua_users(self) -> list[OpcUaUser]:
        return [OpcUaUser.model_validate(u) for u in self.users]


#: prctl(2) option: the signal a process gets when its parent ends
PR_SET_PDEATHSIG = 1


def follow_supervisor(spec: LaunchSpec) -> None:
    """SIGKILL this process when the supervisor that started it ends (Linux; elsewhere
    the lifeline alone). Exits at once when the supervisor is already gone."""
    if not spec.supervisor:
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        return
    if os.getppid() != spec.supervisor and not _alive(spec.supervisor):
        # it ended before the line above (a parent that is not the supervisor but lives
        # is a launcher between the two, which then stands for it)
        raise SystemExit("motion-server: the supervisor is gone")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def setup_logging(level: str) -> None:
    """The server's log format on standard error, in every process."""
    logging.basicConfig(level=level.upper(), format=LOG_FORMAT, stream=sys.stderr)
    if level.upper() != "DEBUG":
        # asyncua reports every standard node it loads at INFO: thousands of lines
        logging.getLogger("asyncua").setLevel(logging.WARNING)
        # it also logs a bind failure with a traceback; the front-end reports it in one line
        logging.getLogger("asyncua.server.server").setLevel(logging.CRITICAL)
    # asyncua's UaProcessor logs every ServiceFault it answers at ERROR ("sending service
    # fault response: ..."), though each is a client's request refused with a status
    # code (BadTooManyOperations, BadSessionIdInvalid, ...), not a server error
    logging.getLogger("asyncua.server.uaprocessor").addFilter(_service_fault_as_warning)


def _service_fault_as_warning(record: logging.LogRecord) -> bool:
    if record.levelno == logging.ERROR and str(record.msg).startswith("sending service fault"):
        record.levelno, record.levelname = logging.WARNING, "WARNING"
    return True
