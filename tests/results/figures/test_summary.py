"""heliostep.results.figures.summary: the run's figures from a trace built by hand, with known answers."""

import numpy as np
import pandas as pd
import pytest

from figures_oracle import figures
from heliostep.results.figures.summary import summarize
from heliostep.scenario import RolesConfig

STEP = np.pi / 100


def _inputs(step_times, indices):
    """A run's metadata as written to metadata.json: the roles and the drive record (no DriveInputs)."""
    drive = {
        "mode": "one-phase-on",
        "current": 5.5,
        "step_angle": STEP,
        "initial_index": 0,
        "step_times": list(step_times),
        "step_indices": list(indices),
    }
    return {"roles": RolesConfig().present(), "drive": drive}


def _trace(time, rotor, command, error=None, tau=None, power=None):
    n = len(time)
    return pd.DataFrame(
        {
            "time": time,
            "mechanics.theta": rotor,
            "rotor_angle_cmd": command,
            "panel_angle_error": np.zeros(n) if error is None else error,
            "motor.tau": np.zeros(n) if tau is None else tau,
            "motor.i_a": np.full(n, 5.5),
            "motor.i_b": np.zeros(n),
            "motor.power": np.zeros(n) if power is None else power,
            "mechanics.theta_p": np.zeros(n),
        }
    )


def test_settling_time_and_executed_steps():
    # step at 1 s; the rotor reaches the new position (within 5 % of a step) at 1.2 s
    time = np.array([0.0, 1.0, 1.0, 1.1, 1.2, 2.0, 3.0])
    rotor = np.array([0.0, 0.0, 0.0, 0.5 * STEP, 0.99 * STEP, STEP, STEP])
    command = np.array([0.0, 0.0, STEP, STEP, STEP, STEP, STEP])
    summary = summarize(_trace(time, rotor, command), _inputs([1.0], [1]))
    assert summary["steps_commanded"] == 1 and summary["steps_executed"] == 1 and summary["missed_steps"] == 0
    # the band (5 % of a step) is crossed between 1.1 s (0.45 step outside) and 1.2 s (0.04 inside)
    assert summary["settling_time_s"]["per_step"] == [pytest.approx(0.1 + 0.1 * 0.45 / 0.49)]
    assert summary["steps_lost"] == 0


def test_step_not_reached_by_the_next_step_is_missed():
    # two steps commanded, the rotor never moves: the first is missed at 2 s, the second at the end
    time = np.array([0.0, 1.0, 1.0, 2.0, 2.0, 3.0])
    rotor = np.zeros(6)
    command = np.array([0, 0, STEP, STEP, 2 * STEP, 2 * STEP])
    summary = summarize(_trace(time, rotor, command), _inputs([1.0, 2.0], [1, 2]))
    assert summary["missed_steps"] == 2 and summary["steps_executed"] == 0
    assert summary["missed_step_times_s"] == [1.0, 2.0]
    assert summary["settling_time_s"]["not_settled"] == 2
    assert summary["steps_lost"] == 2


def test_error_energy_and_peaks():
    time = np.linspace(0.0, 3.0, 301)
    error = np.radians(0.01) * np.sin(2 * np.pi * time)  # RMS of a sine over whole periods: amplitude/sqrt(2)
    summary = summarize(
        _trace(time, np.zeros(301), np.zeros(301), error=error, tau=-0.6 * np.sin(time), power=np.full(301, 3.0)),
        _inputs([], []),
    )
    assert summary["max_tracking_error_deg"] == pytest.approx(0.01, rel=1e-3)
    assert summary["rms_tracking_error_deg"] == pytest.approx(0.01 / np.sqrt(2), rel=1e-3)
    assert summary["peak_torque_Nm"] == pytest.approx(0.6)
    assert summary["electrical_energy_J"] == pytest.approx(9.0)  # 3 W for 3 s
    assert summary["peak_phase_current_A"] == 5.5


def test_slip_loses_whole_periods_and_later_full_steps_are_not_missed():
    # three steps; at the first the rotor slips back one electrical period (moves 1 - 4 = -3
    # steps), the next two move it by one step each: one step missed, 4 steps lost
    time = np.array([0.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.5, 3.0, 3.0, 3.5, 4.0])
    rotor = np.array([0, 0, 0, -3, -3, -3, -2, -2, -2, -1, -1]) * STEP
    command = np.array([0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3]) * STEP
    summary = summarize(_trace(time, rotor, command), _inputs([1.0, 2.0, 3.0], [1, 2, 3]))
    assert summary["missed_steps"] == 1 and summary["missed_step_times_s"] == [1.0]
    assert summary["steps_executed"] == 2
    assert summary["steps_lost"] == 4


def test_lost_steps_are_net_of_the_elastic_lag_held_from_the_start():
    # a loaded rotor lags 0.7 step from the start; it slips one period at the step: 4 lost, not 5
    lag = 0.7 * STEP
    time = np.array([0.0, 1.0, 1.0, 2.0])
    rotor = np.array([-lag, -lag, -lag, -3 * STEP - lag])
    command = np.array([0.0, 0.0, STEP, STEP])
    summary = summarize(_trace(time, rotor, command), _inputs([1.0], [1]))
    assert summary["steps_lost"] == 4
    assert summary["final_lag_steps"] == pytest.approx(0.7)


