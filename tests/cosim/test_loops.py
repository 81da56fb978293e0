"""Algebraic loops beyond linear ones, on both paths (the compiled kernel's Newton in C, the Python
solver's): a non-linear loop on its closed form, one that loses its real solution while simulating and
one without a real solution from the start (named failures: the torn input, its last value and residual,
the time), and a loop whose values are so large that only a relative tolerance can be met
(``SolverOptions.loop_rtol`` and ``loop_atol``). A singular loop is refused at initialization as bad input
(``test_fmi_conformance.py``, ``test_kernel.py``).

The non-linear loop: a quadratic Gain (``sq``: y = a u^2 + c, its k and b 0) and a linear one (y = k u + b)
fed back to each other, c = r t the integral of a third Gain's constant output. Its torn input u solves
k a u^2 - u + (k r t + b) = 0: u = (1 - sqrt(D)) / (2 k a), D = 1 - 4 k a (k r t + b) (the root Newton
reaches from 0), real until D = 0 at t* = (1 / (4 k a) - b) / (k r), where the two roots meet at
u = 1 / (2 k a); the integral of u is t / (2 k a) - (D(0)^1.5 - D^1.5) / (12 k^3 a^2 r).
"""

import re

import numpy as np
import pandas as pd
import pytest

import heliostep.cosim.integrator as integrator
from heliostep.cosim import Connection, CoSimulation, LoopError, SimulationError, read_fmu
from heliostep.cosim.integrator import compiled_kernel
from heliostep.cosim.master import SolverOptions
from third_party_fmu import build_mini_fmu

A, K, B, RATE = 0.1, 2.0, 0.5, 0.25
FOLD = (1 / (4 * K * A) - B) / (K * RATE)  # [s] t*, 1.5 s


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    out = tmp_path_factory.mktemp("mini-loops")
    return {name: read_fmu(build_mini_fmu(name, out)) for name in ("Gain", "Lag")}


def on_path(monkeypatch, compiled: bool) -> None:
    monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))


def square_loop(mini) -> CoSimulation:
    return CoSimulation(
        {"sq": mini["Gain"], "g": mini["Gain"], "ramp": mini["Gain"]},
        [Connection("g.y", "sq.u"), Connection("sq.y", "g.u"), Connection("ramp.s", "sq.c")],
        parameters={"sq": {"a": A, "k": 0.0, "b": 0.0}, "g": {"k": K, "b": B}, "ramp": {"k": 0.0, "b": RATE}},
    )


def torn_input(t: np.ndarray) -> np.ndarray:
    return (1 - np.sqrt(1 - 4 * K * A * (K * RATE * t + B))) / (2 * K * A)


def torn_input_integral(t: np.ndarray) -> np.ndarray:
    d0, d = 1 - 4 * K * A * B, 1 - 4 * K * A * (K * RATE * t + B)
    return t / (2 * K * A) - (d0**1.5 - d**1.5) / (12 * K**3 * A**2 * RATE)


