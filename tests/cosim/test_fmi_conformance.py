"""FMI 2.0 conformance of the master with small hand-written FMUs of every variable type.

The FMUs (``tests/data/mini/``, built with gcc by ``third_party_fmu.build_mini_fmu``):
Counter (Integer/Boolean/discrete Real outputs, time events every second, asks to terminate
at t_stop = 9 s), PassThrough (continuous, discrete Real, Integer and Boolean inputs copied to
outputs; its discrete inputs refuse to be set in continuous-time mode, as FMI 2.0 demands;
its derivatives fail once |u_c| > u_max) and Switch (a Boolean mode changed by state events).
Each is checked alone against fmpy and connected against first principles.
"""

import logging
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu

import heliostep.cosim.integrator as integrator
from heliostep.cosim import (
    Connection,
    CoSimulation,
    PiecewiseConstant,
    SimulationError,
    read_fmu,
)
from heliostep.cosim.fmi import FMIError, ModelExchangeInstance
from heliostep.cosim.integrator import compiled_kernel
from heliostep.errors import InputError
from third_party_fmu import build_mini_fmu


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    out = tmp_path_factory.mktemp("mini")
    return {name: build_mini_fmu(name, out) for name in ("Counter", "PassThrough", "Switch", "Rescale")}


@pytest.fixture(scope="module")
def infos(mini):
    return {name: read_fmu(path) for name, path in mini.items()}


def connected(infos, **parameters):
    system = CoSimulation(
        {"counter": infos["Counter"], "pt": infos["PassThrough"], "sw": infos["Switch"]},
        [
            Connection("counter.count", "pt.u_i"),
            Connection("counter.half", "pt.u_d"),
            Connection("sw.on", "pt.u_b"),
            Connection("sw.x", "pt.u_c"),
        ],
        parameters=parameters,
    )
    return system.simulate(0.0, 12.0, np.arange(0.0, 12.01, 0.5))


def at(trace, t):
    """The rows at time t (two around an event)."""
    return trace[np.isclose(trace["time"], t, rtol=0, atol=1e-9)]


# ------------------------------------------------------------------ types of variables
def test_read_fmu_knows_every_variable_type(infos):
    counter = infos["Counter"]
    assert {n: counter.variables[n].type for n in ("count", "x", "half", "even", "step", "enabled")} == {
        "count": "Integer",
        "x": "Real",
        "half": "Real",
        "even": "Boolean",
        "step": "Integer",
        "enabled": "Boolean",
    }
    assert counter.variables["enabled"].start == 1.0 and counter.variables["step"].start == 1.0
    assert counter.variables["half"].discrete and not counter.variables["x"].discrete
    assert counter.traced_outputs == ["count", "x", "half", "even"]


def test_counter_alone_matches_fmpy_and_terminates_at_9_s(mini, infos):
    grid = np.arange(0.0, 12.01, 0.5)
    ours = CoSimulation({"c": infos["Counter"]}).simulate(0.0, 12.0, grid)
    theirs = simulate_fmu(
        str(mini["Counter"]), stop_time=12.0, output_interval=0.5, solver="CVode", output=["count", "x", "half", "even"]
    )
    # fmpy ends at the terminate request too
    assert theirs["time"][-1] == pytest.approx(9.0)
    assert ours.terminated and ours.termination_time == pytest.approx(9.0)
    assert "c asked to terminate" in ours.termination_reason
    assert ours.statistics["terminated"] is True and ours.statistics["termination_time"] == pytest.approx(9.0)
    trace = ours.trace
    assert trace["time"].iloc[-1] == pytest.approx(9.0)
    for t in np.arange(0.5, 9.0, 1.0):  # grid times that are not events
        row = at(trace, t).iloc[0]
        theirs_row = theirs[np.isclose(theirs["time"], t)][0]
        assert row["c.count"] == theirs_row["count"] == np.floor(t)
        assert row["c.x"] == pytest.approx(theirs_row["x"], abs=1e-6)
        assert row["c.half"] == theirs_row["half"] and bool(row["c.even"]) == bool(theirs_row["even"])
    # first principles: count jumps by one at every whole second, x = sum of the counts
    for k in range(1, 10):
        before, after = at(trace, k)[["c.count", "c.even"]].to_numpy()[[0, -1]]
        assert before[0] == k - 1 and after[0] == k
        assert after[1] == float(k % 2 == 0)
    assert trace["c.x"].iloc[-1] == pytest.approx(36.0, abs=1e-6)  # 0 + 1 + ... + 8


