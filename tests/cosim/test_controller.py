"""heliostep.cosim.controller: a controller sampled while simulating, its steps decided from the FMUs' outputs.

Checked against first principles (a rotor stepped to a target stops within half a step of it, having taken
exactly the steps the distance asks) and against the same changes given before the simulation (the trace bit
for bit, in the compiled kernel's events and in Python's)."""

from __future__ import annotations

import numpy as np
import pytest

from drive_system import DRIVE_CONNECTIONS
from heliostep.cosim.controller import ScheduledInput
from heliostep.cosim.master import CoSimulation, PiecewiseConstant, SolverOptions
from heliostep.drive.sequencer import Sequencer
from heliostep.errors import InputError

SEQUENCER = Sequencer()
TARGET_STEPS = 5
SAMPLE = 0.02  # [s]
LATENCY = 0.005  # [s] from the sample to the step it commands
DETAIL = np.array([0.0, 0.001, 0.0025])  # [s] after each step it commands, the output rows it asks for


class StepToTarget:
    """Reads the rotor's angle every SAMPLE; while it is more than half a step from the target, one step
    towards it, LATENCY after the sample."""

    reads = ("mechanics.theta",)
    sets = ()

    def __init__(self, stop: float):
        self.sample_times = np.arange(1, int(round(stop / SAMPLE)) + 1) * SAMPLE
        i_a, i_b = SEQUENCER.reference_currents(0)
        self.inputs = (
            ScheduledInput("i_a_ref", "motor.i_a_ref", float(i_a), capacity=2),  # grows while simulating
            ScheduledInput("i_b_ref", "motor.i_b_ref", float(i_b), capacity=2),
        )
        self.index, self.samples, self.decided = 0, [], 0
        self.target = SEQUENCER.position(TARGET_STEPS)

    def setting(self, time: float) -> np.ndarray:
        return np.zeros(0)

    def sample(self, time: float, readings: np.ndarray) -> None:
        self.samples.append((time, float(readings[0])))
        self.decided = len(self.inputs[0].times)
        error = self.target - readings[0]
        if abs(error) > 0.5 * SEQUENCER.increment:
            self.index += int(np.sign(error))
            i_a, i_b = SEQUENCER.reference_currents(self.index)
            for item, value in zip(self.inputs, (i_a, i_b)):
                item.append(time + LATENCY, float(value))

    def outputs_after(self, time: float) -> np.ndarray:
        return (self.inputs[0].times[self.decided :, None] + DETAIL[None, :]).ravel()


def _closed_loop(drive, stop=0.5, **simulate):
    controller = StepToTarget(stop)
    system = CoSimulation(drive, DRIVE_CONNECTIONS, controller=controller)
    return controller, system.simulate(0.0, stop, **simulate)


def test_a_rotor_stepped_to_its_target_stops_within_half_a_step_having_taken_the_steps_it_needs(drive):
    controller, result = _closed_loop(drive, output_times=np.linspace(0.0, 0.5, 501))
    assert controller.index == TARGET_STEPS  # no step more or less than the distance asks
    theta = result.trace["mechanics.theta"].to_numpy()
    assert abs(theta[-1] - controller.target) < 0.5 * SEQUENCER.increment
    # each step LATENCY after a sample that found the rotor more than half a step short
    steps = controller.inputs[0].times
    assert len(steps) == TARGET_STEPS and np.all(
        np.isin(np.round(steps - LATENCY, 9), np.round(SAMPLE * np.arange(1, 26), 9))
    )
    assert [round(t, 9) for t, _ in controller.samples] == [round(t, 9) for t in controller.sample_times]
    # the output rows it asked for after each step, at their instants
    times = result.trace["time"].to_numpy()
    wanted = (steps[:, None] + DETAIL[None, :]).ravel()
    assert np.abs(times[np.searchsorted(times, wanted - 1e-12)] - wanted).max() < 1e-12
    # the trace carries the commanded currents at their instants
    rows = result.trace.drop_duplicates("time", keep="last").set_index("time")
    i_a, _ = SEQUENCER.reference_currents(TARGET_STEPS)
    assert rows["i_a_ref"].iloc[-1] == pytest.approx(float(i_a))


@pytest.mark.parametrize("rtol", [1e-6, 1e-8])
def test_the_same_changes_given_before_the_simulation_give_the_same_trace_bit_for_bit(drive, rtol):
    grid = np.union1d(np.linspace(0.0, 0.5, 101), StepToTarget(0.5).sample_times)  # the samples' stops, as outputs
    options = SolverOptions(rtol=rtol)
    controller, closed = _closed_loop(drive, output_times=grid, solver=options)
    given = [PiecewiseConstant(i.name, i.target, i.times.copy(), i.values.copy()) for i in controller.inputs]
    grid = np.union1d(grid, (controller.inputs[0].times[:, None] + DETAIL[None, :]).ravel())  # the rows it asked for
    replay = CoSimulation(drive, DRIVE_CONNECTIONS, given).simulate(0.0, 0.5, grid, options)
    assert closed.statistics["compiled_events"] > 0  # the appended changes went through the compiled kernel
    assert closed.trace.columns.tolist() == replay.trace.columns.tolist()
    np.testing.assert_array_equal(closed.trace.to_numpy(), replay.trace.to_numpy())


def test_a_controller_reading_or_giving_what_it_cannot_is_refused_before_simulating(drive):
    controller = StepToTarget(0.1)
    controller.reads = ("mechanics.tau",)  # an input
    with pytest.raises(InputError, match="controller reading 'mechanics.tau'"):
        CoSimulation(drive, DRIVE_CONNECTIONS, controller=controller)
    controller = StepToTarget(0.1)
    controller.sets = ("mechanics.m_ext",)  # a change the mechanics' derivatives would see between events
    with pytest.raises(InputError, match="must have no continuous state"):
        CoSimulation(drive, DRIVE_CONNECTIONS, controller=controller)


def test_a_change_appended_before_its_sample_is_an_error(drive):
    controller = StepToTarget(0.1)

    def sample(time, readings):
        for item in controller.inputs:
            item.append(time - 0.01, 0.0)

    controller.sample = sample  # type: ignore[method-assign]
    with pytest.raises(Exception, match="appended a change before that instant"):
        CoSimulation(drive, DRIVE_CONNECTIONS, controller=controller).simulate(0.0, 0.1)
