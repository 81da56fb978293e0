"""A pass-through of several FMI 3.0 types and an array as a Model Exchange FMU built by PythonFMU3:
each ``*_out`` is its ``*_in`` (Int32, Int64, UInt64, Boolean, String, Float64[3]), direct feedthrough.
No state."""

import numpy as np
from pythonfmu3 import (
    Boolean,
    Dimension,
    Float64,
    Fmi3Causality,
    Fmi3SlaveBase,
    Fmi3Variability,
    Int32,
    Int64,
    ModelExchange,
    String,
    UInt64,
)

KINDS = {"i32": Int32, "i64": Int64, "u64": UInt64, "b": Boolean, "s": String}


class PyPass(Fmi3SlaveBase, ModelExchange):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "a pass-through of several types and an array (heliostep's tests)"
        self.time = 0.0
        self.i32_in, self.i64_in, self.u64_in, self.b_in, self.s_in = 0, 0, 0, False, ""
        self.a_in = np.zeros(3)
        discrete = Fmi3Variability.discrete
        self.register_variable(
            Float64("time", causality=Fmi3Causality.independent, variability=Fmi3Variability.continuous)
        )
        for name, kind in KINDS.items():
            self.register_variable(kind(f"{name}_in", causality=Fmi3Causality.input, variability=discrete))
        for name, kind in KINDS.items():
            self.register_variable(
                kind(
                    f"{name}_out",
                    causality=Fmi3Causality.output,
                    variability=discrete,
                    getter=lambda name=name: getattr(self, f"{name}_in"),
                )
            )
        self.register_variable(  # its own setter: PythonFMU3 0.3.4's reshapes with numpy's removed newshape=
            Float64(
                "a_in",
                causality=Fmi3Causality.input,
                variability=discrete,
                dimensions=[Dimension(start="3")],
                setter=lambda values: setattr(self, "a_in", np.asarray(values, dtype=float)),
            )
        )
        self.register_variable(
            Float64(
                "a_out",
                causality=Fmi3Causality.output,
                variability=discrete,
                dimensions=[Dimension(start="3")],
                getter=lambda: list(np.asarray(self.a_in, dtype=float)),
            )
        )

    def get_continuous_state_derivatives(self):
        return []
