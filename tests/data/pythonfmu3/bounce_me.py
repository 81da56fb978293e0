"""A state event as an FMI 3.0 Model Exchange FMU built by PythonFMU3: x falls at ``rate`` [1/s] from 1;
its event indicator is x; where x crosses zero, x is reset to 1 (valuesOfContinuousStatesChanged) and the
Int32 output ``crossings`` counts one. So the crossings are at k / rate, k = 1, 2, ..."""

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


class PyBounce(Fmi3SlaveBase, ModelExchange):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "a state x falling to zero and reset to one (heliostep's tests)"
        self.time = 0.0
        self.x = 1.0
        self.derx = -1.0
        self.rate = 1.0
        self.crossings = 0
        self.z = 1.0
        self.register_variable(
            Float64("time", causality=Fmi3Causality.independent, variability=Fmi3Variability.continuous)
        )
        self.register_variable(
            Float64(
                "x",
                causality=Fmi3Causality.output,
                start=1.0,
                variability=Fmi3Variability.continuous,
                initial=Fmi3Initial.exact,
            )
        )
        self.register_variable(
            Float64("derx", causality=Fmi3Causality.local, variability=Fmi3Variability.continuous, derivative=1)
        )
        self.register_variable(Float64("rate", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))
        self.register_variable(
            Int32(
                "crossings",
                causality=Fmi3Causality.output,
                variability=Fmi3Variability.discrete,
                initial=Fmi3Initial.exact,
                start=0,
            )
        )
        self.register_variable(
            Float64("z", causality=Fmi3Causality.local, variability=Fmi3Variability.continuous),
            has_event_indicator=True,
        )

    def get_continuous_state_derivatives(self):
        self.derx = -self.rate
        return [self.derx]

    def get_event_indicators(self):
        self.z = self.x
        return [self.z]

    def update_discrete_states(self):
        if self.x <= 1e-9:
            self.x = 1.0
            self.crossings += 1
            return Fmi3UpdateDiscreteStatesResult(valuesOfContinuousStatesChanged=True)
        return Fmi3UpdateDiscreteStatesResult()