@pytest.mark.parametrize("interpolate", [False, True])
def test_a_time_event_a_rounding_error_after_an_output_time_is_handled_at_its_own_instant(infos, interpolate):
    # np.linspace(0, 2.9, 30) holds 0.49999999999999994, 0.9999999999999999, ...: output times a rounding
    # error before the counter's time events every 0.5 s. Stopping there, the master once took each event
    # as passed (within eps of the time reached) and lost it and every later one (count 0 at the end).
    grid = np.linspace(0.0, 2.9, 30)
    assert 0.5 - grid[5] == pytest.approx(5.55e-17, rel=0.01)  # the output time just before the event
    monitor = (lambda rows: None) if interpolate else None
    result = CoSimulation({"c": infos["Counter"]}, parameters={"c": {"period": 0.5}}).simulate(
        0.0, 2.9, grid, monitor=monitor
    )
    assert result.statistics["time_events"] == 5  # at 0.5, 1.0, ... 2.5 s
    trace = result.trace
    for k in range(1, 6):  # count steps by one at each event, at the event's own time
        before, after = at(trace, 0.5 * k)["c.count"].to_numpy()[[0, -1]]
        assert (before, after) == (k - 1, k)
    # first principles: x = the integral of the count, 0.5 (0 + 1 + ... + 4) + 0.4 * 5 at 2.9 s
    assert trace["c.x"].iloc[-1] == pytest.approx(0.5 * 10 + 0.4 * 5, abs=1e-6)


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("interpolate", [False, True])
@pytest.mark.parametrize("side", ["before", "after"])
def test_time_events_that_change_no_state_keep_the_run_going(infos, monkeypatch, compiled, interpolate, side):
    """A periodic time event that changes no state while the state moves (FMPy issue 882's case: a
    Modelica sample(0.2, 0.2) counting in a discrete variable, der(x) = 1; CVODE, restarted after each
    event, was asked for an output time within rounding of the restart and stopped with CV_TOO_CLOSE).
    Here the Counter with ``enabled`` false only ticks at its events every 0.2 s ((k + 1) 0.2: 0.6000000000000001
    s, 1.2000000000000002 s, ...) and x has der(x) = rate = 1; the output times k / 10 fall a rounding
    error before some events, or are moved a rounding error after each. The run goes on to the end on
    either path: every event at its own instant, a row on each side with the same x, x = t throughout."""
    monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
    events = np.array([(k + 1.0) * 0.2 for k in range(10)])
    grid = np.array([k / 10 for k in range(21)])
    assert grid[6] < events[2] and grid[12] < events[5] and grid[14] < events[6]  # 1 ulp before
    if side == "after":
        grid = np.union1d(grid, np.nextafter(events[:-1], np.inf))  # 1 ulp after each event but the last
    parameters = {"c": {"period": 0.2, "enabled": False, "rate": 1.0, "t_stop": 100.0}}
    result = CoSimulation({"c": infos["Counter"]}, parameters=parameters).simulate(
        0.0, 2.0, grid, monitor=(lambda rows: None) if interpolate else None
    )
    stats, trace = result.statistics, result.trace
    assert stats["compiled_rhs"] == compiled and not result.terminated
    assert stats["time_events"] == 10 and trace["time"].iloc[-1] == 2.0
    times = trace["time"].to_numpy()
    for t in events[:-1]:  # the row before and the row after each event, at the event's own instant
        assert np.count_nonzero(times == t) >= 2
        assert np.ptp(trace.loc[times == t, "c.x"]) == 0.0  # the event changed no state
    # every output time has its row (one within rounding of an event: the event's own rows)
    assert all(np.min(np.abs(times - t)) <= 1e-12 for t in grid)
    np.testing.assert_allclose(trace["c.x"], times, rtol=0, atol=1e-12)
    assert (trace["c.count"] == 0).all()


