"""A first-order lag T dy/dt = u - y as an FMI 3.0 Model Exchange FMU built by PythonFMU3.

heliostep's tests build it with ``pythonfmu3.builder.FmuBuilder`` (an exporter nobody in the project
wrote: its own C++ FMI layer, its own modelDescription.xml) and run it against first principles. Past
``t_fail`` [s] its derivatives raise, which PythonFMU3 0.3.4 does not survive: its C++ layer reads the
failed call's result (NULL) and the process dies with SIGSEGV, a real third-party crash.
"""

from pythonfmu3 import Float64, Fmi3Causality, Fmi3Initial, Fmi3SlaveBase, Fmi3Variability, ModelExchange


class PyLag(Fmi3SlaveBase, ModelExchange):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "first-order lag T dy/dt = u - y (heliostep's tests)"
        self.time = 0.0
        self.u = 0.0
        self.y = 0.0
        self.dery = 0.0
        self.T = 0.5
        self.t_fail = 1e300
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
        self.register_variable(
            Float64("dery", causality=Fmi3Causality.local, variability=Fmi3Variability.continuous, derivative=2)
        )
        self.register_variable(Float64("T", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))
        self.register_variable(Float64("t_fail", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))

    def get_continuous_state_derivatives(self):
        if self.time > self.t_fail:
            raise ValueError(f"failing on request past t_fail = {self.t_fail} s")
        self.dery = (self.u - self.y) / self.T
        return [self.dery]
