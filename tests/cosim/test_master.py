"""heliostep.cosim.master: connected Model Exchange FMUs against the monolithic FMU, events, errors."""

import numpy as np
import pandas as pd
import pytest
from fmpy import simulate_fmu

from drive_system import DRIVE_CONNECTIONS, STEP_INDICES, STEP_TIMES, current_inputs
from heliostep.cosim.fmi import read_fmu
from heliostep.cosim.master import (
    Connection,
    CoSimulation,
    PiecewiseConstant,
    SimulationError,
    SolverOptions,
)
from heliostep.drive.sequencer import Sequencer
from heliostep.errors import InputError


def _fmpy_input(stop_time):
    i_a, i_b = Sequencer().reference_currents(STEP_INDICES)
    edges = [0.0, *STEP_TIMES, stop_time]
    rows = []
    for k in range(len(STEP_INDICES)):
        rows += [(edges[k], i_a[k], i_b[k], 0.0), (edges[k + 1], i_a[k], i_b[k], 0.0)]
    return np.array(rows, dtype=[("time", float), ("i_a_ref", float), ("i_b_ref", float), ("m_ext", float)])


def _last_per_time(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.drop_duplicates("time", keep="last").set_index("time")


def test_cosimulation_equals_monolithic_drive_system(drive, fmu_paths):
    stop, grid = 0.6, np.round(np.arange(0, 0.6 + 1e-9, 1e-3), 12)
    result = CoSimulation(drive, DRIVE_CONNECTIONS, current_inputs()).simulate(
        0.0, stop, grid, SolverOptions(rtol=1e-8)
    )
    mono = simulate_fmu(
        str(fmu_paths["DriveSystem"]),
        fmi_type="ModelExchange",
        solver="CVode",
        stop_time=stop,
        output_interval=1e-3,
        input=_fmpy_input(stop),
        relative_tolerance=1e-8,
        output=["motor.tau", "motor.i_a", "motor.i_b", "mechanics.theta", "mechanics.theta_p"],
    )
    ours, theirs = _last_per_time(result.trace), _last_per_time(pd.DataFrame(mono))
    common = ours.index.intersection(np.round(theirs.index, 12))
    assert len(common) > 550
    theirs.index = np.round(theirs.index, 12)
    for column, tolerance in (
        ("motor.tau", 1e-4),
        ("motor.i_a", 1e-4),
        ("motor.i_b", 1e-4),
        ("mechanics.theta", 1e-6),
        ("mechanics.theta_p", 1e-8),
    ):
        difference = np.abs(ours.loc[common, column].to_numpy() - theirs.loc[common, column].to_numpy())
        assert difference.max() < tolerance, column
    # first principles: net one step forward (3 up, 2 down) from 0
    assert result.trace["mechanics.theta"].iloc[-1] == pytest.approx(np.pi / 100, abs=1e-4)


def test_steps_get_rows_just_before_and_just_after(drive):
    result = CoSimulation(drive, DRIVE_CONNECTIONS, current_inputs()).simulate(0.0, 0.3, np.array([0.0, 0.3]))
    trace = result.trace
    for t, (before, after) in zip(STEP_TIMES[:2], [(0, 1), (1, 2)]):
        rows = trace[trace["time"] == t]
        assert len(rows) == 2
        i_a, i_b = Sequencer().reference_currents(np.array([before, after]))
        assert rows["i_b_ref"].tolist() == pytest.approx(list(i_b))
        # the states are continuous across the event
        assert rows["mechanics.theta"].iloc[0] == rows["mechanics.theta"].iloc[1]
    assert result.statistics["events"] == 3  # steps at 0.05, 0.15 and 0.25 s


def test_propagation_follows_direct_feedthrough(drive):
    system = CoSimulation(drive, list(reversed(DRIVE_CONNECTIONS)), current_inputs())
    order = [(c.source, c.target) for c in system.order]
    # motor.tau depends directly on motor.theta, so theta must be passed on before tau is read
    assert order.index(("mechanics.theta", "motor.theta")) < order.index(("motor.tau", "mechanics.tau"))


@pytest.mark.parametrize(
    "connection, message",
    [
        (Connection("motor.torque", "mechanics.tau"), "StepperMotor.fmu has no variable 'torque'; its outputs: i_a"),
        (Connection("gearbox.tau", "mechanics.tau"), "no FMU instance 'gearbox'"),
        (Connection("motor.tau", "mechanics.theta"), "expected an input, it is a Real output"),
        (Connection("motor.power", "mechanics.tau"), r"units differ \('W' vs 'N.m'\)"),
        (Connection("tau", "mechanics.tau"), "expected 'instance.variable'"),
    ],
)
def test_bad_connections_are_named(drive, connection, message):
    with pytest.raises(InputError, match=message):
        CoSimulation(drive, [connection])


def test_input_driven_twice_is_an_error(drive):
    with pytest.raises(InputError, match="mechanics.tau is driven twice"):
        CoSimulation(drive, DRIVE_CONNECTIONS + [Connection("motor.power", "mechanics.tau")])


def test_solver_failure_keeps_the_trace_so_far(drive, capfd):
    # the motor is idle until 0.05 s, when the current is switched on
    switch_on = [PiecewiseConstant("i_a_ref", "motor.i_a_ref", np.array([0.05]), np.array([0.0, 5.5]))]
    system = CoSimulation(drive, DRIVE_CONNECTIONS, switch_on)
    with pytest.raises(SimulationError) as failure:
        # the current's rise needs far more than 5 internal steps: CVODE gives up there
        system.simulate(0.0, 0.6, np.round(np.arange(0, 0.6, 0.01), 12), SolverOptions(max_num_steps=5))
    error = failure.value
    assert "simulation failed at t = 0.05" in str(error)
    assert len(error.trace) >= 6 and error.trace["time"].max() == pytest.approx(0.05)
    assert error.statistics["rhs"] > 0
    # CVODE's own message is in the error, once; SUNDIALS' default handler printed it to stderr as well
    # ("[ERROR][rank 0]...") before the master's handler became the only one
    assert "mxstep steps taken" in str(error)
    assert "[ERROR]" not in capfd.readouterr().err


def test_an_input_change_a_rounding_error_after_an_output_time_takes_effect(drive):
    """A change at 0.05 + 1 ulp with an output row at 0.05 (found by the speed-torque bench: the
    change was consumed at 0.05 with the value from before it, and never applied)."""
    change = np.nextafter(0.05, 1.0)
    switch_on = [PiecewiseConstant("i_a_ref", "motor.i_a_ref", np.array([change]), np.array([0.0, 5.5]))]
    system = CoSimulation(drive, DRIVE_CONNECTIONS, switch_on)
    trace = system.simulate(0.0, 0.1, np.round(np.arange(0, 0.1, 0.01), 12)).trace
    last = trace.iloc[-1]
    assert last["i_a_ref"] == 5.5
    # the loop holds K i_ref / (K + R) of it ([paper] eq. 7 at rest, the averaged chopper: docs/physics.md)
    assert last["motor.i_a"] == pytest.approx(100.0 * 5.5 / (100.0 + 0.1), rel=1e-4)


def test_unknown_parameter_instance_is_named(drive):
    with pytest.raises(InputError, match="unknown FMU instance"):
        CoSimulation(drive, DRIVE_CONNECTIONS, parameters={"motr": {"L": 1e-3}})


def test_unknown_parameter_name_found_setting_up_the_fmus_is_an_input_error(drive):
    """Found while instantiating, before any row: bad input, raised as it is (not a SimulationError)."""
    system = CoSimulation(drive, DRIVE_CONNECTIONS, parameters={"motor": {"Rxx": 3.0}})
    with pytest.raises(InputError, match="has no parameter 'Rxx'") as failure:
        system.simulate(0.0, 0.1)
    assert not isinstance(failure.value, SimulationError)


def test_failures_while_simulating_are_run_failures_and_input_errors_are_not():
    from heliostep.cosim import FMIError, LoopError
    from heliostep.cosim.kernel import KernelBuildError
    from heliostep.errors import RunFailure

    for error in (SimulationError, FMIError, LoopError, KernelBuildError):
        assert issubclass(error, RunFailure) and not issubclass(error, InputError), error
    assert not issubclass(InputError, RunFailure)


def test_third_party_fmu_with_events_matches_fmpy(tmp_path):
    from third_party_fmu import build_bouncing_ball

    path = build_bouncing_ball(tmp_path)
    stop = 2.0
    grid = np.round(np.arange(0.0, stop + 1e-9, 1e-3), 12)
    result = CoSimulation({"ball": read_fmu(path)}).simulate(0.0, stop, grid, SolverOptions(rtol=1e-8))
    reference = pd.DataFrame(
        simulate_fmu(
            str(path),
            fmi_type="ModelExchange",
            solver="CVode",
            stop_time=stop,
            output_interval=1e-3,
            relative_tolerance=1e-8,
            output=["height", "bounce_count"],
        )
    )
    ours, theirs = _last_per_time(result.trace), _last_per_time(reference)
    theirs.index = np.round(theirs.index, 12)
    common = ours.index.intersection(theirs.index)
    assert len(common) > 1900
    # state events (bounces) and the time event (the kick at t_kick = 0.5 s) happened in both
    assert ours["ball.bounce_count"].iloc[-1] == theirs["bounce_count"].iloc[-1] == 2
    assert result.statistics["state_events"] >= 2 and result.statistics["time_events"] == 1
    np.testing.assert_allclose(ours.loc[common, "ball.height"], theirs.loc[common, "height"], atol=1e-5)
    # first principles: the first impact is at sqrt(2 h0 / g)
    first_bounce = result.trace.loc[result.trace["ball.bounce_count"] >= 1, "time"].iloc[0]
    assert first_bounce == pytest.approx(np.sqrt(2 * 1.0 / 9.81), abs=1e-6)
