"""The compiled right-hand side (heliostep.cosim.kernel) and interpolated output rows.

The compiled path must give bit-identical traces to the Python callbacks (same FMI calls in the
same order), surface FMU errors with the FMU's message and the time of the failing evaluation,
and fall back to Python for algebraic loops. Interpolated output rows (one-step mode) must stay
within the solver tolerance of rows where CVODE stops (at rtol 1e-6 the
stopped, interpolated and normal-mode rotor angles differ by up to 3e-5 rad from each other).
"""

import numpy as np
import pandas as pd
import pytest

import heliostep.cosim.master as master
from heliostep.cosim import Connection, CoSimulation, PiecewiseConstant, SimulationError, read_fmu
from heliostep.cosim.fmi import FMIError
from heliostep.cosim.kernel import kernels_dir, library_path
from heliostep.cosim.master import SolverOptions
from heliostep.drive.sequencer import Sequencer
from third_party_fmu import build_mini_fmu

DRIVE_CONNECTIONS = [
    Connection("motor.tau", "mechanics.tau"),
    Connection("mechanics.theta", "motor.theta"),
    Connection("mechanics.omega", "motor.omega"),
]
STEP_TIMES = np.array([0.05, 0.15, 0.25, 0.35, 0.45])
STEP_INDICES = np.array([0, 1, 2, 3, 2, 1])


@pytest.fixture(scope="module")
def drive(fmu_paths):
    return {"motor": read_fmu(fmu_paths["StepperMotor"]), "mechanics": read_fmu(fmu_paths["PanelMechanics"])}


@pytest.fixture(scope="module")
def mini(tmp_path_factory):
    out = tmp_path_factory.mktemp("mini-kernel")
    return {name: read_fmu(build_mini_fmu(name, out)) for name in ("PassThrough", "Switch", "Gain")}


def _inputs():
    i_a, i_b = Sequencer().reference_currents(STEP_INDICES)
    return [
        PiecewiseConstant("i_a_ref", "motor.i_a_ref", STEP_TIMES, i_a),
        PiecewiseConstant("i_b_ref", "motor.i_b_ref", STEP_TIMES, i_b),
    ]


def _run(drive, monkeypatch, compiled: bool, interpolate: bool = False, monitor=None):
    monkeypatch.setattr(master, "COMPILED_RHS", compiled)
    monkeypatch.setattr(master, "INTERPOLATE_OUTPUTS", interpolate)
    grid = np.round(np.arange(0.0, 0.6 + 1e-9, 1e-3), 12)
    return CoSimulation(drive, DRIVE_CONNECTIONS, _inputs()).simulate(
        0.0, 0.6, grid, SolverOptions(rtol=1e-6), monitor=monitor
    )


@pytest.mark.parametrize("with_monitor, interpolate", [(False, False), (True, False), (True, True)])
def test_compiled_rhs_gives_the_same_trace_bit_for_bit(drive, monkeypatch, with_monitor, interpolate):
    """The compiled kernel (right-hand side, and with a monitor the one-step loop of hs_advance)
    and the Python callbacks with their own one-step loop: the same rows, bit for bit, also
    with interpolated output rows (the two loops' twin rules for which output goes where)."""
    rows = {True: [], False: []}
    results = {}
    for compiled in (False, True):
        monitor = (lambda block, keep=rows[compiled]: keep.append(block.copy())) if with_monitor else None
        results[compiled] = _run(drive, monkeypatch, compiled, interpolate=interpolate, monitor=monitor)
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


@pytest.mark.parametrize("interpolate", [False, True])
def test_fmu_error_inside_the_compiled_rhs_keeps_its_message_and_time(mini, monkeypatch, interpolate):
    monkeypatch.setattr(master, "COMPILED_RHS", True)
    monkeypatch.setattr(master, "INTERPOLATE_OUTPUTS", interpolate)
    system = CoSimulation(
        {"pt": mini["PassThrough"], "sw": mini["Switch"]},
        [Connection("sw.x", "pt.u_c")],
        parameters={"pt": {"u_max": 0.75}},
    )
    with pytest.raises(SimulationError) as failure:
        system.simulate(0.0, 2.0, np.arange(0.0, 2.01, 0.5), monitor=(lambda row: None) if interpolate else None)
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


def test_algebraic_loops_fall_back_to_the_python_rhs(mini, monkeypatch):
    monkeypatch.setattr(master, "COMPILED_RHS", True)
    gain = mini["Gain"]
    system = CoSimulation(
        {"a": gain, "b": gain},
        [Connection("a.y", "b.u"), Connection("b.y", "a.u")],
        parameters={"a": {"k": 0.5, "b": 1.0}, "b": {"k": -3.0, "b": 2.0}},
    )
    result = system.simulate(0.0, 2.0, np.linspace(0.0, 2.0, 5))
    assert not result.statistics["compiled_rhs"] and result.statistics["loop_solves"] > 0
    np.testing.assert_allclose(result.trace["b.y"], -0.4, rtol=1e-9)


@pytest.mark.parametrize("compiled", [False, True])
def test_interpolated_output_rows_match_rows_where_the_solver_stops(drive, monkeypatch, compiled):
    monitor_rows = []
    stopped = _run(drive, monkeypatch, compiled, interpolate=False, monitor=lambda row: None)
    interpolated = _run(
        drive, monkeypatch, compiled, interpolate=True, monitor=lambda block: monitor_rows.append(block.copy())
    )
    a, b = stopped.trace, interpolated.trace
    assert len(a) == len(b)
    np.testing.assert_array_equal(a["time"].to_numpy(), b["time"].to_numpy())  # same rows, events included
    np.testing.assert_array_equal(a["i_b_ref"].to_numpy(), b["i_b_ref"].to_numpy())
    np.testing.assert_allclose(b["mechanics.theta"], a["mechanics.theta"], atol=1e-4)  # as the regression tube
    np.testing.assert_allclose(b["motor.i_a"], a["motor.i_a"], atol=2e-2)
    # CVODE stops only at the step instants and the stop time, not at the 601 output times
    assert interpolated.statistics["integrator_calls"] <= len(STEP_TIMES) + 1
    assert stopped.statistics["integrator_calls"] > 500
    assert interpolated.statistics["rhs"] < stopped.statistics["rhs"]
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
    monkeypatch.setattr(master, "COMPILED_RHS", compiled)
    monkeypatch.setattr(master, "INTERPOLATE_OUTPUTS", True)
    seen = []
    system = CoSimulation(drive, DRIVE_CONNECTIONS, _inputs())
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
