"""A conveyor with a product sensor: the plant FMU of the line example (FMI 2.0).

Built with the same builder as the controller FMUs (pythonfmu), and independent of
motion-server: ``pythonfmu build -f conveyor.py``.

The belt is driven by a controller's axis: its position comes in as ``belt_position``
(mm). Products lie on the belt every ``pitch`` mm, each off its nominal place by a few
millimetres (the table ``OFFSETS``, repeated). A registration sensor (a photo eye) sees
a product's leading edge: ``sensor`` is true while a product of ``length`` mm is in front
of it. When a product arrives, ``correction`` becomes the change of its offset from the
previous product's: the phase correction a downstream axis geared to the belt needs to
meet this product where it lies; ``products`` counts the products seen.
"""

from __future__ import annotations

import math

from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real

#: each product's offset from its nominal place (mm), repeated along the belt
OFFSETS = (0.0, 4.0, 1.0, -3.0, 2.5, 6.0, -1.5, 0.0)


class Conveyor(Fmi2Slave):
    author = "motion-server examples"
    description = "conveyor belt with a product registration sensor"

    def __init__(self, **kwargs: object) -> None:
        super().__init__(**kwargs)
        self.pitch = 100.0
        self.length = 30.0
        self.belt_position = 0.0
        self.sensor = False
        self.correction = 0.0
        self.products = 0
        fixed = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        # outputs start exact (pythonfmu writes no InitialUnknowns)
        out = {
            "causality": Fmi2Causality.output,
            "variability": Fmi2Variability.discrete,
            "initial": Fmi2Initial.exact,
        }
        self.register_variable(Real("pitch", **fixed))
        self.register_variable(Real("length", **fixed))
        self.register_variable(
            Real(
                "belt_position",
                causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous,
            )
        )
        self.register_variable(Boolean("sensor", **out))
        self.register_variable(Real("correction", **out))
        self.register_variable(Integer("products", **out))

    def product_at(self, index: int) -> float:
        """Where product ``index`` lies on the belt (its leading edge, mm from the sensor
        when the belt is at 0)."""
        return (index + 1) * self.pitch + OFFSETS[index % len(OFFSETS)]

    def do_step(self, current_time: float, step_size: float) -> bool:
        x = self.belt_position
        # the product that could be in front of the sensor: the last one whose edge passed
        index = max(0, math.floor(x / self.pitch) - 1)
        seen = False
        for k in (index - 1, index, index + 1):
            if k >= 0 and self.product_at(k) <= x < self.product_at(k) + self.length:
                seen = True
                if not self.sensor:
                    self.products += 1
                    previous = OFFSETS[(k - 1) % len(OFFSETS)] if k > 0 else 0.0
                    self.correction = OFFSETS[k % len(OFFSETS)] - previous
        self.sensor = seen
        return True
