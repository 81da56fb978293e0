"""heliostep.results.figures.solution's plot data: the solver-step rows held around the peak |torque| and
the per-bin envelopes, checked against the whole series computed here by brute force (no code of
the recorder's), whatever the blocks the rows come in; their memory stays bounded."""

from __future__ import annotations

import numpy as np
import pytest

from heliostep.results.figures.plot_data import ROTOR_LAG
from heliostep.results.figures.solution import PEAK_WINDOW_HALF_WIDTH, PeakWindow, SolutionRecorder
from heliostep.results.trace.frame import drive_from_metadata
from heliostep.scenario import RolesConfig

STEP = np.pi / 100
COLUMNS = ["time", "mechanics.theta", "motor.tau", "motor.i_a", "motor.i_b", "motor.power", "mechanics.theta_p"]
DURATION = 60.0
STEPS = np.arange(2.0, DURATION, 4.0)


def _rows(seed: int = 3) -> np.ndarray:
    """Solver-like rows: dense after each step (a decaying ring), sparse between, two rows at each
    step instant; the torque's largest magnitude is a single negative spike after one step."""
    rng = np.random.default_rng(seed)
    dense = (STEPS[:, None] + np.geomspace(1e-5, 0.5, 300)[None, :]).ravel()
    time = np.sort(np.r_[rng.uniform(0.0, DURATION, 3000), dense, STEPS, STEPS, 0.0, DURATION])
    since = time - np.r_[-np.inf, STEPS][np.searchsorted(STEPS, time, side="right")]
    since = np.where(np.isfinite(since), since, 1e3)  # before the first step: long settled
    ring = np.exp(-since / 0.01) * np.sin(2 * np.pi * 100 * since)
    torque = 0.8 * ring + 0.01 * rng.normal(size=time.size)
    spike = int(np.searchsorted(time, STEPS[9] + 0.003))
    torque[spike] = -2.5
    index = np.searchsorted(STEPS, time, side="right")
    current_a = 5.5 * np.cos(index * np.pi / 2) * (1.0 - 0.05 * ring)
    current_b = 5.5 * np.sin(index * np.pi / 2) + 0.1 * ring
    zeros = np.zeros_like(time)
    return np.column_stack([time, index * STEP, torque, current_a, current_b, zeros, zeros])


def _recorder(span=(0.0, DURATION), bins=200, block=4096) -> SolutionRecorder:
    drive = {
        "mode": "one-phase-on",
        "current": 5.5,
        "step_angle": STEP,
        "initial_index": 0,
        "step_times": list(STEPS),
        "step_indices": list(range(1, len(STEPS) + 1)),
    }
    sequencer, schedule = drive_from_metadata(drive)
    roles = RolesConfig().present()
    return SolutionRecorder(COLUMNS, roles, sequencer, schedule, None, block=block, span=span, bins=bins)


def _feed(recorder: SolutionRecorder, rows: np.ndarray, seed: int) -> None:
    """The rows in blocks of random sizes (1 to 500 rows), as the master may hand them."""
    rng = np.random.default_rng(seed)
    start = 0
    while start < len(rows):
        size = int(rng.integers(1, 500))
        recorder(rows[start : start + size])
        start += size


@pytest.mark.parametrize(("block", "seed"), [(1, 0), (7, 1), (4096, 2)])
def test_the_window_is_every_row_within_the_half_width_of_the_peak(block, seed):
    rows = _rows()
    recorder = _recorder(block=block)
    _feed(recorder, rows, seed)
    figures, data = recorder.figures(), recorder.plot_data()
    peak = int(np.argmax(np.abs(rows[:, 2])))  # brute force over the whole series
    assert abs(data.peak_torque) == figures["peak_torque_Nm"] == 2.5
    assert data.peak_time == rows[peak, 0] and data.peak_torque == rows[peak, 2]
    near = np.abs(rows[:, 0] - rows[peak, 0]) <= PEAK_WINDOW_HALF_WIDTH
    assert data.columns == ["time", "motor.tau", "mechanics.theta", "motor.i_a", "motor.i_b"]
    np.testing.assert_array_equal(data.peak_rows, rows[near][:, [0, 2, 1, 3, 4]])
    assert float(np.abs(data.column("motor.tau")).max()) == figures["peak_torque_Nm"]
    assert data.peak_step == 10 and data.step_count == len(STEPS)  # the spike follows the 10th step
    np.testing.assert_array_equal(data.steps, [STEPS[9]])


