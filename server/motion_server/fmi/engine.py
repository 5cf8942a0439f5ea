"""The controller behind an FMU: the scan in this process, stepped by the master.

:class:`CoSimController` holds a :class:`~motion_server.runtime.Runtime` (the very scan,
image and judged write queue the server runs, with no scan process and no socket) on the
manual clock, and does what an FMI Co-Simulation slave does:

- the master sets inputs: the values are kept, nothing is written yet;
- ``do_step(t, h)``: the inputs changed since the last step go to the image as one write
  batch (judged like a client's: words before bits, so a trigger sees the operands set
  with it), then the cycles that fit in ``h`` run, then the outputs are read from the
  published image. That is exactly what a Modbus client does with the manual clock:
  write the tags, then ``Clock.Step`` with ``Clock.StepCycles`` = n; the traces are bit
  for bit the same;
- the master gets outputs: values of the last published cycle.

Step sizes: a step that is a whole number of base periods (within 1e-9 of one period)
runs that many cycles. Any other step is **carried over**: the cycles that fit run and the
remainder is added to the next step, so simulated time never drifts from the master's by
a period or more; the first such step is logged as a warning through the FMU's logger,
the later ones at ``ok`` status. A step that is negative or not finite is refused
(``do_step`` returns False: the wrappers answer fmi2Discard / fmi3Discard).

The server's own warnings and errors raised while a step runs (a subnormal REAL written,
an instruction's internal error) go to the FMU's logger too. A value the tag map refuses
(out of the tag's type range, a NaN) is not written: the FMU's logger names the variable
and the reason, and the other inputs of that step are
written all the same. Nothing the master sets can crash the scan or move an axis that an
equal Modbus write would not move.

This module imports no FMI builder: the scripts shipped inside the FMU (:mod:`.slave2`,
:mod:`.slave3`) adapt it to pythonfmu and pythonfmu3.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
from collections.abc import Callable, Iterator
from enum import IntEnum
from typing import Any

from .. import config
from ..config import SiteMap
from ..runtime import Runtime
from ..tagmap import ClockMode, TagAccessError
from .serving import SERVE_NEEDS, ServedRuntime, ServeError
from .variables import Causality, Kind, Variable, fmu_variables

#: how close to a whole number of periods a step must be to count as one
WHOLE_TOLERANCE = 1e-9
_U32 = 1 << 32


class LogLevel(IntEnum):
    """The FMI status a log message is given (FMI 2.0 and 3.0 share the numbers)."""

    OK = 0
    WARNING = 1
    ERROR = 3


Logger = Callable[[str, LogLevel], None]


def _no_log(message: str, level: LogLevel) -> None:
    return None


class _Forward(logging.Handler):
    """The server's own warnings and errors (``motion_server`` loggers) raised in this
    thread, handed to the FMU's logger: the master shows them with the instance's name."""

    def __init__(self, log: Logger) -> None:
        super().__init__(logging.WARNING)
        self._log = log
        self._thread = threading.get_ident()

    def filter(self, record: logging.LogRecord) -> bool:
        return record.thread == self._thread

    def emit(self, record: logging.LogRecord) -> None:
        level = LogLevel.ERROR if record.levelno >= logging.ERROR else LogLevel.WARNING
        self._log(f"{record.name}: {record.getMessage()}", level)


@contextlib.contextmanager
def forwarding(log: Logger) -> Iterator[None]:
    """While the block runs, the server's warnings in this thread go to ``log`` too."""
    handler = _Forward(log)
    logger = logging.getLogger("motion_server")
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)


def site_for_fmu(text: str, source: str) -> SiteMap:
    """The site map as the FMU runs it: parsed without the environment's settings (the
    FMU runs the same wherever it is imported), manual clock, no retained state, no audit
    log (the FMU writes no files)."""
    site = config.parse(text, source, environ={})
    return site.model_copy(
        update={
            "controller": site.controller.model_copy(update={"clock": "manual"}),
            "retain": site.retain.model_copy(update={"enabled": False}),
            "audit": site.audit.model_copy(update={"enabled": False}),
        }
    )


