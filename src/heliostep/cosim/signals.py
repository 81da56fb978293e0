"""The values the master consumes: connections, master-side input signals, solver settings."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from heliostep.errors import InputError


@dataclass(frozen=True)
class Connection:
    """An FMU output feeding an FMU input, both as ``instance.variable``; with a ``transform`` (factor,
    offset) the input gets ``factor * output + offset`` (Real ends, whose units may then differ: the
    transformation converts them), (1.0, 0.0) copying the value as it is."""

    source: str
    target: str
    transform: tuple[float, float] | None = None


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
    ``rtol`` × the FMU's nominal), largest step [s] and most internal steps per output; and the
    tolerances of the algebraic loops' Newton (:class:`~heliostep.cosim.loops.LoopSolver`): a loop
    is solved when every torn input v has |y(v) - v| <= ``loop_atol`` + ``loop_rtol`` |v| [v's unit].
    The relative part is what large values need: rounding alone leaves |y(v) - v| near 1e-16 |v|,
    above any fixed absolute tolerance once |v| is large enough (1e4 for 1e-12).
    """

    rtol: float = 1e-6
    atol: float | None = None
    max_step: float = np.inf  # no limit: inputs change only where CVODE restarts anyway
    max_num_steps: int = 100_000
    loop_rtol: float = 1e-10
    loop_atol: float = 1e-12


def cvode_failure(error_info: tuple | None, flag: int) -> RuntimeError:
    """The error for a CVODE call that returned ``flag`` < 0, with what CVODE's error handler
    recorded (code, module, function, message), where it recorded anything."""
    code, module, function, message = error_info or (flag, "CVODE", "", "no message")
    return RuntimeError(f"CVode error (code {code}) in module {module}, function {function}: {message}")


def too_many_steps(max_steps: int, t_stop: float, reached: float) -> RuntimeError:
    """The error for a one-step CVODE loop that took ``max_steps`` internal steps (the limit
    CVODE itself applies in normal mode, ``SolverOptions.max_num_steps``) short of ``t_stop``."""
    return RuntimeError(
        f"CVode took {max_steps} internal steps (solver.max_num_steps) before reaching "
        f"t = {t_stop:.9g} s, at t = {reached:.9g} s"
    )
