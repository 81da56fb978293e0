"""Issue #24: FMI 3.0 Co-Simulation FMUs as sampled components of the Model Exchange system.

Lag3 (``tests/data/mini3cs/lag3.c``: T dy/dt = u - y, e = u - y) exports FMI 3.0 Model Exchange and
Co-Simulation from one binary, the same equations; its fmi3DoStep integrates with the input held,
RK4 at 1 ms inside. The example is ``tests/cosim/test_sampled.py``'s: an FMI 2.0 Model Exchange Gain
makes a ramp s = t that drives the lag, whose y drives a second Gain (its s integrates y). The CS run
is checked against three independent references: the recurrence of the sampled ramp through the lag
y_(k+1) = u_k + (y_k - u_k) exp(-h / T), u_k = t_k (first principles); fmpy's own Co-Simulation of the
CS FMU alone (``fmpy.simulate_fmu``, the ramp as its input, sampled at its communication points); and
the Model Exchange twin (the loose coupling's error, measured).
"""

from __future__ import annotations

import numpy as np
import pytest

import lag_reference
from heliostep.cosim import Connection, CoSimulation, SolverOptions, read_fmu
from heliostep.cosim.master import SimulationError
from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from third_party_fmu import build_mini_fmu
from third_party_fmu3cs import build_lag3_fmu

T_LAG = 0.5
STOP = 3.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("sampled3")
    return {
        "Gain": build_mini_fmu("Gain", out),
        "Lag3": build_lag3_fmu(out),
        "Lag3CS": build_lag3_fmu(out / "cs", interfaces=("CoSimulation",)),
    }


def example(fmus, interval: float | None, lag_parameters: dict | None = None, stop: float = STOP):
    lag = read_fmu(fmus["Lag3"], co_simulation=interval is not None)
    gain = read_fmu(fmus["Gain"])
    system = CoSimulation(
        {"ramp": gain, "lag": lag, "integral": gain},
        [Connection("ramp.s", "lag.u"), Connection("lag.y", "integral.u")],
        parameters={"ramp": {"k": 0.0, "b": 1.0}, "integral": {"k": 1.0, "b": 0.0}, "lag": lag_parameters or {}},
        communication_intervals={"lag": interval} if interval is not None else None,
    )
    return system.simulate(0.0, stop, np.linspace(0.0, stop, 3001), SolverOptions(rtol=1e-9))


def sampled_lag(h: float, stop: float = STOP):
    """The lag's output at the communication points k h (the ramp sampled and held): first principles."""
    return lag_reference.sampled_lag(h, stop, T_LAG)


def after_points(trace, h: float):
    """The row after each communication point's event (the new held values) and the point's index."""
    at = trace[np.isclose(trace["time"] / h, np.round(trace["time"] / h), rtol=0, atol=1e-6)]
    after = at.drop_duplicates("time", keep="last")
    return after, np.round(after["time"].to_numpy() / h).astype(int)


@pytest.mark.parametrize("h", [0.1, 0.01])
def test_an_fmi3_cs_fmu_is_stepped_at_its_interval_as_first_principles_and_fmpys_own_cs_say(fmus, h):
    import fmpy

    result = example(fmus, h)
    trace = result.trace
    after, k = after_points(trace, h)
    points, y = sampled_lag(h)
    assert len(after) == len(points)
    assert np.max(np.abs(after["lag.y"].to_numpy() - y[k])) < 1e-9  # the recurrence, at every point
    mid = trace[np.isclose((trace["time"] / h) % 1.0, 0.5, atol=1e-6)]  # half-way between points: held
    assert len(mid) > 20
    assert np.max(np.abs(mid["lag.y"].to_numpy() - y[np.floor(mid["time"].to_numpy() / h + 1e-9).astype(int)])) < 1e-9
    # the second gain integrates the staircase exactly: s(K h) = h (y_0 + ... + y_(K-1))
    assert trace["integral.s"].iloc[-1] == pytest.approx(h * y[:-1].sum(), rel=1e-6, abs=1e-9)
    # fmpy's own FMI 3.0 Co-Simulation of the lag alone, the ramp u = t its input, stepped at h
    ramp = np.array([(0.0, 0.0), (STOP, STOP)], dtype=[("time", float), ("u", float)])
    theirs = fmpy.simulate_fmu(
        str(fmus["Lag3"]), fmi_type="CoSimulation", stop_time=STOP, step_size=h, output_interval=h, input=ramp
    )
    assert len(theirs) == len(points)
    np.testing.assert_allclose(after["lag.y"].to_numpy(), theirs["y"][k], rtol=0, atol=1e-9)
    assert result.statistics["sampled_components"]["lag"] == {"interval_s": h, "steps": int(round(STOP / h))}
    assert result.statistics["compiled_rhs"]  # the Model Exchange side stays in the compiled kernel


def test_the_loose_couplings_error_against_the_model_exchange_twin_is_first_order_in_the_interval(fmus):
    twin = example(fmus, None).trace  # the same FMU as Model Exchange: the exact solution to CVODE's tolerance
    exact = lag_reference.exact_lag(twin["time"], T_LAG)
    assert np.max(np.abs(twin["lag.y"] - exact)) < 1e-6
    errors = {}
    for h in (0.1, 0.01):
        trace = example(fmus, h).trace.drop_duplicates("time", keep="first")  # before each event: still held
        on_twin = np.interp(trace["time"], twin["time"], twin["lag.y"])
        errors[h] = float(np.max(np.abs(trace["lag.y"] - on_twin)))
    lag_reference.check_first_order_loose_coupling(
        errors, T_LAG, above=1e-5
    )  # the twin's error on top: 1e-5 over the limit


