"""The light's integrals between the output rows (heliostep.results.light.rows): the rows' trapezoid of a
power that depends on the driven angle, corrected with the solution's integral of the tracking error.

Checked against an integral computed in the test (scipy's adaptive quadrature of a stepped and ringing
angle), and on co-simulated runs across output grids: the stepping's light must not move with the grid.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from heliostep.paths import scenarios_dir
from heliostep.results.light.on_tube import light_timeseries
from heliostep.results.light.rows import RowMarks, corrections
from heliostep.run import RunOptions, run_scenario

#: an output grid of 30 s with 10 ms of detail after each step at 5 ms: the panel is still swinging at
#: its last detail row (tests/results/figures/test_figures.py's coarse grid)
COARSE = ("output.interval=30", "output.step_detail=0.01", "output.step_interval=0.005")

# a stepped angle: the reference a t, the panel stepped onto it every 10 s with a decaying ring
RATE = 2.4e-5  # [rad/s] the reference's speed: one step of STEP per 10 s
STEP = 2.4e-4  # [rad] the panel's step
TAU, PERIOD = 0.005, 0.009  # [s] the ring's decay and period (the drive's: about five periods)
STEPS = np.array([10.0, 20.0, 30.0])
END = 40.0
SLOPE0, SLOPE1 = 5.0, 0.02  # [W/rad], [W/(rad s)] the power's slope in the angle, drifting with the sun


def _panel(t):
    k = np.searchsorted(STEPS, t, side="right")  # steps taken by t
    held = k * STEP
    since = t - np.where(k > 0, STEPS[np.maximum(k - 1, 0)], 0.0)
    ring = np.where(k > 0, STEP * np.exp(-since / TAU) * np.cos(2 * np.pi * since / PERIOD), 0.0)
    return held - ring


def _error(t):
    return _panel(t) - (RATE * t - STEP / 2)  # the reference between the detents: e swings about 0


def _slope(t):
    return SLOPE0 + SLOPE1 * t


def _integral(f, a, b):
    """f over [a, b], by pieces between the steps (quad with the ring's time scale as a break)."""
    edges = np.unique(np.concatenate([[a, b], STEPS[(STEPS > a) & (STEPS < b)]]))
    total = 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        for x0, x1 in ((lo, min(hi, lo + 0.1)), (min(hi, lo + 0.1), hi)):
            if x1 > x0:
                total += quad(f, x0, x1, limit=400, epsabs=1e-16, epsrel=1e-13)[0]
    return total


def test_the_corrected_trapezoid_is_the_integral_of_a_stepped_ringing_angle():
    """Rows as a coarse grid gives them (30 s, both sides of each step, one row 5 ms after it, mid-swing), the
    solution's error integrals exact: the corrected trapezoid of (slope x error) is the integral computed by
    quadrature, where the rows' own trapezoid is far off."""
    rows = np.sort(np.concatenate([[0.0, 30.0, END], STEPS, STEPS, STEPS + 0.005]))
    error, reference = _error(rows), RATE * rows - STEP / 2
    power = _slope(rows) * error
    marks = RowMarks(STEPS)
    for block in (slice(0, 4), slice(4, 7), slice(7, None)):  # in blocks, as the light takes its rows
        marks(rows[block], error[block], reference[block], lambda marked, b=block: {"power": _slope(rows[b][marked])})
    degrees = np.degrees
    solution = {
        "error_integral_at_steps_deg_s": [degrees(_integral(_error, 0.0, t)) for t in STEPS],
        "error_integral_deg_s": degrees(_integral(_error, 0.0, END)),
        "end_time_s": END,
    }
    truth = _integral(lambda t: _slope(t) * _error(t), 0.0, END)
    rows_only = np.trapezoid(power, rows)
    corrected = rows_only + corrections(marks, solution)["power"]
    assert abs(rows_only - truth) > 10 * abs(truth)  # the line through the mid-swing row: 39 times off
    # what is left is second order: the missed part's weight is the slope at the step, where the row's line
    # starts 5 ms later, (SLOPE1 / SLOPE0) x 5 ms = 2e-5 of the correction (measured 1.9e-5)
    assert corrected == pytest.approx(truth, abs=3e-5 * abs(rows_only - truth))


def test_the_second_order_part_is_the_integral_of_a_stepped_ringing_angle_too():
    """A power curved in the angle, g = S(t) e + (C / 2) e^2 (a driven primary's image crossing the tube): the
    slope given at the actual attitude (S + C e), its curvature C, and the solution's integrals of e and e^2
    exact; the corrected trapezoid is the quadrature's integral, the rows' own far off."""
    curvature = -4e4  # [W/rad^2]: the e^2 part comparable to the e part at e ~ 1e-4 rad
    rows = np.sort(np.concatenate([[0.0, 30.0, END], STEPS, STEPS, STEPS + 0.005]))
    error, reference = _error(rows), RATE * rows - STEP / 2

    def power(t, e):
        return _slope(t) * e + curvature / 2 * e**2

    marks = RowMarks(STEPS)
    for block in (slice(0, 4), slice(4, 7), slice(7, None)):
        t, e = rows[block], error[block]
        marks(
            t,
            e,
            reference[block],
            lambda marked, t=t, e=e: {
                "power": _slope(t[marked]) + curvature * e[marked],
                "power''": np.full(len(marked), curvature),
            },
        )
    degrees = np.degrees
    solution = {
        "error_integral_at_steps_deg_s": [degrees(_integral(_error, 0.0, t)) for t in STEPS],
        "error_integral_deg_s": degrees(_integral(_error, 0.0, END)),
        "error_sq_integral_at_steps_deg2_s": [
            degrees(1.0) ** 2 * _integral(lambda x: _error(x) ** 2, 0.0, t) for t in STEPS
        ],
        "error_sq_integral_deg2_s": degrees(1.0) ** 2 * _integral(lambda x: _error(x) ** 2, 0.0, END),
        "end_time_s": END,
    }
    truth = _integral(lambda t: power(t, _error(t)), 0.0, END)
    rows_only = np.trapezoid(power(rows, error), rows)
    corrected = rows_only + corrections(marks, solution)["power"]
    assert abs(rows_only - truth) > 2 * abs(truth)  # 3.3 times the integral
    assert corrected == pytest.approx(truth, abs=3e-5 * abs(rows_only - truth))  # measured 1.3e-5


def test_the_curvature_term_makes_the_trapezoid_of_a_held_angle_exact():
    """The panel held (no step, no ring: e = -(reference), linear) and the slope linear in time: the rows'
    trapezoid of their product errs by -h d(slope) d(e) / 6 a row interval, which the curvature term
    (no solution: a stored run from before its error integrals) takes back to rounding."""
    rows = np.array([0.0, 3.0, 4.5, 4.5, 6.0, 9.0])  # a mark at 4.5 s: the slope's rate from two marks
    reference = RATE * rows - STEP / 2
    error = -reference
    marks = RowMarks([4.5])
    marks(rows, error, reference, lambda marked: {"power": _slope(rows[marked])})
    # the exact integral of (SLOPE0 + SLOPE1 t) (-(RATE t - STEP / 2)) over [0, 9]
    t = 9.0
    truth = -(-SLOPE0 * STEP / 2 * t + (SLOPE0 * RATE - SLOPE1 * STEP / 2) * t**2 / 2 + SLOPE1 * RATE * t**3 / 3)
    rows_only = np.trapezoid(_slope(rows) * error, rows)
    corrected = rows_only + corrections(marks, None)["power"]
    assert abs(rows_only - truth) > 1e-6 * abs(truth)
    assert corrected == pytest.approx(truth, rel=1e-13)


@pytest.fixture(scope="module")
def central_runs(fmu_paths):
    path = scenarios_dir() / "jan21-central.yaml"
    return run_scenario(path, RunOptions(keep_trace=False)), run_scenario(
        path, RunOptions(keep_trace=False), overrides=COARSE
    )


def test_the_stepping_light_does_not_move_with_the_output_grid(central_runs):
    """The paper's case on its own grid (detail rows every 0.5 ms for 50 ms after each step: within 2e-4 of
    a 0.2 ms grid's stepping change, docs/light.md) and on a 30 s grid: the stepping's figures agree (the
    change within 3 %, its second-order part from the solution's integral of e^2 too). On the coarse grid the
    rows' own trapezoid made the change 29 times the fine grid's (-1.55e-2 against -5.4e-4 J)."""
    fine, coarse = (run.summary for run in central_runs)
    assert coarse["rows"] < fine["rows"] / 50
    assert coarse["light_stepping_change_J"] == pytest.approx(fine["light_stepping_change_J"], rel=0.05)
    assert coarse["light_stepping_first_order_J"] == pytest.approx(fine["light_stepping_first_order_J"], rel=0.06)
    assert coarse["light_stepping_first_order_cosine_J"] == pytest.approx(
        fine["light_stepping_first_order_cosine_J"], rel=0.03
    )
    assert coarse["light_stepping_mean_error_rad"] == pytest.approx(fine["light_stepping_mean_error_rad"], rel=0.03)


def test_a_day_hour_on_its_own_30_s_grid_has_the_fine_grid_stepping_light(fmu_paths):
    """jan21-day's first hour on its shipped grid (30 s, 5 ms detail for 10 ms) against 0.1 s with the paper
    case's fine detail: the stepping's change within 5e-9 of the energy (3.6e-9 measured; it was 2.7e-5 of it:
    0.73 J against -9e-5 J; the first-order terms alone left 1.3e-9 here, the second-order ones, which the
    paper's case and a driven primary need, 3.6e-9 at this low sun)."""
    hour = ("window.end=null", "window.duration=3600")
    path = scenarios_dir() / "jan21-day.yaml"
    shipped = run_scenario(path, RunOptions(keep_trace=False), overrides=hour).summary
    fine = run_scenario(
        path,
        RunOptions(keep_trace=False),
        overrides=(*hour, "output.interval=0.1", "output.step_detail=0.05", "output.step_interval=0.0005"),
    ).summary
    energy = fine["light_energy_J"]
    assert shipped["light_stepping_change_J"] == pytest.approx(fine["light_stepping_change_J"], abs=5e-9 * energy)
    assert abs(fine["light_stepping_change_J"]) < 5e-8 * energy  # the stepping changes the light by nothing (1.2e-8)
    # the largest misses at the swing (0.72 mm from the 30 s rows against 0.92 mm before), the mean intercept
    for key in ("max_longitudinal_miss_m", "max_transverse_miss_m"):
        assert shipped[key] == pytest.approx(fine[key], rel=2e-4), key
    assert shipped["mean_intercept"] == pytest.approx(fine["mean_intercept"], rel=1e-4)


def test_the_largest_misses_and_the_mean_intercept_do_not_move_with_the_output_grid(central_runs):
    """The actual attitude's largest misses are taken at the solution's swing too (its extremes of the error
    per step, ``error_extremes_deg``), so the coarse rows no longer step over the swing's peak: the largest
    longitudinal miss was 0.58 mm on the 30 s grid against 0.94 mm. The mean intercept is a ratio of
    trapezoids in time (over the rows it leaned to the rows clustered after the steps)."""
    fine, coarse = (run.summary for run in central_runs)
    for key in ("max_longitudinal_miss_m", "max_transverse_miss_m"):
        assert coarse[key] == pytest.approx(fine[key], rel=1e-4), key
    assert fine["max_longitudinal_miss_m"] > 1.5 * fine["max_transverse_miss_m"] > 0  # a secondary's error: along
    assert coarse["mean_intercept"] == pytest.approx(fine["mean_intercept"], rel=1e-5)


def test_a_driven_primary_stepping_light_is_second_order_and_does_not_move_with_the_grid(fmu_paths):
    """A driven primary's error moves the image across the tube: its change is second order in the error
    (-6.9e-2 J against a first-order term of +1.1e-3 J), the power's curvature in the angle over the swing and
    over the held stretches. On 30 s rows it agrees with its own grid within 2e-3 (1.4e-4 measured; the
    first-order correction alone left it 36 % off, the rows alone more)."""
    path = scenarios_dir() / "jan21-central.yaml"
    fine = run_scenario(path, RunOptions(keep_trace=False), overrides=("mirror.axis=primary",)).summary
    coarse = run_scenario(path, RunOptions(keep_trace=False), overrides=("mirror.axis=primary", *COARSE)).summary
    assert abs(fine["light_stepping_change_J"]) > 30 * abs(fine["light_stepping_first_order_J"])
    assert coarse["light_stepping_change_J"] == pytest.approx(fine["light_stepping_change_J"], rel=2e-3)
    assert coarse["light_stepping_first_order_J"] == pytest.approx(fine["light_stepping_first_order_J"], rel=0.01)


def test_the_light_of_a_held_run_s_rows_integrates_to_its_summary_figure(fmu_paths):
    """The power on the tube at a held run's rows (what its figure draws, computed from the trace in four
    chunks of 200 rows): its trapezoid is the summary's light energy, which corrects it between the rows by
    parts in 10^8."""
    held = run_scenario(
        scenarios_dir() / "jan21-central.yaml", RunOptions(row_group_rows=200), overrides=("window.duration=40",)
    )
    trace = held.trace_columns(["panel_angle_ref", held.metadata["roles"]["panel_angle"]])
    assert len(trace) > 600 and held.figures is not None  # more rows than three chunks
    light = light_timeseries(trace, held.metadata, held.scenario, held.weather)
    assert "power_actual_W" in light and "stepping_first_order_W" in light
    energy = np.trapezoid(light["power_actual_W"], light["time"])
    assert energy > 1000.0 and energy == pytest.approx(held.summary["light_energy_J"], rel=1e-6)


def test_a_streamed_run_and_a_run_without_trace_have_the_same_light_figures(fmu_paths):
    scenario, overrides = scenarios_dir() / "jan21-central.yaml", ("window.duration=5",)
    streamed = run_scenario(scenario, RunOptions(stream=True), overrides=overrides)
    figures_only = run_scenario(scenario, RunOptions(keep_trace=False), overrides=overrides)
    assert streamed.held_trace is None
    light = [key for key in streamed.summary if key.startswith("light_")]
    assert len(light) > 8 and [streamed.summary[key] for key in light] == [figures_only.summary[key] for key in light]
