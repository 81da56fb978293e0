"""Issue #24: the master run against FMI 3.0 FMUs that nobody in the project wrote, of the kinds the
issue names: exported by PythonFMU3 (``tests/support/third_party_pythonfmu3.py``: its own C++ FMI 3.0 layer
and modelDescription.xml), each checked against fmpy's own FMI 3.0 simulation and first principles:

- a first-order lag (Model Exchange) driven by an FMI 2.0 ramp in one system, in the compiled kernel:
  y = t - T (1 - exp(-t / T));
- a counter with an Int32 output and time events that asks to terminate;
- a state event: x falls at a rate r from 1, reset to 1 where it crosses zero: crossings at k / r;
- outputs of several types (Int32, Int64, UInt64, Boolean) and a Float64[3] array, traced element-wise;
- the lag as Co-Simulation, sampled: the recurrence of the sampled ramp;
- the counter beside the shipped drive in a supervised ``heliostep run``: the termination said;
- an FMI 2.0 Co-Simulation lag exported by PythonFMU, sampled, and its refused step (``do_step``
  returning False: PythonFMU's ``fmi2Discard``, then ``fmi2Terminated``) ending the run there.
"""

from __future__ import annotations

import json

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

import lag_reference
from heliostep.cosim import Connection, CoSimulation, SolverOptions, read_fmu
from third_party_fmu import build_mini_fmu
from third_party_pythonfmu3 import MODELS, MODELS2, build_pythonfmu, build_pythonfmu3

T_LAG = 0.5


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("pythonfmu3")
    built = {model: build_pythonfmu3(model, out) for model in MODELS}
    built.update({model: build_pythonfmu(model, out) for model in MODELS2})
    built["Gain"] = build_mini_fmu("Gain", out)
    return built


def simulate(fmus, instances, connections=(), parameters=None, stop=3.0, n=31, intervals=None):
    system = CoSimulation(
        {
            name: read_fmu(fmus[model], co_simulation=bool(intervals and name in intervals))
            for name, model in instances.items()
        },
        [Connection(*c) for c in connections],
        parameters=parameters or {},
        communication_intervals=intervals,
    )
    return system.simulate(0.0, stop, np.linspace(0.0, stop, n), SolverOptions(rtol=1e-9))


def test_the_fmus_are_pythonfmu3s_own_fmi3_exports(fmus):
    for model in MODELS:
        description = fmpy.read_model_description(str(fmus[model]))
        assert description.fmiVersion == "3.0" and description.generationTool.startswith("PythonFMU3")
        assert validate_fmu(str(fmus[model])) == []  # fmpy's checks of its XML


def test_a_pythonfmu3_lag_driven_by_an_fmi2_ramp_follows_the_exact_solution_in_the_compiled_kernel(fmus):
    result = simulate(
        fmus,
        {"ramp": "Gain", "lag": "lag_me"},
        [("ramp.s", "lag.u")],
        {"ramp": {"k": 0.0, "b": 1.0}, "lag": {"T": T_LAG}},
        n=301,
    )
    trace = result.trace
    assert np.max(np.abs(trace["lag.y"] - lag_reference.exact_lag(trace["time"], T_LAG))) < 1e-6
    assert result.statistics["compiled_rhs"] is True  # FMI 2.0 and FMI 3.0 in one compiled system


def test_the_counter_terminates_at_its_limit_where_fmpy_stops_and_counts_the_time_events(fmus):
    result = simulate(fmus, {"c": "counter_me"}, parameters={"c": {"period": 0.25, "limit": 5}})
    reference = fmpy.simulate_fmu(str(fmus["counter_me"]), stop_time=3.0, output_interval=0.05)
    assert result.terminated and result.termination_time == pytest.approx(1.25)
    assert result.statistics["termination_instances"] == ["c"]
    assert (
        "c asked to terminate the simulation (fmi3UpdateDiscreteStates: terminateSimulation)"
        in result.termination_reason
    )
    assert reference["time"][-1] == pytest.approx(1.25)  # fmpy stops at the same event
    trace = result.trace
    assert trace["c.count"].iloc[-1] == 5 and trace["time"].iloc[-1] == pytest.approx(1.25)
    between = trace[trace["time"] < 1.25 - 1e-9].drop_duplicates("time", keep="last")
    np.testing.assert_array_equal(between["c.count"], np.floor(between["time"] / 0.25 + 1e-9))
    assert result.statistics["time_events"] == 5


