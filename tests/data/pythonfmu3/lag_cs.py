"""The first-order lag T dy/dt = u - y as an FMI 3.0 Co-Simulation FMU built by PythonFMU3: each step
integrates it exactly with its input held, y <- u + (y - u) exp(-h / T)."""

import math

from pythonfmu3 import Float64, Fmi3Causality, Fmi3Initial, Fmi3Slave, Fmi3Variability


class PyLagCS(Fmi3Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "first-order lag, exact steps with the input held (heliostep's tests)"
        self.time = 0.0
        self.u = 0.0
        self.y = 0.0
        self.T = 0.5
        self.register_variable(
            Float64("time", causality=Fmi3Causality.independent, variability=Fmi3Variability.continuous)
        )
        self.register_variable(Float64("u", causality=Fmi3Causality.input, start=0.0))
        self.register_variable(
            Float64(
                "y",
                causality=Fmi3Causality.output,
                start=0.0,
                variability=Fmi3Variability.continuous,
                initial=Fmi3Initial.exact,
            )
        )
        self.register_variable(Float64("T", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        self.y = self.u + (self.y - self.u) * math.exp(-step_size / self.T)
        return True