class CoSimController:
    """One controller instance of the FMU (see the module docstring). ``serve``: the
    site map's front-ends serve the image while the master steps (:mod:`.serving`)."""

    def __init__(self, site: SiteMap, log: Logger = _no_log, serve: bool = False) -> None:
        self.site = site
        self.log = log
        self.runtime = Runtime(site, fresh=True)
        self.runtime.set_mode(ClockMode.MANUAL)
        self.served: ServedRuntime | None = None
        #: serve from the first step on (not when a builder instantiates the slave to
        #: write the model description)
        self._serve = serve
        view = self.runtime.image
        self.view = view
        slots = {t.name: i for i, t in enumerate(view.layout.tags)}
        self.variables: list[Variable] = fmu_variables(view.map, slots)
        self.by_name = {v.name: i for i, v in enumerate(self.variables)}
        self.period = self.runtime.period
        self._values = view.values().copy()
        #: the inputs as the master set them (value reference -> value), and as written
        self._inputs: dict[int, Any] = {}
        self._written: dict[int, Any] = {}
        for vr, var in enumerate(self.variables):
            if var.causality == Causality.INPUT:
                value = view.typed(var.slot, float(self._values[var.slot]))
                self._inputs[vr] = value
                self._written[vr] = value
        #: the part of a period carried over from steps that were not whole periods
        self.carry = 0.0
        self._carry_warned = False
        self.cycles = 0

    # -- values ---------------------------------------------------------------------------
    def get(self, vr: int) -> Any:
        """The value of variable ``vr``: an input as set, else as of the last cycle."""
        var = self.variables[vr]
        if var.causality == Causality.INPUT:
            return self._inputs[vr]
        raw = float(self._values[var.slot])
        if var.kind == Kind.BOOLEAN:
            return raw != 0.0
        if var.kind == Kind.REAL:
            return raw
        return int(raw)

    def set(self, vr: int, value: Any) -> None:
        """Set input ``vr`` (written to the image at the next step)."""
        var = self.variables[vr]
        if var.causality != Causality.INPUT:
            if value == self.get(vr):
                return
            message = f"{var.name} is fixed by the site map ({self.get(vr)!r}), not {value!r}"
            self.log(message, LogLevel.ERROR)
            raise ValueError(message)
        if var.kind == Kind.INTEGER and var.unsigned32 and int(value) < 0:
            value = int(value) + _U32
        self._inputs[vr] = value

    # -- time -----------------------------------------------------------------------------
    def cycles_for(self, step: float) -> int | None:
        """The cycles a step of ``step`` seconds runs (carry-over included), or None for a
        step that cannot be taken."""
        if not math.isfinite(step) or step < 0.0:
            self.log(f"step of {step!r} s refused: not a finite, non-negative time", LogLevel.ERROR)
            return None
        periods = self.carry + step / self.period
        whole = round(periods)
        if abs(periods - whole) <= WHOLE_TOLERANCE:
            self.carry = 0.0
            return int(whole)
        count = math.floor(periods)
        self.carry = periods - count
        message = (
            f"step of {step!r} s is not a whole number of {self.period!r} s periods: "
            f"{count} cycles run, {self.carry * self.period:.9g} s carried over to the next step"
        )
        self.log(message, LogLevel.OK if self._carry_warned else LogLevel.WARNING)
        self._carry_warned = True
        return int(count)

    def do_step(self, step: float) -> bool:
        """Write the changed inputs, run the cycles of ``step`` seconds, read the outputs."""
        count = self.cycles_for(step)
        if count is None:
            return False
        if self._serve:
            self.start_serving()
        if self.served is not None:
            self.served.call(lambda: self._step(count))
        else:
            self._step(count)
        return True

    def start_serving(self) -> None:
        """Start the front-ends (once; :class:`ServeError` when they cannot listen, or
        when the site map lets clients step the clock)."""
        self._serve = False
        if self.site.controller.remote_clock:
            raise ServeError(SERVE_NEEDS)
        self.served = ServedRuntime(self.runtime)
        port = self.served.modbus_port
        where = f"Modbus TCP on port {port}" if port is not None else "no Modbus"
        self.log(f"front-ends serving the FMU's controller: {where}", LogLevel.OK)

    def _step(self, count: int) -> None:
        with forwarding(self.log):
            self.write_inputs()
            if count:
                self.runtime.cycle(count)
                self.cycles += count
        self._values = self.view.values().copy()

    def write_inputs(self) -> None:
        changed = [vr for vr, v in self._inputs.items() if v != self._written[vr]]
        if not changed:
            return
        updates = [(self.variables[vr].tag, self._inputs[vr]) for vr in changed]
        try:
            self.view.write_many(updates)
        except (TagAccessError, ValueError, TypeError, OverflowError):
            # one refused value refuses the batch: write them one by one to name it
            for vr in changed:
                var = self.variables[vr]
                try:
                    self.view.write(var.tag, self._inputs[vr])
                except (TagAccessError, ValueError, TypeError, OverflowError) as exc:
                    message = f"{var.name} = {self._inputs[vr]!r} not written: {exc}"
                    self.log(message, LogLevel.ERROR)
        for vr in changed:
            self._written[vr] = self._inputs[vr]

    def close(self) -> None:
        """Nothing to save (no retained state); a served controller stops its groups
        (the programmed stop) and closes its front-ends."""
        if self.served is not None:
            self.served.stop()
            self.served = None
