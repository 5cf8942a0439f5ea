"""The FMI 2.0 Co-Simulation slave (pythonfmu): the script ``motion-server fmu --fmi 2``
ships in the FMU. It adapts :class:`~motion_server.fmi.engine.CoSimController` to
pythonfmu's :class:`Fmi2Slave`; the importing machine needs a Python with motion-server
installed (pythonfmu itself travels inside the FMU)."""

from __future__ import annotations

from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status
from pythonfmu.variables import Boolean, Integer, Real

from motion_server.fmi.engine import LogLevel
from motion_server.fmi.shipped import controller_from
from motion_server.fmi.variables import Causality, Kind, Variable

_CAUSALITY = {
    Causality.INPUT: (Fmi2Causality.input, Fmi2Variability.discrete),
    Causality.OUTPUT: (Fmi2Causality.output, Fmi2Variability.discrete),
    Causality.PARAMETER: (Fmi2Causality.parameter, Fmi2Variability.fixed),
}
_TYPES: dict[Kind, Any] = {Kind.BOOLEAN: Boolean, Kind.INTEGER: Integer, Kind.REAL: Real}
_I32 = 1 << 31


class MotionServerFmu2(Fmi2Slave):
    """A motion-server controller as an FMI 2.0 Co-Simulation slave."""

    author = "motion-server"
    description = "motion-server controller (the scan in-process, stepped by the master)"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        shipped, self.controller = controller_from(self.resources, self._log)
        self.modelName = shipped.model
        period = self.controller.period
        self.default_experiment = DefaultExperiment(0.0, 1.0, period)
        for vr, var in enumerate(self.controller.variables):
            self.register_variable(self._variable(vr, var), nested=False)

    def _variable(self, vr: int, var: Variable) -> Any:
        causality, variability = _CAUSALITY[var.causality]
        ctl = self.controller
        wraps = var.kind == Kind.INTEGER and var.unsigned32

        def getter() -> Any:
            value = ctl.get(vr)
            # FMI 2.0 integers are 32-bit signed: a UDINT of 2^31 or more as its two's complement
            return value - 2 * _I32 if wraps and value >= _I32 else value

        def setter(value: Any) -> None:
            ctl.set(vr, value)

        return _TYPES[var.kind](
            var.name,
            causality=causality,
            variability=variability,
            description=var.description,
            getter=getter,
            initial=None if var.causality == Causality.INPUT else Fmi2Initial.exact,
            setter=setter,
        )

    def _log(self, message: str, level: LogLevel) -> None:
        self.log(message, Fmi2Status(int(level)))

    def do_step(self, current_time: float, step_size: float) -> bool:
        return self.controller.do_step(step_size)

    def terminate(self) -> None:
        self.controller.close()