def test_integer_and_boolean_parameters_are_set_with_their_own_functions(infos):
    grid = np.array([0.0, 3.5])
    doubled = CoSimulation({"c": infos["Counter"]}, parameters={"c": {"step": 2, "t_stop": 4.0}})
    assert at(doubled.simulate(0.0, 5.0, grid).trace, 3.5)["c.count"].iloc[0] == 6.0
    disabled = CoSimulation({"c": infos["Counter"]}, parameters={"c": {"enabled": False, "t_stop": 4.0}})
    assert at(disabled.simulate(0.0, 5.0, grid).trace, 3.5)["c.count"].iloc[0] == 0.0
    with pytest.raises(InputError, match="parameter step: 1.5 is not a valid Integer value"):
        CoSimulation({"c": infos["Counter"]}, parameters={"c": {"step": 1.5}})


def test_switch_alone_matches_fmpy_and_switches_at_the_exact_times(mini, infos):
    ours = CoSimulation({"s": infos["Switch"]}).simulate(0.0, 4.0, np.arange(0.0, 4.01, 0.25)).trace
    theirs = simulate_fmu(
        str(mini["Switch"]), stop_time=4.0, output_interval=0.25, solver="CVode", output=["x", "on", "switches"]
    )
    for t in (0.25, 0.5, 1.25, 2.0, 2.75, 3.5):
        assert at(ours, t)["s.x"].iloc[0] == pytest.approx(theirs[np.isclose(theirs["time"], t)]["x"][0], abs=1e-6)
    # x rises at 1/s to 1 (t = 1), falls at 2/s to 0 (t = 1.5), rises to 1 (2.5), falls to 0 (3.0)
    for k, (t, on_after) in enumerate([(1.0, 0.0), (1.5, 1.0), (2.5, 0.0), (3.0, 1.0)], start=1):
        rows = at(ours, t)
        assert len(rows) >= 2, f"no event rows at t = {t}"
        assert rows["s.on"].iloc[0] == 1.0 - on_after and rows["s.on"].iloc[-1] == on_after
        assert rows["s.switches"].iloc[0] == k - 1 and rows["s.switches"].iloc[-1] == k
    assert at(ours, 4.0)["s.x"].iloc[-1] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled kernel", "python callbacks"])
def test_nominals_are_read_at_the_start_and_again_only_when_an_event_says_they_changed(infos, compiled, monkeypatch):
    """FMI 2.0: the states' nominals change only where fmi2NewDiscreteStates says
    nominalsOfContinuousStatesChanged. Rescale has a time event every 0.25 s and changes its
    nominal at the one at t = 1: the master reads them twice (the FMU counts the calls), not at
    every event, and the solution stays e^-t."""

    monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
    result = CoSimulation({"r": infos["Rescale"]}).simulate(0.0, 3.0, np.arange(0.0, 3.01, 0.5))
    trace = result.trace
    assert result.statistics["events"] >= 11  # 0.25, 0.5, ..., 2.75
    assert trace["r.nominal_reads"].iloc[-1] == 2 and result.statistics["nominal_reads"] == 2
    assert at(trace, 1.0)["r.switched"].iloc[-1] == 1.0 and at(trace, 0.5)["r.switched"].iloc[-1] == 0.0
    assert trace["r.nominal_reads"][trace["time"] < 1.0].max() == 1  # the first read, before the switch
    np.testing.assert_allclose(trace["r.x"], np.exp(-trace["time"]), rtol=1e-3)  # CVODE at rtol 1e-6 over 12 restarts


