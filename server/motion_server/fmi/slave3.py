"""The FMI 3.0 Co-Simulation slave (pythonfmu3): the script ``motion-server fmu --fmi 3``
ships in the FMU. It adapts :class:`~motion_server.fmi.engine.CoSimController` to
pythonfmu3's :class:`Fmi3Slave`; the importing machine needs a Python with motion-server
installed (pythonfmu3 itself travels inside the FMU). A UDINT tag is an Int64 here."""

from __future__ import annotations

from typing import Any

from pythonfmu3 import Fmi3Causality, Fmi3Initial, Fmi3Slave, Fmi3Status, Fmi3Variability
from pythonfmu3.default_experiment import DefaultExperiment
from pythonfmu3.variables import Boolean, Float64, Int32, Int64

from motion_server.fmi.engine import LogLevel
from motion_server.fmi.shipped import controller_from
from motion_server.fmi.variables import Causality, Kind, Variable

_CAUSALITY = {
    Causality.INPUT: (Fmi3Causality.input, Fmi3Variability.discrete),
    Causality.OUTPUT: (Fmi3Causality.output, Fmi3Variability.discrete),
    Causality.PARAMETER: (Fmi3Causality.parameter, Fmi3Variability.fixed),
}


class MotionServerFmu3(Fmi3Slave):
    """A motion-server controller as an FMI 3.0 Co-Simulation slave."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        shipped, self.controller = controller_from(self.resources, self._log)
        self.modelName = shipped.model
        self.author = "motion-server"
        self.description = "motion-server controller (the scan in-process, stepped by the master)"
        self.default_experiment = DefaultExperiment(0.0, 1.0, self.controller.period)
        for vr, var in enumerate(self.controller.variables):
            self.register_variable(self._variable(vr, var), nested=False)
        # FMI 3.0 wants the independent variable declared (value reference: the last)
        ctl = self.controller
        time = Float64(
            "time",
            causality=Fmi3Causality.independent,
            variability=Fmi3Variability.continuous,
            description="simulated time [s]",
            getter=lambda: ctl.runtime.sim_time,
        )
        self.register_variable(time, nested=False)

    def _variable(self, vr: int, var: Variable) -> Any:
        causality, variability = _CAUSALITY[var.causality]
        ctl = self.controller
        if var.kind == Kind.BOOLEAN:
            cls: Any = Boolean
        elif var.kind == Kind.REAL:
            cls = Float64
        else:
            cls = Int64 if var.unsigned32 else Int32

        def getter() -> Any:
            return ctl.get(vr)

        def setter(value: Any) -> None:
            ctl.set(vr, value)

        return cls(
            var.name,
            causality=causality,
            variability=variability,
            description=var.description,
            getter=getter,
            initial=None if var.causality == Causality.INPUT else Fmi3Initial.exact,
            setter=setter,
        )

    def _log(self, message: str, level: LogLevel) -> None:
        self.log(message, Fmi3Status(int(level)))

    def do_step(self, current_time: float, step_size: float) -> bool:
        return self.controller.do_step(step_size)

    def terminate(self) -> None:
        self.controller.close()
