"""The compiled right-hand side (heliostep.cosim.kernel) and interpolated output rows.

The compiled path must give bit-identical traces to the Python callbacks (same FMI calls in the
same order), surface FMU errors with the FMU's message and the time of the failing evaluation,
and solve algebraic loops in C as the Python path does. Interpolated output rows (one-step mode, with a
monitor) must stay within the solver tolerance of the rows of CVODE's normal mode (no monitor).
"""

import numpy as np
import pandas as pd
import pytest

import heliostep.cosim.integrator as integrator
from drive_system import DRIVE_CONNECTIONS, STEP_TIMES, current_inputs
from heliostep.cosim import Connection, CoSimulation, SimulationError, read_fmu
from heliostep.cosim.fmi import FMIError
from heliostep.cosim.integrator import compiled_kernel
from heliostep.cosim.kernel import kernels_dir, library_path
from heliostep.cosim.master import SolverOptions
from heliostep.errors import InputError
from third_party_fmu import build_mini_fmu


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    out = tmp_path_factory.mktemp("mini-kernel")
    return {name: read_fmu(build_mini_fmu(name, out)) for name in ("PassThrough", "Switch", "Gain", "Lag")}


def _run(drive, monkeypatch, compiled: bool, monitor=None):
    monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
    grid = np.round(np.arange(0.0, 0.6 + 1e-9, 1e-3), 12)
    return CoSimulation(drive, DRIVE_CONNECTIONS, current_inputs()).simulate(
        0.0, 0.6, grid, SolverOptions(rtol=1e-6), monitor=monitor
    )


@pytest.mark.parametrize("with_monitor", [False, True])
def test_compiled_rhs_gives_the_same_trace_bit_for_bit(drive, monkeypatch, with_monitor):
    """The compiled kernel (right-hand side, and with a monitor the one-step loop of hs_advance)
    and the Python callbacks with the kernel's one-step loop: the same rows, bit for bit, also
    with interpolated output rows."""
    rows = {True: [], False: []}
    results = {}
    for compiled in (False, True):
        monitor = (lambda block, keep=rows[compiled]: keep.append(block.copy())) if with_monitor else None
        results[compiled] = _run(drive, monkeypatch, compiled, monitor=monitor)
    assert results[True].statistics["compiled_rhs"] and not results[False].statistics["compiled_rhs"]
    pd.testing.assert_frame_equal(results[True].trace, results[False].trace, check_exact=True)
    assert results[True].statistics["rhs"] == results[False].statistics["rhs"] > 0
    if with_monitor:  # the monitor is shown blocks of rows (copied here: views valid during the call)
        seen = {compiled: np.vstack(blocks) for compiled, blocks in rows.items()}
        assert len(seen[True]) == len(seen[False]) > len(results[True].trace)
        np.testing.assert_array_equal(seen[True], seen[False])


def test_kernel_is_compiled_once_into_the_cache_by_content():
    path = library_path()
    assert path.parent == kernels_dir() and path.exists()
    stamp = path.stat().st_mtime_ns
    assert library_path() == path and path.stat().st_mtime_ns == stamp  # reused, not rebuilt


@pytest.mark.parametrize("monitored", [False, True])
def test_fmu_error_inside_the_compiled_rhs_keeps_its_message_and_time(mini, monkeypatch, monitored):
    system = CoSimulation(
        {"pt": mini["PassThrough"], "sw": mini["Switch"]},
        [Connection("sw.x", "pt.u_c")],
        parameters={"pt": {"u_max": 0.75}},
    )
    with pytest.raises(SimulationError) as failure:
        system.simulate(0.0, 2.0, np.arange(0.0, 2.01, 0.5), monitor=(lambda row: None) if monitored else None)
    error = failure.value
    cause = error.__cause__
    assert error.statistics["compiled_rhs"]
    assert isinstance(cause, FMIError) and cause.instance == "pt" and cause.function == "fmi2GetDerivatives"
    assert cause.status == "fmi2Error"
    # u_c = x = t before the switch at 1 s: the failing evaluation is past 0.75 s
    assert 0.75 < error.time < 1.5 and cause.time == pytest.approx(error.time)
    assert f"u_c = {error.time:.6f} exceeds u_max = 0.75" in str(error)
    assert f"simulation failed at t = {error.time:.9g} s" in str(error)
    assert error.trace["time"].max() == pytest.approx(0.5)