def test_the_envelopes_are_the_min_and_max_of_every_row_in_each_bin():
    rows = _rows()
    recorder = _recorder(bins=200)
    _feed(recorder, rows, 5)
    figures, data = recorder.figures(), recorder.plot_data()
    edges = np.linspace(0.0, DURATION, 201)
    assert data.edges is not None
    np.testing.assert_allclose(data.edges, edges, rtol=0, atol=1e-12)
    which = np.minimum((rows[:, 0] // (DURATION / 200)).astype(int), 199)
    for column, name in ((2, "motor.tau"), (3, "motor.i_a"), (4, "motor.i_b")):
        for k in (0, 17, 50, 120, 199):
            inside = rows[which == k, column]
            assert data.minimum[name][k] == inside.min() and data.maximum[name][k] == inside.max(), (name, k)
    torque = max(np.nanmax(np.abs(data.minimum["motor.tau"])), np.nanmax(np.abs(data.maximum["motor.tau"])))
    assert torque == figures["peak_torque_Nm"]
    currents = max(np.nanmax(np.abs(data.minimum[c])) for c in ("motor.i_a", "motor.i_b"))
    currents = max(currents, *(np.nanmax(np.abs(data.maximum[c])) for c in ("motor.i_a", "motor.i_b")))
    assert currents == figures["peak_phase_current_A"]
    assert data.worst["motor.tau"] == (float(rows[np.argmax(np.abs(rows[:, 2])), 0]), -2.5)
    assert all(len(data.minimum[c]) == 200 for c in data.minimum)  # the bins, whatever the rows


def test_the_held_rows_stay_bounded():
    # 2 million rows at 10 us: 20,000 rows within 0.1 s of any instant; held at most 2 x 1,000
    time = np.arange(0.0, 20.0, 1e-5)
    torque = np.sin(time) * (1.0 + time / 20.0)  # the peak grows: the window is replaced often
    window = PeakWindow(torque=1, max_rows=1000)
    for start in range(0, time.size, 4096):
        window(np.column_stack([time[start : start + 4096], torque[start : start + 4096]]))
    assert window.max_held <= 2 * 1000
    peak = int(np.argmax(np.abs(torque)))
    assert window.peak == abs(torque[peak]) and window.rows is not None
    assert len(window.rows) <= 1000 and torque[peak] in window.rows[:, 1]  # thinned, the peak row kept
    assert window.rows[0, 0] >= time[peak] - 0.1 and window.rows[-1, 0] <= time[peak] + 0.1


def test_the_recorder_holds_no_more_than_the_rows_of_two_windows():
    # bound, counted here by brute force: the rows of any 0.1 s (the lead-in) plus those of any 0.2 s
    rows = _rows()
    recorder = _recorder(block=64)
    _feed(recorder, rows, 9)
    time, h = rows[:, 0], PEAK_WINDOW_HALF_WIDTH
    lead_in = np.max(np.arange(time.size) + 1 - np.searchsorted(time, time - h, side="left"))
    window = np.max(np.searchsorted(time, time + h, side="right") - np.searchsorted(time, time - h, side="left"))
    assert recorder.peak_window is not None
    assert recorder.peak_window.max_held <= lead_in + window
    assert recorder.peak_window.max_held < len(rows) / 4


def test_without_a_span_there_are_no_envelopes_and_without_torque_no_window():
    recorder = _recorder(span=None)
    recorder(_rows())
    data = recorder.plot_data()
    assert data.edges is None and data.minimum == {} and data.peak_rows is not None
    drive = drive_from_metadata(
        {
            "mode": "one-phase-on",
            "current": 5.5,
            "step_angle": STEP,
            "initial_index": 0,
            "step_times": [],
            "step_indices": [],
        }
    )
    bare = SolutionRecorder(["time", "mechanics.theta"], RolesConfig().present(), *drive, None, span=(0.0, 1.0))
    bare(np.array([[0.0, 0.0], [1.0, 0.0]]))
    assert bare.plot_data().peak_rows is None  # without torque no window; the rotor's angle and lag enveloped
    assert set(bare.plot_data().minimum) == {"mechanics.theta", ROTOR_LAG}