def _streamed(trace, metadata, block):
    """The SolutionRecorder's figures of the rows of ``trace`` (reference: the trace's own)."""
    from heliostep.results.figures.summary import SolutionRecorder
    from heliostep.results.trace.frame import drive_from_metadata

    sequencer, schedule = drive_from_metadata(metadata["drive"])
    columns = ["time", "mechanics.theta", "motor.tau", "motor.i_a", "motor.i_b", "motor.power", "mechanics.theta_p"]
    error = trace.set_index("time")["panel_angle_error"]

    def reference(t):  # the panel is at 0
        return -np.interp(t, error.index.to_numpy(), error.to_numpy())

    recorder = SolutionRecorder(columns, metadata["roles"], sequencer, schedule, reference, block=block)
    for row in trace[columns].to_numpy():
        recorder(row)
    return recorder.figures()


@pytest.mark.parametrize("block", [1, 2, 3, 100])
def test_streamed_figures_of_a_slip_a_late_step_and_a_step_at_the_end(block):
    # a slip at 1 s (-3 steps), a full step at 2 s that settles at 2.4 s, a step at 3 s the rotor
    # has not made when the run ends at 3.5 s, and a step commanded after the end
    time = np.array([0.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.2, 2.4, 3.0, 3.0, 3.5])
    rotor = np.array([0, 0, 0, -3, -3, -3, -2.5, -2.02, -2, -2, -2]) * STEP
    command = np.array([0, 0, 1, 1, 1, 2, 2, 2, 2, 3, 3]) * STEP
    error = np.radians(0.01) * np.sin(time)
    power = 3.0 + time
    tau = np.array([0, 0, 0.5, -0.7, 0, 0.2, 0.1, 0, 0, 0.3, 0])
    trace = _trace(time, rotor, command, error=error, tau=tau, power=power)
    metadata = _inputs([1.0, 2.0, 3.0, 9.0], [1, 2, 3, 4])
    streamed = _streamed(trace, metadata, block)
    assert [o["move_steps"] for o in streamed["step_outcomes"]] == pytest.approx([-3.0, 1.0, 0.0])
    assert streamed["missed_steps"] == 2 and streamed["missed_step_times_s"] == [1.0, 3.0]
    assert streamed["steps_lost"] == 5  # 4 lost at the slip, 1 not made by the end
    settling = [o["settling_s"] for o in streamed["step_outcomes"]]
    # step at 2 s: 0.5 step outside at 2.2 s, 0.02 inside at 2.4 s: crossing at 2.2 + 0.2 * 0.45 / 0.48
    assert settling[1] == pytest.approx(0.2 + 0.2 * 0.45 / 0.48)
    assert settling[2] is None
    assert streamed["peak_torque_Nm"] == 0.7 and streamed["peak_phase_current_A"] == 5.5
    assert streamed["electrical_energy_J"] == pytest.approx(3.0 * 3.5 + 3.5**2 / 2)  # integral of 3 + t
    assert streamed["max_tracking_error_deg"] == pytest.approx(0.01 * np.sin(1.5))
    assert streamed["solution_rows"] == len(time) and streamed["end_time_s"] == 3.5
    # the same as the definitions evaluated on the whole trace at once (summary.figures: written
    # apart from the recorder, which summarize itself now goes through)
    whole = figures(trace, metadata)
    for key in ("missed_steps", "steps_lost", "max_tracking_error_deg", "electrical_energy_J", "peak_torque_Nm"):
        assert streamed[key] == pytest.approx(whole[key], rel=1e-12), key
    assert streamed["rms_tracking_error_deg"] == pytest.approx(whole["rms_tracking_error_deg"], rel=1e-12)
    assert streamed["settling_time_s"] == whole["settling_time_s"]


def _idle_inputs(step_times, indices, fraction, delay):
    metadata = _inputs(step_times, indices)
    metadata["drive"].update(idle_current_fraction=fraction, idle_delay=delay)
    return metadata


@pytest.mark.parametrize("slips", [0, 1])
def test_lost_steps_are_net_of_the_larger_lag_the_load_causes_at_the_idle_current(slips):
    # The load holds the rotor 0.19 step behind at full current. The detent's torque is
    # k_e I sin(N_c d) (eq. 9, a full step is a quarter period): at 30 % of the current the same
    # load needs sin(N_c d) = sin(N_c 0.19 step) / 0.3, a lag of 0.87 step, still in its detent
    # (the old rule, net of the start lag only, counted 1 lost step here); a slip adds 4.
    n_c = np.pi / 2 / STEP
    start_lag = 0.19 * STEP
    idle_lag = np.arcsin(np.sin(n_c * start_lag) / 0.3) / n_c
    assert idle_lag / STEP == pytest.approx(0.87, abs=0.01)
    time = np.array([0.0, 0.5, 1.0, 2.0, 3.0])
    end = -idle_lag - slips * 4 * STEP
    rotor = np.array([-start_lag, -start_lag, -start_lag, end, end])
    summary = summarize(_trace(time, rotor, np.zeros(5)), _idle_inputs([], [], fraction=0.3, delay=0.5))
    assert summary["steps_lost"] == 4 * slips
    assert summary["final_lag_steps"] == pytest.approx(idle_lag / STEP)
    # with full current to the end (the drop comes after it) the start lag is the rule
    held = summarize(_trace(time, np.full(5, -start_lag), np.zeros(5)), _idle_inputs([], [], fraction=0.3, delay=5.0))
    assert held["steps_lost"] == 0 and held["final_lag_steps"] == pytest.approx(0.19)
