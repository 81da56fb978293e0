"""Issue #24: FMI 3.0 Model Exchange FMUs in the master and its compiled kernel.

The mini FMI 3.0 FMUs (``tests/data/mini3/``, built by ``tests/support/third_party_fmu3.py``): Counter3
(an Int32 count stepped at time events, a Boolean parity, a state with der(x) = scale, a Float32
parameter; it terminates at the first event at or after t_stop) and Threshold3 (tau dy/dt = u - y
with a state event where y crosses level). Each alone is compared with fmpy's own FMI 3.0
simulation (``fmpy.simulate_fmu``) and with first principles; connected with FMI 2.0 mini Gains
in one system, with first principles: a ramp s = t from a Gain drives the lag, so
y = t - tau (1 - exp(-t / tau)), and a second Gain integrates y.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from scipy.optimize import brentq

import heliostep.cosim.integrator as integrator
from heliostep.cosim import Connection, CoSimulation, SolverOptions, read_fmu
from heliostep.errors import InputError
from third_party_fmu import build_mini_fmu
from third_party_fmu3 import build_mini3_fmu

TAU, LEVEL = 0.5, 0.5


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("fmi3")
    built = {name: build_mini3_fmu(name, out) for name in ("Counter3", "Threshold3")}
    built["Gain"] = build_mini_fmu("Gain", out)
    built["PassThrough"] = build_mini_fmu("PassThrough", out)
    return built


def run(fmus, instances, connections=(), parameters=None, stop=8.0, n=17, rtol=1e-6):
    system = CoSimulation(
        {name: read_fmu(fmus[kind]) for name, kind in instances.items()},
        [Connection(*c) for c in connections],
        parameters=parameters or {},
    )
    return system.simulate(0.0, stop, np.linspace(0.0, stop, n), SolverOptions(rtol=rtol))


def test_the_counter_alone_agrees_with_fmpy_and_terminates_at_its_event(fmus):
    import fmpy

    result = run(fmus, {"c": "Counter3"}, parameters={"c": {"scale": 2.0, "t_stop": 4.5}})
    reference = fmpy.simulate_fmu(
        str(fmus["Counter3"]), stop_time=8.0, output_interval=0.5, start_values={"scale": 2.0}
    )
    assert result.terminated and result.termination_time == pytest.approx(5.0)
    assert result.statistics["termination_instances"] == ["c"]
    assert "fmi3UpdateDiscreteStates: terminateSimulation" in result.termination_reason
    assert result.statistics["compiled_rhs"] is True
    trace = result.trace
    # fmpy's run stops at the same event; its last row holds the values before the event, as
    # heliostep's row before it; heliostep's last row has the event's own (count 5, odd)
    assert reference["time"][-1] == pytest.approx(5.0)
    before, last = trace.iloc[-2], trace.iloc[-1]
    assert before["time"] == last["time"] == pytest.approx(5.0)
    assert before["c.count"] == reference["count"][-1] == 4 and before["c.odd"] == float(reference["odd"][-1]) == 0.0
    assert last["c.count"] == 5 and last["c.odd"] == 1.0
    assert last["c.x"] == pytest.approx(reference["x"][-1]) == pytest.approx(10.0)  # x = 2 t
    # between events: count = floor(t), x = 2 t (the Float32 parameter set through fmi3SetFloat32)
    between = trace[(trace["time"] % 1.0) == 0.5]
    assert len(between) == 5
    np.testing.assert_array_equal(between["c.count"], np.floor(between["time"]))
    np.testing.assert_allclose(between["c.x"], 2.0 * between["time"], rtol=1e-9)
    np.testing.assert_array_equal(between["c.odd"], np.floor(between["time"]) % 2)


def test_the_state_event_model_alone_crosses_where_fmpy_and_first_principles_say(fmus):
    import fmpy

    result = run(fmus, {"t": "Threshold3"}, stop=2.0, n=5, rtol=1e-9)
    reference = fmpy.simulate_fmu(str(fmus["Threshold3"]), stop_time=2.0, output_interval=0.5, relative_tolerance=1e-9)
    trace = result.trace
    crossing = trace["time"][trace["t.crossings"].diff() == 1].iloc[0]
    fmpy_crossing = reference["time"][np.flatnonzero(np.diff(reference["crossings"]) == 1)[0] + 1]
    assert crossing == pytest.approx(TAU * np.log(1.0 / (1.0 - LEVEL)), abs=1e-7)
    assert crossing == pytest.approx(fmpy_crossing, abs=1e-6)
    assert result.statistics["state_events"] == 1 and result.statistics["compiled_rhs"] is True
    at = trace.drop_duplicates("time", keep="last").set_index("time")
    for t in (0.5, 1.0, 2.0):
        assert at.loc[t, "t.y"] == pytest.approx(1.0 - np.exp(-t / TAU), rel=1e-6)
        assert at.loc[t, "t.y"] == pytest.approx(reference["y"][reference["time"] == t][-1], rel=1e-6)
        assert at.loc[t, "t.above"] == 1.0 and at.loc[t, "t.crossings"] == 1.0


def exact_y(t):
    return t - TAU * (1.0 - np.exp(-t / TAU))


def exact_integral(t):
    return t**2 / 2.0 - TAU * t + TAU**2 * (1.0 - np.exp(-t / TAU))


def test_fmi2_and_fmi3_fmus_in_one_system_follow_first_principles(fmus):
    result = run(
        fmus,
        {"ramp": "Gain", "lag": "Threshold3", "integral": "Gain"},
        [("ramp.s", "lag.u"), ("lag.y", "integral.u")],
        parameters={"ramp": {"k": 0.0, "b": 1.0}, "integral": {"k": 1.0, "b": 0.0}},
        stop=3.0,
        n=31,
        rtol=1e-9,
    )
    assert result.statistics["compiled_rhs"] is True  # FMI 3.0 through the adapter, in the one kernel
    trace = result.trace.drop_duplicates("time", keep="last")
    t = trace["time"].to_numpy()
    np.testing.assert_allclose(trace["lag.y"], exact_y(t), atol=1e-7)
    np.testing.assert_allclose(trace["integral.s"], exact_integral(t), atol=1e-7)
    crossing = result.trace["time"][result.trace["lag.crossings"].diff() == 1].iloc[0]
    assert crossing == pytest.approx(brentq(lambda s: exact_y(s) - LEVEL, 0.1, 3.0), abs=1e-7)


def test_the_counters_int32_and_boolean_outputs_drive_an_fmi2_fmus_integer_and_boolean_inputs(fmus):
    result = run(
        fmus,
        {"c": "Counter3", "p": "PassThrough"},
        [("c.count", "p.u_i"), ("c.odd", "p.u_b"), ("c.x", "p.u_c")],
        parameters={"c": {"t_stop": 100.0}},
        stop=6.0,
        n=13,
    )
    trace = result.trace.drop_duplicates("time", keep="last")
    t = trace["time"].to_numpy()
    np.testing.assert_array_equal(trace["p.y_i"], np.floor(t))  # count = floor(t), through FMI 2.0's Integer
    np.testing.assert_array_equal(trace["p.y_b"], np.floor(t) % 2)  # odd, through FMI 2.0's Boolean
    np.testing.assert_allclose(trace["p.y_c"], t, rtol=1e-9)  # x = t (scale 1)
    assert result.statistics["time_events"] == 6 and not result.terminated


def test_an_fmi3_instance_logs_into_its_own_messages(fmus, caplog):
    with caplog.at_level(logging.DEBUG, logger="heliostep.fmu"):
        run(fmus, {"first": "Counter3", "second": "Counter3"}, parameters={"first": {"t_stop": 1.0}}, stop=2.0)
    initialized = [r.getMessage() for r in caplog.records if "initialized" in r.getMessage()]
    assert sorted(m.split(" ")[0] for m in initialized) == ["first", "second"]
    assert [r.getMessage().split(" ")[0] for r in caplog.records if "terminating" in r.getMessage()] == ["first"]


@pytest.mark.parametrize(
    "extra, interface, feature",
    [
        (
            '    <Clock name="tick" valueReference="20" causality="input" variability="discrete"/>',
            "ModelExchange",
            "clock",
        ),
        (
            '    <Float64 name="v" valueReference="21" causality="output" variability="discrete" clocks="20"/>\n'
            '    <Clock name="tick" valueReference="20" causality="input" variability="discrete"/>',
            "ModelExchange",
            "clocked variable 'v'",
        ),
        ("", "CoSimulation", "Co-Simulation"),
    ],
)
def test_unsupported_fmi3_features_are_refused_up_front_naming_the_fmu_and_the_feature(
    tmp_path, extra, interface, feature
):
    path = build_mini3_fmu("Counter3", tmp_path, extra=extra, interface=interface)
    with pytest.raises(InputError) as refused:
        read_fmu(path)
    assert str(path) in str(refused.value) and feature in str(refused.value)


def test_on_the_python_right_hand_side_the_mixed_system_gives_the_same_first_principles(fmus, monkeypatch):

    monkeypatch.setattr(integrator, "compiled_kernel", lambda *args: None)
    result = run(
        fmus,
        {"ramp": "Gain", "lag": "Threshold3", "integral": "Gain"},
        [("ramp.s", "lag.u"), ("lag.y", "integral.u")],
        parameters={"ramp": {"k": 0.0, "b": 1.0}, "integral": {"k": 1.0, "b": 0.0}},
        stop=3.0,
        n=31,
        rtol=1e-9,
    )
    assert result.statistics["compiled_rhs"] is False
    trace = result.trace.drop_duplicates("time", keep="last")
    np.testing.assert_allclose(trace["lag.y"], exact_y(trace["time"].to_numpy()), atol=1e-7)
    np.testing.assert_allclose(trace["integral.s"], exact_integral(trace["time"].to_numpy()), atol=1e-7)


def test_an_fmi3_counter_beside_the_shipped_drive_terminates_the_run_said_in_summary_json(tmp_path, capsys, fmus):
    import json

    from heliostep.cli import main
    from heliostep.paths import scenarios_dir

    out = tmp_path / "out"
    args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(out), "--no-plots"]
    args += ["--set", "window.duration=12", "--set", f"fmus.counter={fmus['Counter3']}"]
    assert main([*args, "--set", "parameters.counter.t_stop=2.5"]) == 1  # supervised: in a child process
    assert "terminated by counter at t = 3 s" in capsys.readouterr().out  # the first event at or after 2.5 s
    summary = json.loads((out / "summary.json").read_text())
    assert summary["terminated"]["instances"] == ["counter"] and summary["terminated"]["time_s"] == pytest.approx(3.0)


def test_a_clock_fmu_in_a_scenario_is_exit_2_naming_the_fmu_and_the_clock(tmp_path, capsys):
    from heliostep.cli import main
    from heliostep.paths import scenarios_dir

    clocked = build_mini3_fmu(
        "Counter3",
        tmp_path,
        extra='    <Clock name="tick" valueReference="20" causality="input" variability="discrete"/>',
    )
    args = ["run", str(scenarios_dir() / "jan21-central.yaml"), "--out", str(tmp_path / "out"), "--no-plots"]
    assert main([*args, "--no-supervise", "--set", f"fmus.counter={clocked}"]) == 2
    error = capsys.readouterr().err
    assert str(clocked) in error and "clock" in error