def test_the_state_event_crosses_where_first_principles_and_fmpy_say(fmus):
    rate = 2.0
    result = simulate(fmus, {"b": "bounce_me"}, parameters={"b": {"rate": rate}}, stop=2.2, n=23)
    reference = fmpy.simulate_fmu(
        str(fmus["bounce_me"]), stop_time=2.2, output_interval=0.1, start_values={"rate": rate}, relative_tolerance=1e-9
    )
    trace = result.trace
    crossings = trace["time"][trace["b.crossings"].diff() == 1].to_numpy()
    np.testing.assert_allclose(crossings, np.arange(1, 5) / rate, atol=1e-7)  # k / r
    assert result.statistics["state_events"] == 4
    fmpy_crossings = reference["time"][np.flatnonzero(np.diff(reference["crossings"]) == 1) + 1]
    np.testing.assert_allclose(crossings, fmpy_crossings, atol=1e-6)
    rows = trace.drop_duplicates("time", keep="last")
    for t in (0.1, 0.7, 1.3, 1.9):  # x = 1 - r (t - k / r) after the k-th crossing
        row = rows.iloc[int(np.argmin(np.abs(rows["time"].to_numpy() - t)))]
        k = np.floor(row["time"] * rate)
        assert row["time"] == pytest.approx(t)
        assert row["b.x"] == pytest.approx(1.0 - rate * (row["time"] - k / rate), abs=1e-7)
        assert row["b.crossings"] == k


def test_outputs_of_every_integer_type_a_boolean_and_an_array_are_traced_element_wise(fmus):
    result = simulate(fmus, {"types": "types_me"}, parameters={"types": {"period": 0.5}}, stop=2.9, n=30)
    trace = result.trace
    assert [c for c in trace.columns if c.startswith("types.")] == [
        "types.whole",
        "types.big",
        "types.unsigned",
        "types.odd",
        "types.scaled[1]",
        "types.scaled[2]",
        "types.scaled[3]",
    ]
    assert result.statistics["text_outputs"]["types.label"][:3] == [[0.0, "k=0"], [0.5, "k=1"], [1.0, "k=2"]]
    rows = trace.drop_duplicates("time", keep="last")
    k = np.floor(rows["time"].to_numpy() / 0.5 + 1e-9)  # the events so far
    np.testing.assert_array_equal(rows["types.whole"], k)
    np.testing.assert_array_equal(rows["types.big"], k * 2.0**33)  # Int64, exact in a double
    np.testing.assert_array_equal(rows["types.unsigned"], k + 2.0**40)  # UInt64
    np.testing.assert_array_equal(rows["types.odd"], k % 2)
    for i in (1, 2, 3):
        np.testing.assert_array_equal(rows[f"types.scaled[{i}]"], i * k)
    assert result.statistics["time_events"] == 5


def test_a_pass_through_of_every_type_and_an_array_fed_element_by_element_gives_back_its_inputs(fmus):
    connections = [
        ("types.whole", "p.i32_in"),
        ("types.big", "p.i64_in"),
        ("types.unsigned", "p.u64_in"),
        ("types.odd", "p.b_in"),
        ("types.label", "p.s_in"),
        ("types.scaled[1]", "p.a_in[3]"),  # reversed, element by element
        ("types.scaled[2]", "p.a_in[2]"),
        ("types.scaled[3]", "p.a_in[1]"),
    ]
    result = simulate(fmus, {"types": "types_me", "p": "pass_me"}, connections, stop=2.9, n=30)
    trace = result.trace
    for source, target in connections[:4]:
        np.testing.assert_array_equal(trace[target.replace("_in", "_out")], trace[source])
    for i in (1, 2, 3):
        np.testing.assert_array_equal(trace[f"p.a_out[{4 - i}]"], trace[f"types.scaled[{i}]"])
    k = np.floor(trace["time"].drop_duplicates(keep="last").to_numpy() / 0.5 + 1e-9)
    assert trace["p.a_out[1]"].drop_duplicates().tolist() == [3.0 * j for j in range(int(k.max()) + 1)]
    texts = result.statistics["text_outputs"]  # the String, at each change
    assert texts["p.s_out"] == texts["types.label"] == [[0.5 * j, f"k={j}"] for j in range(6)]


def test_the_pythonfmu3_cs_lag_runs_sampled_as_the_recurrence_of_the_sampled_ramp(fmus):
    h = 0.1
    result = simulate(
        fmus,
        {"ramp": "Gain", "lag": "lag_cs"},
        [("ramp.s", "lag.u")],
        {"ramp": {"k": 0.0, "b": 1.0}, "lag": {"T": T_LAG}},
        n=301,
        intervals={"lag": h},
    )
    points, y = lag_reference.sampled_lag(h, 3.0, T_LAG)
    trace = result.trace
    mid = trace[np.isclose((trace["time"] / h) % 1.0, 0.5, atol=1e-6)]  # half-way between points: held
    k = np.floor(mid["time"].to_numpy() / h + 1e-9).astype(int)
    assert len(mid) > 20
    np.testing.assert_allclose(mid["lag.y"].to_numpy(), y[k], atol=1e-12)
    assert result.statistics["sampled_components"]["lag"] == {"interval_s": h, "steps": 30}