def test_an_algebraic_loop_of_two_gains_is_solved_in_the_compiled_kernel(mini, monkeypatch):
    gain = mini["Gain"]
    system = CoSimulation(
        {"a": gain, "b": gain},
        [Connection("a.y", "b.u"), Connection("b.y", "a.u")],
        parameters={"a": {"k": 0.5, "b": 1.0}, "b": {"k": -3.0, "b": 2.0}},
    )
    result = system.simulate(0.0, 2.0, np.linspace(0.0, 2.0, 5))
    stats = result.statistics
    assert stats["compiled_rhs"] and stats["loop_solves_compiled"] > 0 and stats["loop_solves"] > 0
    np.testing.assert_allclose(result.trace["b.y"], -0.4, rtol=1e-9)  # (k_b b_a + b_b) / (1 - k_a k_b)


def _lag_loop(mini, compiled: bool, monkeypatch, k: float = 0.5, b: float = 1.0):
    """A Lag (T dy/dt = e, e = u - y) and a Gain (y = k u + b) in a loop: lag.e -> g.u, g.y -> lag.u."""
    monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
    system = CoSimulation(
        {"lag": mini["Lag"], "g": mini["Gain"]},
        [Connection("lag.e", "g.u"), Connection("g.y", "lag.u")],
        parameters={"lag": {"T": 0.5}, "g": {"k": k, "b": b}},
    )
    return system.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 11), SolverOptions(rtol=1e-8))