def test_an_fmi3_cs_fmu_in_an_algebraic_loop_is_refused_naming_it_and_the_loop(fmus):
    lag = read_fmu(fmus["Lag3"], co_simulation=True)
    gain = read_fmu(fmus["Gain"])
    assert lag.output_feedthrough == {"y": [], "e": ["u"]}  # from its ModelStructure: e = u - y feeds u through
    with pytest.raises(
        InputError, match=r"the Co-Simulation FMU 'lag' \(Lag3\.fmu\) is in an algebraic loop: .*lag\.e"
    ):
        CoSimulation(
            {"lag": lag, "gain": gain},
            [Connection("lag.e", "gain.u"), Connection("gain.y", "lag.u")],
            communication_intervals={"lag": 0.1},
        )
    # through y (no direct feedthrough: a state) the same loop is no algebraic loop, and runs
    CoSimulation(
        {"lag": lag, "gain": gain},
        [Connection("lag.y", "gain.u"), Connection("gain.y", "lag.u")],
        communication_intervals={"lag": 0.1},
    )


def test_a_cs_only_fmi3_fmu_without_an_interval_and_an_me_only_one_with_one_are_refused_saying_so(fmus, tmp_path):
    with pytest.raises(InputError, match=r"Lag3\.fmu: FMI 3\.0 Co-Simulation only .*communication_interval"):
        read_fmu(fmus["Lag3CS"])
    assert read_fmu(fmus["Lag3CS"], co_simulation=True).co_simulation
    me_only = build_lag3_fmu(tmp_path, interfaces=("ModelExchange",))
    with pytest.raises(InputError, match=r"Lag3\.fmu: the FMU does not support Co-Simulation"):
        read_fmu(me_only, co_simulation=True)


def test_a_shorter_last_step_is_refused_for_an_fmu_that_cannot_vary_its_step(fmus, tmp_path):
    # Lag3 says canHandleVariableCommunicationStepSize="true": 1.05 s at 0.1 s ends with a step of 0.05 s
    assert example(fmus, 0.1, stop=1.05).statistics["sampled_components"]["lag"]["steps"] == 11
    fixed = {**fmus, "Lag3": build_lag3_fmu(tmp_path, variable_steps=False)}  # the attribute left out: false
    with pytest.raises(InputError, match=r"communication_interval\.lag: 0\.1 s does not divide the window \(1\.05 s\)"):
        example(fixed, 0.1, stop=1.05)
    assert example(fixed, 0.15, stop=1.05).statistics["sampled_components"]["lag"]["steps"] == 7  # 0.15 divides it


@pytest.mark.parametrize(
    "misbehave, flag",
    [
        (1, "eventHandlingNeeded, though instantiated with eventModeUsed = false (heliostep does not run FMI 3.0"),
        (2, "earlyReturn at lastSuccessfulTime = 1.05 s, before the communication point 1.1 s, though instantiated"),
    ],
)
def test_a_do_step_asking_for_event_mode_or_returning_early_fails_the_run_naming_the_instance_and_the_flag(
    fmus, misbehave, flag
):
    # t_stop = 1.05: the step from 1.0 to 1.1 asks for event mode (after the step, at 1.1), or returns
    # early at 1.05 (the step from 1.0 not completed)
    with pytest.raises(SimulationError) as failed:
        example(fmus, 0.1, {"t_stop": 1.05, "misbehave": misbehave})
    message = str(failed.value)
    at = "1.1" if misbehave == 1 else "1"
    assert message.startswith("simulation failed at t = 1.1 s: lag: fmi3DoStep returned ") and flag in message
    assert message.endswith(f" at t = {at} s"), message
    trace = failed.value.trace  # the rows so far kept: up to the point, the row before its event
    assert trace["time"].iloc[-1] == pytest.approx(1.1) and len(trace) > 1000


def test_a_scenario_runs_an_fmi3_cs_fmu_whose_terminate_simulation_ends_the_run_said_in_the_summary(
    fmus, tmp_path, capsys
):
    import json

    import pandas as pd

    from heliostep.cli import main

    # the paper's drive with the ramp and the lag (FMI 3.0 CS at 50 ms) beside it, supervised (the master
    # in a child process); the lag asks to terminate at the first point at or after t_stop = 2 s: the run
    # ends there, before the 4 s window (exit 1, the trace so far written)
    out = tmp_path / "out"
    args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(out), "--no-plots"]
    overrides = (
        "window.duration=4",
        f"fmus.ramp={fmus['Gain']}",
        f"fmus.lag={fmus['Lag3CS']}",
        "parameters.ramp={k: 0.0, b: 1.0}",
        "parameters.lag={t_stop: 2.0}",
        "communication_interval.lag=0.05",
        "connections=[[motor.tau, mechanics.tau], [mechanics.theta, motor.theta], [mechanics.omega, motor.omega],"
        " [ramp.s, lag.u]]",
    )
    assert main([*args, *(item for o in overrides for item in ("--set", o))]) == 1
    assert "terminated by lag at t = 2 s" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["terminated"]["instances"] == ["lag"] and summary["terminated"]["time_s"] == pytest.approx(2.0)
    assert "fmi3DoStep: terminateSimulation" in summary["terminated"]["by"]
    metadata = json.loads((out / "metadata.json").read_text())
    assert metadata["statistics"]["sampled_components"]["lag"]["steps"] == 40
    trace = pd.read_parquet(out / "trace.parquet")
    assert trace["time"].iloc[-1] == pytest.approx(2.0)
    after, k = after_points(trace, 0.05)
    _, y = sampled_lag(0.05, 2.0)
    assert len(after) > 30 and np.max(np.abs(after["lag.y"].to_numpy() - y[k])) < 1e-9
    assert "motor.tau" in trace and "mechanics.theta" in trace  # the drive beside it, as Model Exchange
