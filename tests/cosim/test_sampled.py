"""Issue #24: Co-Simulation FMUs (FMI 2.0) as sampled components of the Model Exchange system.

The mini Lag (``tests/data/mini/lag.c``: T dy/dt = u - y, e = u - y) exports both Model Exchange and
Co-Simulation (its fmi2DoStep: fixed-step RK4 at 1 ms inside). In the example a Model Exchange Gain
makes a ramp s = t (b = 1, u = 0) that drives the lag, whose y drives a second Gain (k = 1, b = 0:
its s integrates y). As Model Exchange, y follows the exact solution y = t - T (1 - exp(-t / T)). As
Co-Simulation at an interval h, the lag's input is the ramp sampled and held, so at the communication
points y_(k+1) = u_k + (y_k - u_k) exp(-h / T) with u_k = t_k, and y is held in between: both written
here from first principles, and the loose coupling's error measured against the exact solution.
"""

from __future__ import annotations

import time as clock

import numpy as np
import pytest

import lag_reference
from heliostep.cosim import Connection, CoSimulation, SolverOptions, read_fmu
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.run import RunOptions, run_scenario
from third_party_fmu import build_mini_fmu

T_LAG = 0.5
STOP = 3.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("sampled")
    return {name: build_mini_fmu(name, out) for name in ("Gain", "Lag")}


def example(fmus, interval: float | None):
    lag = read_fmu(fmus["Lag"], co_simulation=interval is not None)
    gain = read_fmu(fmus["Gain"])
    system = CoSimulation(
        {"ramp": gain, "lag": lag, "integral": gain},
        [Connection("ramp.s", "lag.u"), Connection("lag.y", "integral.u")],
        parameters={"ramp": {"k": 0.0, "b": 1.0}, "integral": {"k": 1.0, "b": 0.0}, "lag": {"T": T_LAG}},
        communication_intervals={"lag": interval} if interval is not None else None,
    )
    started = clock.perf_counter()
    result = system.simulate(0.0, STOP, np.linspace(0.0, STOP, 3001), SolverOptions(rtol=1e-9))
    return result, clock.perf_counter() - started


def exact_lag(t):
    return lag_reference.exact_lag(t, T_LAG)


def sampled_lag(h: float):
    """The lag's output at the communication points k h (the ramp sampled and held): first principles."""
    return lag_reference.sampled_lag(h, STOP, T_LAG)


def test_the_model_exchange_twin_follows_the_exact_solution(fmus):
    result, _ = example(fmus, None)
    trace = result.trace
    assert np.max(np.abs(trace["lag.y"] - exact_lag(trace["time"]))) < 1e-5


@pytest.mark.parametrize("h", [0.1, 0.01])
def test_a_cs_fmu_is_stepped_at_its_interval_its_input_sampled_and_its_output_held(fmus, h):
    result, _ = example(fmus, h)
    trace = result.trace
    points, y = sampled_lag(h)
    mid = trace[np.isclose((trace["time"] / h) % 1.0, 0.5, atol=1e-6)]  # half-way between points: held
    k = np.floor(mid["time"].to_numpy() / h + 1e-9).astype(int)
    assert len(mid) > 20
    assert np.max(np.abs(mid["lag.y"].to_numpy() - y[k])) < 1e-9  # the recurrence, held
    # the second gain integrates the staircase exactly: s(K h) = h (y_0 + ... + y_(K-1))
    end = trace["integral.s"].iloc[-1]
    assert end == pytest.approx(h * y[:-1].sum(), rel=1e-6, abs=1e-9)
    assert result.statistics["sampled_components"]["lag"] == {"interval_s": h, "steps": int(round(STOP / h))}
    assert result.statistics["compiled_rhs"]  # the Model Exchange side stays in the compiled kernel


def test_the_loose_couplings_error_against_the_exact_solution_is_of_the_order_of_the_interval(fmus):
    # the largest error is just before a communication point: the held y_k against y((k + 1) h); in the
    # steady ramp y_k = t_k - c with c = h / (1 - exp(-h / T)), so the error tends to h + c - T (~1.5 h)
    errors = {}
    for h in (0.1, 0.01):
        trace = example(fmus, h)[0].trace
        errors[h] = float(np.max(np.abs(trace["lag.y"] - exact_lag(trace["time"]))))
    lag_reference.check_first_order_loose_coupling(errors, T_LAG, above=1e-6)


