"""A held run keeps its figures' light at every row (``RunResult.light_rows``), and its power on the tube is
drawn from them: the same values as the light computed again from the trace, bit for bit, and the same PNG byte
for byte. Real FMUs, real CVODE, real pvlib."""

from __future__ import annotations

import numpy as np
import pytest

from heliostep.paths import scenarios_dir
from heliostep.plots.light import plot_light_run
from heliostep.results.light import light_timeseries
from heliostep.results.light_rows import PLOT_COLUMNS
from heliostep.run import run_scenario

SCENARIO = scenarios_dir() / "jan21-central.yaml"


@pytest.fixture(scope="module")
def held():
    """The paper's mirror for 40 s (603 rows), its output rows evaluated in chunks of 200 (four blocks of the light)."""
    return run_scenario(SCENARIO, overrides=("window.duration=40",), row_group_rows=200)


def _trace_light(result):
    panel_angle = result.metadata["roles"]["panel_angle"]
    return result.trace_columns(["panel_angle_ref", panel_angle])


def test_the_kept_light_is_the_light_of_the_trace_bit_for_bit(held):
    kept = held.light_rows
    trace = _trace_light(held)
    assert len(trace) > 600 and held.figures is not None  # more rows than three chunks
    again = light_timeseries(trace, held.metadata, held.scenario, held.weather)
    expected = [key for key in PLOT_COLUMNS if key in again]
    assert list(kept) == expected and "power_actual_W" in kept and "stepping_first_order_W" in kept
    for key in expected:
        assert np.array_equal(kept[key], again[key].to_numpy(), equal_nan=True), key
    # the rows the summary's light figures integrate (corrected between the rows by parts in 10^8)
    energy = np.trapezoid(kept["power_actual_W"], kept["time"])
    assert energy > 1000.0 and energy == pytest.approx(held.summary["light_energy_J"], rel=1e-6)


def test_the_power_on_the_tube_drawn_from_the_kept_light_is_the_png_drawn_from_the_trace(held, tmp_path):
    trace = _trace_light(held)
    args = (held.metadata, held.scenario)
    for name in ("kept", "again", "short"):
        (tmp_path / name).mkdir()
    (kept,) = plot_light_run(trace, *args, tmp_path / "kept", held.weather, held.summary, series=held.light_rows)
    (again,) = plot_light_run(trace, *args, tmp_path / "again", held.weather, held.summary)
    assert kept.read_bytes() == again.read_bytes()
    # rows that are not the trace's (here: a shorter series) are not drawn: the light is computed from the trace
    short = {key: value[:-1] for key, value in held.light_rows.items()}
    (other,) = plot_light_run(trace, *args, tmp_path / "short", held.weather, held.summary, series=short)
    assert other.read_bytes() == again.read_bytes()


def test_runs_that_do_not_hold_their_trace_keep_no_light_rows():
    overrides = ("window.duration=5",)
    streamed = run_scenario(SCENARIO, overrides=overrides, stream=True)
    assert streamed.held_trace is None and streamed.light_rows is None
    figures_only = run_scenario(SCENARIO, overrides=overrides, keep_trace=False)
    assert figures_only.light_rows is None
    light = [key for key in streamed.summary if key.startswith("light_")]
    assert len(light) > 8 and [streamed.summary[key] for key in light] == [figures_only.summary[key] for key in light]
