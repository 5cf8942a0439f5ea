"""The OPC UA front-end's log under hostile traffic: one line per refused message at
most, no traceback, and a bound on the lines per time.

A client can make the server refuse as many messages as it can send, and each refusal
may leave a line: a connection closed for a fault (:mod:`.opcua_wire`), a request
answered with a ServiceFault (asyncua logs each one), a write refused. 2,207 mutated
messages once wrote 359 tracebacks. The causes of the tracebacks are fixed where they
arise (:mod:`.opcua_wire`); :class:`FloodGate` bounds what is left: at most
:data:`LINES` lines per :data:`WINDOW_S` seconds from the loggers it guards, the rest
counted and reported in one line once the window is over::

    WARNING motion_server.opcua: OPC UA: 312 more log lines suppressed in the last 10 s
    (at most 20 per 10 s)

A line that passes keeps its text; if it carries an exception (``log.exception``) the
exception's type and message are appended and the traceback dropped, unless the logger
is at DEBUG (where a developer wants the stack).

The gate guards ``motion_server.opcua`` and every ``asyncua`` logger: asyncua logs at
its module loggers (``asyncua.server.uaprocessor``: "sending service fault response",
"Error while processing message" with a stack), and a filter on a logger sees only the
records logged on that very logger, so each one gets the filter.

Use::

    gate = FloodGate()
    gate.install()     # on the loggers; gate.remove() takes it off again
    gate.flush()       # now and then (the front-end's idle sweep): report a past window
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

#: the most lines per window, and the window
LINES = 20
WINDOW_S = 10.0
#: the loggers guarded (and every logger under ``asyncua``)
GUARDED = ("motion_server.opcua", "asyncua")

log = logging.getLogger("motion_server.opcua")


class FloodGate(logging.Filter):
    """At most ``lines`` records per ``window`` seconds pass; see the module docstring."""

    def __init__(
        self,
        lines: int = LINES,
        window: float = WINDOW_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__()
        self.lines, self.window, self.clock = lines, window, clock
        self._start = clock()
        self._passed = 0
        self._held = 0  # suppressed in the current window
        #: records suppressed since the gate was made (diagnostics, tests)
        self.suppressed = 0
        self._loggers: list[logging.Logger] = []
        self._reporting = False

    def filter(self, record: logging.LogRecord) -> bool:
        if self._reporting:
            return True
        now = self.clock()
        if now - self._start >= self.window:
            self._roll(now)
        if self._passed >= self.lines:
            self._held += 1
            self.suppressed += 1
            return False
        self._passed += 1
        _one_line(record)
        return True

    def flush(self) -> None:
        """Report the lines suppressed in a window that is over (none may follow)."""
        now = self.clock()
        if now - self._start >= self.window:
            self._roll(now)

    def _roll(self, now: float) -> None:
        held, window = self._held, now - self._start
        self._start, self._passed, self._held = now, 0, 0
        if held:
            self._reporting = True
            try:
                log.warning(
                    "OPC UA: %d more log lines suppressed in the last %.0f s "
                    "(at most %d per %.0f s)",
                    held,
                    window,
                    self.lines,
                    self.window,
                )
            finally:
                self._reporting = False

    # -- installation ---------------------------------------------------------------------
    def install(self) -> None:
        """Put the gate on ``motion_server.opcua`` and on every asyncua logger there is
        (asyncua makes its module loggers when imported, as this module's importer did)."""
        names = [GUARDED[0]] + [
            name
            for name in list(logging.Logger.manager.loggerDict)
            if name == GUARDED[1] or name.startswith(GUARDED[1] + ".")
        ]
        for name in names:
            logger = logging.getLogger(name)
            logger.addFilter(self)
            self._loggers.append(logger)

    def remove(self) -> None:
        for logger in self._loggers:
            logger.removeFilter(self)
        self._loggers.clear()


def _one_line(record: logging.LogRecord) -> None:
    """Drop the traceback of ``record`` (its exception's type and message stay in the
    line), unless its logger is at DEBUG."""
    if record.exc_info is None or logging.getLogger(record.name).isEnabledFor(logging.DEBUG):
        return
    exc = record.exc_info[1]
    if exc is not None:
        record.msg = f"{record.getMessage()} ({type(exc).__name__}: {exc})"
        record.args = None
    record.exc_info = None
    record.exc_text = None
    record.stack_info = None