# ------------------------------------------------------------------ connected, discrete exchange
def test_connected_values_follow_on_every_row_and_discrete_inputs_change_only_at_events(infos):
    result = connected(infos)
    trace = result.trace
    # PassThrough refuses discrete inputs in continuous-time mode (fmi2Error): the run succeeding
    # proves they were set only at events; every row shows the copies of the current outputs
    np.testing.assert_array_equal(trace["pt.y_i"], trace["counter.count"])
    np.testing.assert_array_equal(trace["pt.y_d"], trace["counter.half"])
    np.testing.assert_array_equal(trace["pt.y_b"], trace["sw.on"])
    np.testing.assert_allclose(trace["pt.y_c"], trace["sw.x"], atol=1e-12)
    for k in range(1, 10):  # time events of the counter: rows before and after, at exactly k s
        rows = at(trace, k)
        assert rows["pt.y_i"].iloc[0] == k - 1 and rows["pt.y_i"].iloc[-1] == k
        assert rows["pt.y_d"].iloc[-1] == k / 2
    # the integral of the triangle wave: 0.75 per 1.5 s period
    assert at(trace, 3.0)["pt.integral"].iloc[0] == pytest.approx(1.5, abs=1e-5)
    assert at(trace, 4.5)["pt.integral"].iloc[0] == pytest.approx(2.25, abs=1e-5)
    assert result.terminated and result.termination_time == pytest.approx(9.0)
    assert trace["time"].max() == pytest.approx(9.0)


def test_discrete_input_in_continuous_time_mode_is_refused_by_the_fmu(infos):
    with ModelExchangeInstance(infos["PassThrough"], "pt") as pt:
        pt.setup_experiment(0.0)
        pt.enter_initialization_mode()
        pt.set_integer([2], [3])
        pt.set_boolean([3], [True])
        pt.exit_initialization_mode()
        pt.enter_continuous_time_mode()
        assert list(pt.reader(["y_i", "y_b", "y_c"])()) == [3.0, 1.0, 0.0]
        with pytest.raises(
            FMIError, match="u_i can only be set after instantiation, in initialization mode or event mode"
        ):
            pt.set_integer([2], [4])


def test_master_input_drives_an_integer_input_at_its_change_times(infos):
    step = PiecewiseConstant("n", "pt.u_i", np.array([0.5]), np.array([2.0, 7.0]))
    trace = CoSimulation({"pt": infos["PassThrough"]}, inputs=[step]).simulate(0.0, 1.0).trace
    assert list(at(trace, 0.5)["pt.y_i"]) == [2.0, 7.0]
    assert trace["pt.y_i"].iloc[-1] == 7.0


@pytest.mark.parametrize(
    "connection, message",
    [
        (Connection("sw.on", "pt.u_i"), r"types are incompatible \(sw.on is Boolean, pt.u_i is Integer\)"),
        (Connection("counter.count", "pt.u_c"), r"types are incompatible \(counter.count is Integer, pt.u_c is Real\)"),
        (Connection("sw.x", "pt.u_b"), r"types are incompatible \(sw.x is Real, pt.u_b is Boolean\)"),
        (Connection("sw.x", "counter.x"), "expected an input, it is a Real output"),
    ],
)
def test_incompatible_connections_are_refused_naming_both_ends(infos, connection, message):
    with pytest.raises(InputError, match=message):
        CoSimulation({"counter": infos["Counter"], "pt": infos["PassThrough"], "sw": infos["Switch"]}, [connection])