def test_the_pythonfmu3_counter_beside_the_shipped_drive_terminates_a_supervised_run_said_in_the_summary(
    fmus, tmp_path, capsys
):
    from heliostep.cli import main
    from heliostep.paths import scenarios_dir

    out = tmp_path / "out"
    args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(out), "--no-plots"]
    args += ["--set", "window.duration=12", "--set", f"fmus.counter={fmus['counter_me']}"]
    assert main([*args, "--set", "parameters.counter={period: 1.0, limit: 3}"]) == 1  # in a child process
    assert "terminated by counter at t = 3 s" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["terminated"]["instances"] == ["counter"] and summary["terminated"]["time_s"] == pytest.approx(3.0)


def test_a_pythonfmu_fmi2_cs_lag_runs_sampled_and_its_refused_step_ends_the_run_said_with_its_last_time(fmus):
    assert fmpy.read_model_description(str(fmus["lag2_cs"])).generationTool.startswith("PythonFMU")
    h = 0.1
    parameters = {"ramp": {"k": 0.0, "b": 1.0}, "lag": {"T": T_LAG}}
    instances, connections = {"ramp": "Gain", "lag": "lag2_cs"}, [("ramp.s", "lag.u")]
    result = simulate(fmus, instances, connections, parameters, n=301, intervals={"lag": h})
    _, y = lag_reference.sampled_lag(h, 3.0, T_LAG)
    trace = result.trace
    mid = trace[np.isclose((trace["time"] / h) % 1.0, 0.5, atol=1e-6)]
    k = np.floor(mid["time"].to_numpy() / h + 1e-9).astype(int)
    np.testing.assert_allclose(mid["lag.y"].to_numpy(), y[k], atol=1e-12)
    assert not result.terminated
    # the step from 1.2 s to 1.3 s passes t_stop = 1.25 s: PythonFMU returns fmi2Discard and then says
    # fmi2Terminated, its last successful time 1.2 s; the run ends at the point 1.3 s, the lag held at y(1.2)
    stopped = simulate(
        fmus, instances, connections, {**parameters, "lag": {"T": T_LAG, "t_stop": 1.25}}, n=301, intervals={"lag": h}
    )
    assert stopped.terminated and stopped.termination_time == pytest.approx(1.3)
    assert "fmi2DoStep: fmi2Discard, then fmi2Terminated, its last successful time 1.2 s" in stopped.termination_reason
    assert stopped.trace["lag.y"].iloc[-1] == pytest.approx(y[12], abs=1e-12)


def test_a_crash_inside_the_third_party_fmu_fails_a_supervised_run_named_with_its_trace_so_far(fmus, tmp_path, capsys):
    from heliostep.cli import main
    from heliostep.paths import scenarios_dir
    from heliostep.results.trace.files import read_trace

    # past t_fail the lag's derivatives raise and PythonFMU3's C++ layer dies of it (SIGSEGV): the
    # supervised run (the master in a child process) says where, keeps the trace so far and exits 1
    def run(out, t_fail):
        args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(out), "--no-plots"]
        overrides = (
            "window.duration=60",
            f"fmus.lag={fmus['lag_me']}",
            f"parameters.lag={{T: 0.5, t_fail: {t_fail}}}",
            "connections=[[motor.tau, mechanics.tau], [mechanics.theta, motor.theta],"
            " [mechanics.omega, motor.omega], [mechanics.omega, lag.u]]",
        )
        return main([*args, *(item for o in overrides for item in ("--set", o))])

    assert run(tmp_path / "complete", 1e300) == 0
    assert run(tmp_path / "out", 40.0) == 1
    error = capsys.readouterr().err
    assert "was killed by SIGSEGV in fmi3GetContinuousStateDerivatives of FMU instance 'lag' (model PyLag)" in error
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["complete"] is False and summary["reason"] == "fmu-crashed"
    trace, meta = read_trace(tmp_path / "out" / "trace.parquet")
    assert meta["complete"] == "false" and 20.0 < trace["time"].iloc[-1] <= 40.0
    # the rows kept are those of the run without the crash, up to where it stopped
    complete, _ = read_trace(tmp_path / "complete" / "trace.parquet")
    for column in ("time", "motor.tau", "mechanics.theta_p", "lag.y"):
        np.testing.assert_array_equal(trace[column].to_numpy(), complete[column].to_numpy()[: len(trace)])
