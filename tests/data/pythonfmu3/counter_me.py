"""A counter as an FMI 3.0 Model Exchange FMU built by PythonFMU3: an Int32 output ``count`` stepped by
one at time events every ``period`` [s] (fmi3UpdateDiscreteStates: nextEventTime), asking to terminate
the simulation when it reaches ``limit``. No continuous state."""

from pythonfmu3 import (
    Float64,
    Fmi3Causality,
    Fmi3Initial,
    Fmi3SlaveBase,
    Fmi3UpdateDiscreteStatesResult,
    Fmi3Variability,
    Int32,
    ModelExchange,
)


class PyCounter(Fmi3SlaveBase, ModelExchange):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "counter with time events that terminates (heliostep's tests)"
        self.time = 0.0
        self.count = 0
        self.period = 0.25
        self.limit = 5
        self.register_variable(
            Float64("time", causality=Fmi3Causality.independent, variability=Fmi3Variability.continuous)
        )
        self.register_variable(
            Int32(
                "count",
                causality=Fmi3Causality.output,
                variability=Fmi3Variability.discrete,
                initial=Fmi3Initial.exact,
                start=0,
            )
        )
        self.register_variable(Float64("period", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))
        self.register_variable(Int32("limit", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))

    def get_continuous_state_derivatives(self):
        return []

    def update_discrete_states(self):
        due = self.period * (self.count + 1)
        if self.time >= due - 1e-9 * max(1.0, due):
            self.count += 1
        return Fmi3UpdateDiscreteStatesResult(
            terminateSimulation=self.count >= self.limit,
            nextEventTimeDefined=True,
            nextEventTime=self.period * (self.count + 1),
        )