# ------------------------------------------------------------------ errors, logging, life cycle
def test_fmu_error_inside_the_integrator_keeps_its_message_and_time(infos, caplog):
    system = CoSimulation(
        {"pt": infos["PassThrough"], "sw": infos["Switch"]},
        [Connection("sw.x", "pt.u_c")],
        parameters={"pt": {"u_max": 0.75}},
    )
    with caplog.at_level(logging.DEBUG, logger="heliostep.fmu"):
        with pytest.raises(SimulationError) as failure:
            system.simulate(0.0, 2.0, np.arange(0.0, 2.01, 0.5))
    error = failure.value
    cause = error.__cause__
    assert isinstance(cause, FMIError) and cause.instance == "pt" and cause.function == "fmi2GetDerivatives"
    # u_c = x = t before the switch at 1 s: the failing evaluation is past 0.75 s, never t = 0
    assert 0.75 < error.time < 1.5 and cause.time == pytest.approx(error.time)
    assert f"u_c = {error.time:.6f} exceeds u_max = 0.75" in str(error)
    assert f"simulation failed at t = {error.time:.9g} s" in str(error)
    assert error.trace["time"].max() == pytest.approx(0.5)
    # every instance was terminated (the failed one from its error state) and freed
    terminated = [r.getMessage() for r in caplog.records if "fmi2Terminate at t" in r.getMessage()]
    assert any(m.startswith("pt ") for m in terminated) and any(m.startswith("sw ") for m in terminated)


def test_terminate_is_called_when_the_run_ends_normally(infos, caplog):
    with caplog.at_level(logging.DEBUG, logger="heliostep.fmu"):
        CoSimulation({"c": infos["Counter"]}).simulate(0.0, 12.0)
    assert any(r.getMessage() == "c [fmi2OK] fmi2Terminate at t = 9" for r in caplog.records)


def test_log_messages_stay_with_their_instance(infos):
    first = ModelExchangeInstance(infos["PassThrough"], "first")
    second = ModelExchangeInstance(infos["PassThrough"], "second")  # created last
    try:
        with pytest.raises(FMIError) as failure:
            first.set_real([99], [1.0])
        assert str(failure.value).startswith("first: fmi2SetReal returned fmi2Error")
        assert "fmi2SetReal: invalid value reference 99" in failure.value.messages
        assert not second.messages
        with pytest.raises(FMIError, match=r"second: fmi2SetInteger .*u_d \(value reference 1\) is a Real"):
            second.set_integer([1], [1])
    finally:
        first.close()
        second.close()


def test_calls_on_a_freed_instance_are_fmi_errors(infos):
    inst = ModelExchangeInstance(infos["Switch"], "gone")
    inst.free()
    with pytest.raises(FMIError, match="gone: fmi2SetTime returned no instance"):
        inst.set_time(1.0)
    with pytest.raises(FMIError, match="fmi2GetDerivatives returned no instance"):
        inst.get_derivatives_at(0)
    with pytest.raises(FMIError, match="fmi2GetReal returned no instance"):
        inst.reader(["x"])()


# ------------------------------------------------------------------ binaries
def test_fmu_without_a_binary_for_this_platform_is_refused_up_front(tmp_path):
    fmu = build_mini_fmu("Switch", tmp_path, platform="win64")
    with pytest.raises(InputError, match=r"Switch.fmu: no binary for this platform \(linux64\).*binaries for: win64"):
        read_fmu(fmu)


def test_fmu_with_a_broken_binary_is_refused_naming_the_fmu(mini, tmp_path):
    broken = tmp_path / "Broken.fmu"
    with zipfile.ZipFile(mini["Switch"]) as source, zipfile.ZipFile(broken, "w") as target:
        for item in source.infolist():
            data = b"not a shared library" if item.filename.endswith(".so") else source.read(item)
            target.writestr(item, data)
    with pytest.raises(InputError) as failure:
        read_fmu(broken)
    message = str(failure.value)
    assert message.startswith(f"{broken}: the binary for linux64 (binaries/linux64/Switch.so) does not load")
    assert "heliostep-fmus-" not in message


# ------------------------------------------------------------------ algebraic loops
@pytest.fixture(scope="module")
def gain(tmp_path_factory):
    return read_fmu(build_mini_fmu("Gain", tmp_path_factory.mktemp("gain")))


def gain_loop(gain, k_a, b_a, k_b, b_b):
    return CoSimulation(
        {"a": gain, "b": gain},
        [Connection("a.y", "b.u"), Connection("b.y", "a.u")],
        parameters={"a": {"k": k_a, "b": b_a}, "b": {"k": k_b, "b": b_b}},
    )


