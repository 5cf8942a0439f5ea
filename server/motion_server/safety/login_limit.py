"""Failed logins per client address, for every front-end that takes a password (OPC UA,
the web view): ``max_failures`` failures within ``window`` seconds lock the address out
for ``lockout`` seconds, even with the right password. The log line names the protocol
and the address, never a password."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass
class LoginLimiter:
    """``clock`` is injectable for tests; ``protocol`` and ``log`` name who refuses."""

    max_failures: int = 5
    window: float = 60.0
    lockout: float = 30.0
    clock: Callable[[], float] = time.monotonic
    protocol: str = "OPC UA"
    log: logging.Logger = field(default=logging.getLogger("motion_server.opcua"))
    _failures: dict[str, list[float]] = field(default_factory=dict)
    _locked_until: dict[str, float] = field(default_factory=dict)

    def locked(self, address: str) -> bool:
        until = self._locked_until.get(address)
        if until is None:
            return False
        if self.clock() >= until:
            del self._locked_until[address]
            self._failures.pop(address, None)
            return False
        return True

    def failed(self, address: str) -> None:
        now = self.clock()
        recent = [t for t in self._failures.get(address, []) if now - t < self.window]
        recent.append(now)
        self._failures[address] = recent
        if len(recent) >= self.max_failures:
            self._locked_until[address] = now + self.lockout
            self.log.warning(
                "%s: %d failed logins from %s: refused for %.0f s",
                self.protocol,
                len(recent),
                address,
                self.lockout,
            )

    def succeeded(self, address: str) -> None:
        self._failures.pop(address, None)
