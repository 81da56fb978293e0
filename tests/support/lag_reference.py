"""First principles of a first-order lag T dy/dt = u - y, y(0) = 0, fed the ramp u = t: the references of
the sampled Co-Simulation tests of both FMI versions (``tests/cosim/test_sampled.py``, the mini Lag,
FMI 2.0; ``tests/cosim/test_sampled3.py``, Lag3, FMI 3.0: the same equations).
"""

from __future__ import annotations

import numpy as np


def exact_lag(t, time_constant: float):
    """The lag's exact output y(t) = t - T (1 - e^(-t/T)) [same unit as t] for the ramp u = t, at ``t`` [s]."""
    return t - time_constant * (1.0 - np.exp(-t / time_constant))


def sampled_lag(h: float, stop: float, time_constant: float) -> tuple[np.ndarray, np.ndarray]:
    """The lag's output at the communication points k h [s] up to ``stop`` [s], the ramp sampled at each
    point and held over the step: y_(k+1) = u_k + (y_k - u_k) e^(-h/T), y_0 = 0. Returns (points, y)."""
    a = np.exp(-h / time_constant)
    points = np.arange(0.0, stop + h / 2, h)
    y = np.zeros(len(points))
    for k in range(len(points) - 1):
        y[k + 1] = points[k] + (y[k] - points[k]) * a
    return points, y


def check_first_order_loose_coupling(errors: dict[float, float], time_constant: float, above: float) -> None:
    """Assert the largest error of the loose coupling at each interval h [s] (``errors``: h -> max |y - y_ref|)
    and that it is first order in h (``errors`` at 0.1 s and 0.01 s).

    The largest error is just before a communication point: the held y_k against y((k + 1) h); in the
    steady ramp y_k = t_k - c with c = h / (1 - e^(-h/T)), so it tends to h + c - T (~1.5 h). Each error
    must lie within 3 % below that limit and ``above`` (relative) over it.
    """
    for h, error in errors.items():
        limit = h + h / (1.0 - np.exp(-h / time_constant)) - time_constant
        assert limit * 0.97 < error <= limit * (1 + above), (h, error, limit)
    assert errors[0.01] < errors[0.1] / 8  # first order in h