def test_algebraic_loop_of_two_fmus_is_solved_to_its_closed_form(gain):
    system = gain_loop(gain, 0.5, 1.0, -3.0, 2.0)
    assert system.loops == ["a.y -> b.u -> b.y -> a.u (torn at b.u)"]
    result = system.simulate(0.0, 2.0, np.linspace(0.0, 2.0, 5))
    # u_a = k_b (k_a u_a + b_a) + b_b  =>  u_a = (k_b b_a + b_b) / (1 - k_a k_b) = -0.4
    u_a = (-3.0 * 1.0 + 2.0) / (1 - 0.5 * -3.0)
    y_a = 0.5 * u_a + 1.0
    trace = result.trace
    np.testing.assert_allclose(trace["b.y"], u_a, rtol=1e-9)
    np.testing.assert_allclose(trace["a.y"], y_a, rtol=1e-9)
    np.testing.assert_allclose(trace["a.s"], y_a * trace["time"], rtol=1e-6)  # integrals of y
    np.testing.assert_allclose(trace["b.s"], u_a * trace["time"], rtol=1e-6)
    stats = result.statistics
    assert stats["algebraic_loops"] == system.loops
    assert stats["loop_solves"] > 0 and 1 <= stats["loop_most_iterations"] <= 3


def test_algebraic_loop_without_solution_fails_clearly(gain):
    # found at the loop's first solve, at initialization before any row: bad input (exit 2)
    with pytest.raises(InputError, match=r"algebraic loop through b.u at t = 0 s: singular Jacobian"):
        gain_loop(gain, 1.0, 1.0, 1.0, 1.0).simulate(0.0, 1.0)  # u = u + 2: no solution


def test_a_singular_loop_solved_from_the_start_is_refused_not_accepted(gain):
    # issue #24: y = u fed back to u (k = 1, b = 0): r(v) = y(v) - v is 0 for every v, so Newton's first
    # residual is already 0 and the loop was accepted with 0 iterations; it has no unique solution
    system = CoSimulation({"a": gain}, [Connection("a.y", "a.u")], parameters={"a": {"k": 1.0, "b": 0.0}})
    with pytest.raises(InputError, match=r"algebraic loop through a.u at t = 0 s: singular Jacobian"):
        system.simulate(0.0, 1.0)
    # the same FMU with k = 0.5 loops on itself to the unique u = b / (1 - k)
    fine = CoSimulation({"a": gain}, [Connection("a.y", "a.u")], parameters={"a": {"k": 0.5, "b": 1.0}})
    np.testing.assert_allclose(fine.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 3)).trace["a.y"], 2.0, rtol=1e-9)


def test_algebraic_loop_through_a_discrete_connection_is_refused(infos):
    pt = infos["PassThrough"]
    with pytest.raises(InputError, match="runs through the discrete-time connection"):
        CoSimulation({"p": pt, "q": pt}, [Connection("p.y_i", "q.u_i"), Connection("q.y_i", "p.u_i")])


def test_three_fmu_loop_is_torn_at_the_connection_given_first(gain):
    # c.y -> a.u is given first: that is where the loop a -> b -> c -> a is torn
    loop = [Connection("c.y", "a.u"), Connection("a.y", "b.u"), Connection("b.y", "c.u")]
    system = CoSimulation(
        {"a": gain, "b": gain, "c": gain}, loop, parameters={name: {"k": 0.5, "b": 1.0} for name in "abc"}
    )
    assert system.torn == [loop[0]]
    assert system.loops == ["c.y -> a.u -> a.y -> b.u -> b.y -> c.u (torn at a.u)"]
    u = 1.0 * (1 + 0.5 + 0.25) / (1 - 0.125)  # u = k^3 u + b (1 + k + k^2)
    trace = system.simulate(0.0, 1.0).trace
    np.testing.assert_allclose(trace["c.y"], u, rtol=1e-9)