def test_a_cs_fmu_in_an_algebraic_loop_is_refused_naming_it_and_the_loop(fmus):
    lag = read_fmu(fmus["Lag"], co_simulation=True)
    gain = read_fmu(fmus["Gain"])
    with pytest.raises(InputError, match=r"the Co-Simulation FMU 'lag' \(Lag\.fmu\) is in an algebraic loop: .*lag\.e"):
        CoSimulation(
            {"lag": lag, "gain": gain},
            [Connection("lag.e", "gain.u"), Connection("gain.y", "lag.u")],
            communication_intervals={"lag": 0.1},
        )


def test_a_transformed_connection_into_a_cs_fmu_is_sampled_then_transformed(fmus):
    """The ramp into the lag through (factor, offset) = (2, 1): u_k = 2 t_k + 1 held over each step, so
    y_(k+1) = u_k + (y_k - u_k) exp(-h / T) at the points (the recurrence written here)."""
    h, factor, offset = 0.1, 2.0, 1.0
    system = CoSimulation(
        {"ramp": read_fmu(fmus["Gain"]), "lag": read_fmu(fmus["Lag"], co_simulation=True)},
        [Connection("ramp.s", "lag.u", (factor, offset))],
        parameters={"ramp": {"k": 0.0, "b": 1.0}, "lag": {"T": T_LAG}},
        communication_intervals={"lag": h},
    )
    trace = system.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 101), SolverOptions(rtol=1e-9)).trace
    points = np.arange(11) * h
    y = np.zeros(11)
    for k in range(10):
        u = factor * points[k] + offset
        y[k + 1] = u + (y[k] - u) * np.exp(-h / T_LAG)
    mid = trace[np.isclose((trace["time"] / h) % 1.0, 0.5, atol=1e-6)]  # half-way between points: held
    k = np.floor(mid["time"].to_numpy() / h + 1e-9).astype(int)
    assert len(mid) == 10
    assert np.max(np.abs(mid["lag.y"].to_numpy() - y[k])) < 1e-9


def test_a_transformed_connection_from_a_cs_fmu_into_model_exchange_is_refused(fmus):
    with pytest.raises(
        InputError, match=r"connection lag\.y -> gain\.u: a transformation on a connection from a Co-Sim"
    ):
        CoSimulation(
            {"lag": read_fmu(fmus["Lag"], co_simulation=True), "gain": read_fmu(fmus["Gain"])},
            [Connection("lag.y", "gain.u", (2.0, 0.0))],
            communication_intervals={"lag": 0.1},
        )


def test_a_co_simulation_fmu_read_without_an_interval_is_refused():
    with pytest.raises(InputError, match=r"communication_interval\.lag"):
        from heliostep.cosim.sampled import split_sampled

        split_sampled({}, [], [], {"lag": 0.1})


@pytest.mark.parametrize("supervise", [False, True])
def test_a_scenario_runs_a_cs_fmu_at_its_communication_interval(fmus, supervise):
    # the paper's drive with the ramp and the lag (as Co-Simulation at 50 ms) beside it
    overrides = (
        "window.duration=4",
        f"fmus.ramp={fmus['Gain']}",
        f"fmus.lag={fmus['Lag']}",
        "parameters.ramp={k: 0.0, b: 1.0}",
        "communication_interval.lag=0.05",
        "connections=[[motor.tau, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega],"
        " [ramp.s, lag.u]]",
    )
    result = run_scenario(scenarios_dir() / "jan21-central.yaml", RunOptions(supervise=supervise), overrides=overrides)
    assert result.complete
    # lag.y drives nothing but is traced (held); at the points, the lag of the sampled ramp (first principles)
    assert result.metadata["statistics"]["sampled_components"]["lag"]["steps"] == 80
    a = np.exp(-0.05 / T_LAG)
    y = np.zeros(81)
    for k in range(80):
        y[k + 1] = 0.05 * k + (y[k] - 0.05 * k) * a
    trace = result.trace
    points = trace[np.isclose(trace["time"] / 0.05, np.round(trace["time"] / 0.05), rtol=0, atol=1e-6)]
    after = points.drop_duplicates("time", keep="last")  # the row after each point's event: the new value
    before = points[points["time"] > 0].drop_duplicates("time", keep="first")  # the row before: still held
    k_after = np.round(after["time"].to_numpy() / 0.05).astype(int)
    k_before = np.round(before["time"].to_numpy() / 0.05).astype(int)
    assert len(after) > 20 and np.max(np.abs(after["lag.y"].to_numpy() - y[k_after])) < 1e-9
    assert np.max(np.abs(before["lag.y"].to_numpy() - y[k_before - 1])) < 1e-9
    assert np.max(np.abs(trace["lag.e"])) > 0.04  # every Real output of the CS FMU is in the trace
    assert "motor.tau" in trace and "mechanics.theta" in trace  # the drive beside it, as Model Exchange