def test_a_non_linear_loop_across_fmus_follows_its_closed_form_on_either_path(mini, monkeypatch):
    """Newton iterates at every evaluation (the root moves with c = r t); in C and in Python the same
    iterations and the same trace bit for bit (one torn input), on the closed form."""
    runs = {}
    for compiled in (True, False):
        on_path(monkeypatch, compiled)
        system = square_loop(mini)
        assert system.loops == ["g.y -> sq.u -> sq.y -> g.u (torn at sq.u)"]
        runs[compiled] = system.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 11), SolverOptions(rtol=1e-10))
    c, p = runs[True].statistics, runs[False].statistics
    assert c["compiled_rhs"] and not p["compiled_rhs"] and c["loop_solves_compiled"] == c["rhs"] > 0
    assert c["rhs"] == p["rhs"] and c["loop_iterations"] == p["loop_iterations"] > c["loop_solves"]
    assert c["loop_most_iterations"] == p["loop_most_iterations"] >= 3  # not one linear step
    pd.testing.assert_frame_equal(runs[True].trace, runs[False].trace, check_exact=True)
    trace = runs[True].trace
    t = trace["time"].to_numpy()
    np.testing.assert_allclose(trace["g.y"], torn_input(t), rtol=1e-9)
    np.testing.assert_allclose(trace["sq.y"], (torn_input(t) - B) / K, rtol=1e-9)  # u = k y_sq + b
    np.testing.assert_allclose(trace["g.s"], torn_input_integral(t), rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(trace["sq.s"], (torn_input_integral(t) - B * t) / K, rtol=1e-7, atol=1e-10)


def _no_convergence(message: str) -> tuple[float, float, float]:
    """(time [s], residual, last value) of a loop's no-convergence message through sq.u."""
    found = re.search(
        r"algebraic loop through sq\.u at t = (\S+) s: no convergence in 50 Newton iterations, "
        r"residual (\S+) at sq\.u = (\S+) \(solved when \|residual\| <= solver\.loop_atol \+ "
        r"solver\.loop_rtol \|value\| = 1e-12 \+ 1e-10 \|value\|\)",
        message,
    )
    assert found, message
    return float(found[1]), float(found[2]), float(found[3])


def test_a_loop_that_loses_its_real_solution_fails_named_there_on_either_path(mini, monkeypatch):
    """Past t* the loop has no real solution: the run fails at the first evaluation past it (CVODE's steps
    at most 0.01 s), naming the torn input, its last value and residual, and the time; the residual at
    least the smallest any value leaves, (k c + b) - 1 / (4 k a) at v = 1 / (2 k a); the same message in C
    as in Python; the trace up to there on the closed form."""
    failures = {}
    for compiled in (True, False):
        on_path(monkeypatch, compiled)
        with pytest.raises(SimulationError) as failure:
            square_loop(mini).simulate(0.0, 2.0, np.linspace(0.0, 2.0, 21), SolverOptions(rtol=1e-8, max_step=0.01))
        failures[compiled] = error = failure.value
        assert isinstance(error.__cause__, LoopError) and error.statistics["compiled_rhs"] == compiled
        time, residual, value = _no_convergence(str(error))
        assert FOLD <= time <= FOLD + 0.01 and time == pytest.approx(error.time, abs=1e-8)
        least = K * RATE * time + B - 1 / (4 * K * A)
        assert 0 < least <= residual and np.isfinite(value)
        t = error.trace["time"].to_numpy()
        assert t[-1] < FOLD
        np.testing.assert_allclose(error.trace["g.y"], torn_input(t), rtol=1e-9)
    assert failures[True].statistics["loop_solves_compiled"] > 0  # failed in C
    assert str(failures[True]) == str(failures[False])


def test_a_loop_without_a_real_solution_from_the_start_is_a_named_run_failure(mini):
    """u = u^2 + 1 (a = 1, k = 1, b = 1) has no real root: not bad input (its Jacobian is regular) but a
    simulation that fails at once, at t = 0, its residual at least min(u^2 - u + 1) = 0.75."""
    system = CoSimulation(
        {"sq": mini["Gain"], "g": mini["Gain"]},
        [Connection("g.y", "sq.u"), Connection("sq.y", "g.u")],
        parameters={"sq": {"a": 1.0, "k": 0.0, "b": 0.0}, "g": {"k": 1.0, "b": 1.0}},
    )
    with pytest.raises(SimulationError) as failure:
        system.simulate(0.0, 1.0)
    assert isinstance(failure.value.__cause__, LoopError) and failure.value.time == 0.0
    time, residual, _ = _no_convergence(str(failure.value))
    assert time == 0.0 and residual >= 0.75
    assert str(failure.value).startswith("simulation failed at t = 0 s: algebraic loop through sq.u")


def _large_lag_loop(mini, options: SolverOptions):
    """The Lag-Gain loop of test_kernel.py with b = 1e9: lag.y = 1e9 (1 - exp(-4 t)), the torn input
    g.u = 2e9 - 2 lag.y; rounding leaves its residual near 1e-16 x 2e9, far above an absolute 1e-12."""
    system = CoSimulation(
        {"lag": mini["Lag"], "g": mini["Gain"]},
        [Connection("lag.e", "g.u"), Connection("g.y", "lag.u")],
        parameters={"lag": {"T": 0.5}, "g": {"k": 0.5, "b": 1e9}},
    )
    return system.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 11), options)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_loop_of_large_values_is_solved_with_its_relative_tolerance_on_either_path(mini, monkeypatch, compiled):
    on_path(monkeypatch, compiled)
    result = _large_lag_loop(mini, SolverOptions(rtol=1e-8))  # the default loop tolerances
    t = result.trace["time"].to_numpy()
    np.testing.assert_allclose(result.trace["lag.y"], 1e9 * (1 - np.exp(-4 * t)), rtol=1e-6, atol=1e-3)
    assert result.statistics["loop_solves_compiled"] == (result.statistics["rhs"] if compiled else 0)
    # an absolute tolerance alone cannot be met: a named failure while simulating (in C on that path)
    with pytest.raises(SimulationError, match=r"1e-12 \+ 0 \|value\|\)$") as failure:
        _large_lag_loop(mini, SolverOptions(rtol=1e-8, loop_rtol=0.0))
    error = failure.value
    assert isinstance(error.__cause__, LoopError) and error.time > 0.0
    assert re.search(r"at t = \S+ s: no convergence in 50 Newton iterations, residual \S+ at g\.u = ", str(error))
    assert error.statistics["loop_solves_compiled"] > 0 if compiled else error.statistics["loop_solves_compiled"] == 0
    # one that rounding can meet does (both tolerances reach the kernel)
    loose = _large_lag_loop(mini, SolverOptions(rtol=1e-8, loop_rtol=0.0, loop_atol=1e-3))
    np.testing.assert_allclose(loose.trace["lag.y"], 1e9 * (1 - np.exp(-4 * t)), rtol=1e-6, atol=1e-3)
