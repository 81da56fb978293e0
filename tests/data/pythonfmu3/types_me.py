"""Outputs of several FMI 3.0 types and an array, as a Model Exchange FMU built by PythonFMU3: at time
events every ``period`` [s] (fmi3UpdateDiscreteStates: nextEventTime) the event count k steps by one,
and the outputs are ``whole`` (Int32) = k, ``big`` (Int64) = k * 2^33, ``unsigned`` (UInt64) = k + 2^40,
``odd`` (Boolean) = k odd, ``label`` (String) = "k=<k>", ``scaled`` (Float64[3], discrete) = (k, 2k, 3k).
No state."""

import numpy as np
from pythonfmu3 import (
    Boolean,
    Dimension,
    Float64,
    Fmi3Causality,
    Fmi3SlaveBase,
    Fmi3UpdateDiscreteStatesResult,
    Fmi3Variability,
    Int32,
    Int64,
    ModelExchange,
    String,
    UInt64,
)


class PyTypes(Fmi3SlaveBase, ModelExchange):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "outputs of several types and an array, stepped at time events (heliostep's tests)"
        self.time = 0.0
        self.period = 0.5
        self.whole = 0
        self.big = 0
        self.unsigned = 2**40
        self.odd = False
        self.label = "k=0"
        self.scaled = np.zeros(3)
        discrete = Fmi3Variability.discrete
        self.register_variable(
            Float64("time", causality=Fmi3Causality.independent, variability=Fmi3Variability.continuous)
        )
        self.register_variable(Float64("period", causality=Fmi3Causality.parameter, variability=Fmi3Variability.fixed))
        self.register_variable(Int32("whole", causality=Fmi3Causality.output, variability=discrete))
        self.register_variable(Int64("big", causality=Fmi3Causality.output, variability=discrete))
        self.register_variable(UInt64("unsigned", causality=Fmi3Causality.output, variability=discrete))
        self.register_variable(Boolean("odd", causality=Fmi3Causality.output, variability=discrete))
        self.register_variable(String("label", causality=Fmi3Causality.output, variability=discrete))
        self.register_variable(
            Float64("scaled", causality=Fmi3Causality.output, variability=discrete, dimensions=[Dimension(start="3")])
        )

    def get_continuous_state_derivatives(self):
        return []

    def update_discrete_states(self):
        due = self.period * (self.whole + 1)
        if self.time >= due - 1e-9 * max(1.0, due):
            k = self.whole + 1
            self.whole, self.big, self.unsigned, self.odd = k, k * 2**33, k + 2**40, k % 2 == 1
            self.label = f"k={k}"
            self.scaled = np.array([k, 2.0 * k, 3.0 * k])
        return Fmi3UpdateDiscreteStatesResult(nextEventTimeDefined=True, nextEventTime=self.period * (self.whole + 1))
