"""The values the master consumes: connections, master-side input signals, solver settings."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from heliostep.errors import InputError


@dataclass(frozen=True)
class Connection:
    """An FMU output feeding an FMU input, both as ``instance.variable``."""

    source: str
    target: str


@dataclass(frozen=True)
class PiecewiseConstant:
    """A master-side input: ``values[0]`` before ``times[0]``, ``values[k + 1]`` from ``times[k]`` on.

    ``target`` is the FMU input it drives (``instance.variable``); ``name`` the trace column.
    """

    name: str
    target: str
    times: np.ndarray
    values: np.ndarray

    def __post_init__(self):
        if len(self.values) != len(self.times) + 1:
            raise InputError(f"input {self.name}: expected one more value than change times")
        if np.any(np.diff(self.times) < 0):
            raise InputError(f"input {self.name}: change times must not decrease")

    def value_at(self, time: float) -> float:
        """Value from ``time`` on (right-continuous)."""
        return float(self.values[np.searchsorted(self.times, time, side="right")])


@dataclass(frozen=True)
class SolverOptions:
    """CVODE settings: relative tolerance, absolute tolerance [state units] (default
    ``rtol`` × the FMU's nominal), largest step [s] and most internal steps per output."""

    rtol: float = 1e-6
    atol: float | None = None
    max_step: float = np.inf  # no limit: inputs change only where CVODE restarts anyway
    max_num_steps: int = 100_000


