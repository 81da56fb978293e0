"""Tests of heliostep.plots.light: power on the tube over a window, ideal against the drive."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from heliostep.plots.light import POWER_FILE, light_figure, plot_light, plot_light_run
from heliostep.plots.units import si_scale
from heliostep.results.light.on_tube import light_timeseries
from heliostep.scenario import validate_scenario
from heliostep.solar.tracking import panel_angle_reference

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
METADATA = {"window_start": "2025-01-21T10:00:00+01:00", "timezone": "Europe/Rome", "roles": {"panel_angle": "p"}}


def _scenario(distance):
    return validate_scenario(
        {
            "name": "light-plot",
            "site": {"latitude": 40.0, "longitude": 14.25, "altitude": 0.0, "timezone": "Europe/Rome"},
            "window": {"date": "2025-01-21", "start": "10:00", "duration": 600},
            "plant": {"orientation": "NS", "tube_height": 3.0},
            "mirror": {"distance": distance, "axis": "secondary"},
        }
    )


def _trace(scenario, distance):
    """Ten minutes of a panel 1e-4 rad off its reference, every 5 s."""
    seconds = np.arange(0.0, 601.0, 5.0)
    times = pd.Timestamp("2025-01-21 10:00", tz="Europe/Rome") + pd.to_timedelta(seconds, unit="s")
    ref = panel_angle_reference(times, scenario.site.to_site(), scenario.plant.to_plant(), distance).to_numpy()
    return pd.DataFrame({"time": seconds, "panel_angle_ref": ref, "p": ref + 1e-4})


@pytest.mark.filterwarnings("ignore::Warning")
def test_power_on_the_tube_is_drawn_from_a_run(tmp_path):
    scenario = _scenario(-1.2)
    trace = _trace(scenario, -1.2)
    written = plot_light_run(trace, METADATA, scenario, tmp_path)
    assert [p.name for p in written] == [POWER_FILE]
    assert written[0].read_bytes().startswith(PNG_SIGNATURE) and written[0].stat().st_size > 20_000
    assert plot_light_run(trace.iloc[:1], METADATA, scenario, tmp_path / "none") == []


def test_short_series_draws_nothing(tmp_path):
    series = pd.DataFrame({"time": [0.0], "power_ideal_W": [1.0], "power_reference_W": [1.0]})
    assert plot_light(series, tmp_path / "x.png", METADATA) is None


@pytest.mark.filterwarnings("ignore::Warning")
def test_the_powers_axis_is_zoomed_and_the_differences_have_panels_of_their_own():
    # the central mirror: ideal, reference and actual differ by parts in 10^7; from 0 they were one line
    scenario = _scenario(0.0)
    trace = _trace(scenario, 0.0)
    series = light_timeseries(trace, METADATA, scenario)
    fig = light_figure(series, METADATA)
    top, sharing, stepping = fig.axes[:3]
    assert len([ax for ax in fig.axes if ax.get_ylabel()]) == 3  # powers, sharing's loss, stepping's change
    powers = series[["power_ideal_W", "power_reference_W", "power_actual_W"]].to_numpy()
    factor, unit = si_scale(powers, unit="W")
    assert f"[{unit}]" in top.get_ylabel() and 1.0 <= factor * powers.max() < 1000.0  # e.g. W for 45 W, not kW
    low, high = top.get_ylim()
    assert low > 0.9 * factor * powers.min() and high < 1.1 * factor * powers.max()  # zoomed on them, not from 0
    drawn = stepping.get_lines()[0].get_ydata()  # the stepping's change, every point (few rows: none thinned)
    change = (series["power_actual_W"] - series["power_reference_W"]).to_numpy()
    change_factor, change_unit = si_scale(change, series["stepping_first_order_W"], unit="W")
    assert f"[{change_unit}]" in stepping.get_ylabel()
    np.testing.assert_allclose(drawn, change * change_factor)
    lo, hi = stepping.get_ylim()
    assert 0 < hi - lo < 10 * np.abs(change * change_factor).max()  # scaled to the change itself
    without_actual = light_figure(series.drop(columns=["power_actual_W"]), METADATA)
    assert len([ax for ax in without_actual.axes if ax.get_ylabel()]) == 2


@pytest.mark.filterwarnings("ignore::Warning")
def test_the_legends_give_the_run_s_figures_not_the_rows_trapezoids(fmu_paths):
    """On a 30 s grid the rows' trapezoid of the stepping's change is 29 times the run's figure (which takes the
    panel's swing between the rows from the solution): the legend gives the figure, as summary.json does."""
    from heliostep.paths import scenarios_dir
    from heliostep.plots.light import _energy_text
    from heliostep.run import run_scenario

    coarse = ("output.interval=30", "output.step_detail=0.01", "output.step_interval=0.005")
    run = run_scenario(scenarios_dir() / "jan21-central.yaml", overrides=coarse)
    series = light_timeseries(run.trace, run.metadata, run.scenario)
    time = series["time"].to_numpy()
    change = (series["power_actual_W"] - series["power_reference_W"]).to_numpy()
    fig = light_figure(series, run.metadata, "", run.summary)
    (stepping,) = [ax for ax in fig.axes if ax.get_ylabel().startswith("power change")]
    legend = [t.get_text().replace("\n", " ") for t in stepping.get_legend().get_texts()]
    figure = run.summary["light_stepping_change_J"]
    assert legend[0].endswith(f": {figure:.3g} J")
    assert abs(np.trapezoid(change, time)) > 10 * abs(figure)  # what the rows alone would have said
    assert _energy_text(change, time) not in legend[0]
    top = [t.get_text().replace("\n", " ") for t in light_figure(series, run.metadata).axes[0].get_legend().get_texts()]
    assert top[0].endswith(_energy_text(series["power_ideal_W"].to_numpy(), time))  # without figures: the rows'


def test_si_scale_picks_the_prefix_the_values_read_in():
    assert si_scale(np.array([45.0, 12.0]), unit="W") == (1.0, "W")
    assert si_scale(np.array([0.02, -0.5]), unit="W") == (1e3, "mW")
    assert si_scale(np.array([2500.0]), unit="W") == (1e-3, "kW")
    assert si_scale(np.array([3e-6]), unit="W") == (1e6, "µW")
    assert si_scale(np.zeros(3), np.array([np.nan]), unit="W") == (1.0, "W")


@pytest.mark.filterwarnings("ignore::Warning")
def test_a_panel_the_summary_calls_not_meaningful_is_not_drawn():
    scenario = _scenario(0.0)
    series = light_timeseries(_trace(scenario, 0.0), METADATA, scenario)
    notes = [
        "light_lost_shared_primary_J is exactly 0: the central mirror's primary is the shared one",
        "light_lost_reference_law_J = 1e-9 J is below the sun grid's interpolation noise (1e-06 of the energy): not"
        " meaningful",
    ]
    fig = light_figure(series, METADATA, "", {"light_notes": notes})
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert len(labels) == 2 and not any(label.startswith("power lost") for label in labels)
