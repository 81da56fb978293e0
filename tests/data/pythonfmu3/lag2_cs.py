"""The first-order lag T dy/dt = u - y as an FMI 2.0 Co-Simulation FMU built by PythonFMU (``pythonfmu``
on PyPI, the FMI 2.0 sibling of PythonFMU3): each step integrates it exactly with its input held,
y <- u + (y - u) exp(-h / T); a step that would pass ``t_stop`` [s] returns False (PythonFMU's way to
refuse a step)."""

import math

from pythonfmu.fmi2slave import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PyLag2CS(Fmi2Slave):
    description = "first-order lag, exact steps with the input held (heliostep's tests)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.T = 0.5
        self.t_stop = 1e300
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))
        self.register_variable(Real("T", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("t_stop", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))

    def do_step(self, current_time, step_size):
        if current_time + step_size > self.t_stop + 1e-12:
            return False
        self.y = self.u + (self.y - self.u) * math.exp(-step_size / self.T)
        return True