def test_the_compiled_loop_matches_the_python_loop_and_the_closed_form(mini, monkeypatch):
    """A loop whose solution moves with a state, so every evaluation takes Newton iterations: in C
    (the compiled kernel) and in Python (the callbacks' path) the same Newton, the same
    number of evaluations, the same trace bit for bit (one torn input; with several, the linear
    solves, Gaussian elimination in C and LAPACK in Python, may differ by rounding), both on the
    closed form.

    u = k (u - y) + b  =>  u = (b - k y) / (1 - k) = 2 - y, e = 2 - 2 y, so T dy/dt = 2 - 2 y and
    y(t) = 1 - exp(-2 t / T) = 1 - exp(-4 t); the Gain's integral s has ds/dt = u = 2 - y:
    s(t) = t + (1 - exp(-4 t)) / 4.
    """
    import time as clock

    runs, seconds = {}, {}
    for compiled in (True, False):
        began = clock.perf_counter()
        runs[compiled] = _lag_loop(mini, compiled, monkeypatch)
        seconds[compiled] = clock.perf_counter() - began
    c, p = runs[True].statistics, runs[False].statistics
    assert c["compiled_rhs"] and not p["compiled_rhs"] and p["loop_solves_compiled"] == 0
    assert c["loop_solves_compiled"] == c["rhs"] > 0  # one solve in C per right-hand side (no roots, no monitor)
    assert c["rhs"] == p["rhs"] and c["loop_solves"] == p["loop_solves"]
    assert c["loop_iterations"] == p["loop_iterations"] > c["loop_solves"] / 2  # it moves: Newton works
    assert c["loop_most_iterations"] == p["loop_most_iterations"] <= 2  # a linear loop: one step, to rounding
    print(f"loop, 1 s: compiled {seconds[True]:.3f} s, Python {seconds[False]:.3f} s, {c['rhs']} RHS each")
    # one torn input: the same arithmetic in C and Python (the 1x1 solve is one division), bit for bit
    pd.testing.assert_frame_equal(runs[True].trace, runs[False].trace, check_exact=True)
    t = runs[True].trace["time"].to_numpy()
    np.testing.assert_allclose(runs[True].trace["lag.y"], 1 - np.exp(-4 * t), rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(runs[True].trace["g.s"], t + (1 - np.exp(-4 * t)) / 4, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(runs[True].trace["g.y"], 2 - (1 - np.exp(-4 * t)), rtol=1e-6)


def test_a_loop_beside_the_drive_costs_the_same_evaluations_compiled_as_in_python(drive, mini, monkeypatch):
    """The drive with an extra Lag-Gain loop (benchmarks/bench_loops.py's system, 0.6 s): compiled,
    the drive's connections are copied once per solve and only the loop's in each Newton evaluation;
    the same RHS count and Newton iterations as the Python path, the same trace bit for bit (the
    drive's connections copied again carry the same values), the loop on its closed form
    y = 1 - exp(-4 t). Times printed, not asserted."""
    import time as clock

    fmus = {**drive, "lag": mini["Lag"], "g": mini["Gain"]}
    connections = DRIVE_CONNECTIONS + [Connection("lag.e", "g.u"), Connection("g.y", "lag.u")]
    grid = np.round(np.arange(0.0, 0.6 + 1e-9, 1e-3), 12)
    runs, seconds = {}, {}
    for compiled in (True, False):
        monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
        system = CoSimulation(
            fmus, connections, current_inputs(), parameters={"lag": {"T": 0.5}, "g": {"k": 0.5, "b": 1.0}}
        )
        began = clock.perf_counter()
        runs[compiled] = system.simulate(0.0, 0.6, grid, SolverOptions(rtol=1e-6), monitor=lambda rows: None)
        seconds[compiled] = clock.perf_counter() - began
    c, p = runs[True].statistics, runs[False].statistics
    print(f"drive + loop, 0.6 s: compiled {seconds[True]:.3f} s, Python {seconds[False]:.3f} s, {c['rhs']} RHS each")
    assert c["compiled_rhs"] and not p["compiled_rhs"]
    assert c["rhs"] == p["rhs"] > 0 and c["loop_iterations"] == p["loop_iterations"] > 0
    pd.testing.assert_frame_equal(runs[True].trace, runs[False].trace, check_exact=True)  # one torn input
    t = runs[True].trace["time"].to_numpy()
    np.testing.assert_allclose(runs[True].trace["lag.y"], 1 - np.exp(-4 * t), rtol=1e-4, atol=1e-6)


def test_two_loops_are_solved_together_in_c_as_in_python(mini, monkeypatch):
    """Two Lag-Gain loops: two torn inputs, one Newton on both (a 2 x 2 Jacobian, Gaussian elimination
    in C, LAPACK in Python: the same trace to rounding, 1e-12 relative). Each on its closed form:
    u = k (u - y) + b gives T dy/dt = (b - y) / (1 - k), y = b (1 - exp(-t / (T (1 - k))))."""
    fmus = {"lag1": mini["Lag"], "g1": mini["Gain"], "lag2": mini["Lag"], "g2": mini["Gain"]}
    connections = [
        Connection(f"{a}.{o}", f"{b}.{i}")
        for a, o, b, i in (
            ("lag1", "e", "g1", "u"),
            ("g1", "y", "lag1", "u"),
            ("lag2", "e", "g2", "u"),
            ("g2", "y", "lag2", "u"),
        )
    ]
    parameters = {"lag1": {"T": 0.5}, "g1": {"k": 0.5, "b": 1.0}, "lag2": {"T": 0.5}, "g2": {"k": -1.0, "b": 2.0}}
    runs = {}
    for compiled in (True, False):
        monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
        system = CoSimulation(fmus, connections, parameters=parameters)
        runs[compiled] = system.simulate(0.0, 1.0, np.linspace(0.0, 1.0, 11), SolverOptions(rtol=1e-8))
    c, p = runs[True].statistics, runs[False].statistics
    assert c["compiled_rhs"] and c["loop_solves_compiled"] == c["rhs"] > 0 and c["rhs"] == p["rhs"]
    assert c["loop_iterations"] == p["loop_iterations"] > 0
    for column in ("lag1.y", "lag2.y", "g1.s", "g2.s"):
        np.testing.assert_allclose(runs[True].trace[column], runs[False].trace[column], rtol=1e-12, atol=1e-15)
    t = runs[True].trace["time"].to_numpy()
    np.testing.assert_allclose(runs[True].trace["lag1.y"], 1 - np.exp(-4 * t), rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(runs[True].trace["lag2.y"], 2 * (1 - np.exp(-t)), rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_singular_loop_is_refused_naming_it_on_either_path(mini, monkeypatch, compiled):
    # k = 1: u = (u - y) + 1 has no solution for any y (dr/dv = 0): the loop is refused, named, as bad
    # input (its first solve, at initialization, comes before the compiled kernel runs)
    with pytest.raises(InputError, match=r"algebraic loop through g.u at t = 0 s: singular Jacobian"):
        _lag_loop(mini, compiled, monkeypatch, k=1.0)


@pytest.mark.parametrize("compiled", [False, True])
def test_interpolated_output_rows_match_the_normal_modes_rows(drive, monkeypatch, compiled):
    monitor_rows = []
    stopped = _run(drive, monkeypatch, compiled)  # no monitor: CVODE's normal mode, called at every output time
    interpolated = _run(drive, monkeypatch, compiled, monitor=lambda block: monitor_rows.append(block.copy()))
    a, b = stopped.trace, interpolated.trace
    assert len(a) == len(b)
    np.testing.assert_array_equal(a["time"].to_numpy(), b["time"].to_numpy())  # same rows, events included
    np.testing.assert_array_equal(a["i_b_ref"].to_numpy(), b["i_b_ref"].to_numpy())
    np.testing.assert_allclose(b["mechanics.theta"], a["mechanics.theta"], atol=1e-4)  # as the regression tube
    np.testing.assert_allclose(b["motor.i_a"], a["motor.i_a"], atol=2e-2)
    # CVODE stops only at the step instants and the stop time, not at the 601 output times
    assert interpolated.statistics["integrator_calls"] <= len(STEP_TIMES) + 1
    assert stopped.statistics["integrator_calls"] > 500
    # the monitor saw every trace row, in time order
    times = np.vstack(monitor_rows)[:, 0]
    assert np.all(np.diff(times) >= 0) and set(np.round(b["time"], 12)) <= set(np.round(times, 12))


@pytest.mark.parametrize("compiled", [False, True])
def test_an_output_time_a_rounding_error_before_an_internal_step_is_recorded(drive, monkeypatch, compiled):
    """CVODE interpolates only over its last step: an output time that falls within rounding
    (1e-12 relative) before an internal step must be taken after that step, not after the next
    one (CVodeGetDky refuses it there; seen in a sweep at t = 2995.6497259287 s, 1.8e-12 s before
    a step). With interpolated outputs the internal steps do not depend on the grid, so a first
    run tells where they are."""
    monkeypatch.setattr(integrator, "compiled_kernel", compiled_kernel if compiled else (lambda *args: None))
    seen = []
    system = CoSimulation(drive, DRIVE_CONNECTIONS, current_inputs())
    system.simulate(
        0.0, 0.6, np.array([0.0, 0.6]), SolverOptions(rtol=1e-6), monitor=lambda block: seen.append(block[:, 0].copy())
    )
    times = np.concatenate(seen)
    step = float(times[(times > 0.35) & (times < 0.55)][0])  # an internal step between the inputs' changes
    output = step - 0.5e-12
    assert output < step
    result = system.simulate(
        0.0, 0.6, np.array([0.0, output, 0.6]), SolverOptions(rtol=1e-6), monitor=lambda block: None
    )
    assert output in set(result.trace["time"])
