"""Tests of heliostep.plots.run: the run figures (paper Figs. 8-14) from a synthetic trace."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from heliostep.errors import InputError
from heliostep.plots import run as run_plots
from heliostep.plots.run_trace import TraceClock
from heliostep.plots.thinning import EDGE_GID, Band, min_max_line
from heliostep.results.figures.plot_data import ENVELOPE_BINS, TRACKING_ERROR

STEP_ANGLE = np.radians(1.8)  # [rad]
METADATA = {"window_start": "2025-01-21T10:00:00+01:00", "timezone": "Europe/Rome", "scenario": "synthetic"}
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def synthetic_trace(duration=20.0, step_period=1.0, interval=0.01, detail=0.05, fine=0.0005, loud_step=7):
    """A trace shaped like the master's: regular grid, a finer grid after each step, two rows per step.

    Step k (1-based) at k * step_period; the torque after step ``loud_step`` is twice as large.
    """
    steps = np.arange(step_period, duration, step_period)
    regular = np.arange(0.0, duration + interval / 2, interval)
    after_steps = (steps[:, None] + np.arange(fine, detail, fine)[None, :]).ravel()
    grid = np.unique(np.round(np.r_[regular, after_steps], 9))
    grid = grid[~np.isin(grid, np.round(steps, 9))]
    time = np.sort(np.r_[grid, steps, steps])
    step_index = np.searchsorted(steps, time, side="right")
    first_of_pair = np.r_[np.diff(time) == 0.0, False]
    step_index = np.where(first_of_pair, step_index - 1, step_index)  # the row just before the step
    since_step = time - np.r_[0.0, steps][step_index]
    ringing = np.exp(-since_step / 0.01) * (step_index > 0)
    command = step_index * STEP_ANGLE
    theta = command - STEP_ANGLE * ringing * np.cos(2 * np.pi * 60 * since_step)
    torque = 0.5 * ringing * np.sin(2 * np.pi * 60 * since_step) * np.where(step_index == loud_step, 2.0, 1.0)
    i_a_ref = 5.5 * np.cos(step_index * np.pi / 2)
    i_b_ref = 5.5 * np.sin(step_index * np.pi / 2)
    rise = 1.0 - np.exp(-since_step / 0.003)
    panel_ref = np.radians(20.0) + time * STEP_ANGLE / step_period * 0.0025 / 0.3
    theta_p = np.radians(20.0) + theta * 0.0025 / 0.3
    zeros = np.zeros_like(time)
    return pd.DataFrame(
        {
            "time": time,
            "panel_angle_ref": panel_ref,
            "rotor_angle_ref": time * STEP_ANGLE / step_period,
            "rotor_angle_cmd": command,
            "step_index": step_index,
            "i_a_ref": i_a_ref,
            "i_b_ref": i_b_ref,
            "m_ext": zeros,
            "motor.i_a": i_a_ref * rise,
            "motor.i_b": i_b_ref * rise,
            "motor.tau": torque,
            "motor.v_a": zeros,
            "motor.v_b": zeros,
            "motor.power": zeros,
            "mechanics.theta": theta,
            "mechanics.omega": zeros,
            "mechanics.theta_p": theta_p,
            "mechanics.omega_p": zeros,
            "panel_angle_error": theta_p - panel_ref,
        }
    )


@pytest.fixture(scope="module")
def trace():
    return synthetic_trace()


def png_size(path):
    """(width, height) [px] of a PNG, from its IHDR chunk; fails on anything else."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, f"{path.name} is not a PNG"
    assert data[12:16] == b"IHDR"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_step_times_are_where_the_commanded_index_changes():
    # rows as the master writes them: a row before and a row after each step, same time
    table = pd.DataFrame(
        {"time": [0.0, 0.5, 1.0, 1.0, 1.5, 2.25, 2.25, 3.0, 3.0, 4.0], "step_index": [0, 0, 0, 1, 1, 1, 2, 2, 1, 1]}
    )
    np.testing.assert_array_equal(run_plots.step_times(table), [1.0, 2.25, 3.0])
    assert run_plots.step_times(table.drop(columns="step_index")).size == 0
    assert run_plots.step_times(table.assign(step_index=0)).size == 0


def test_every_figure_is_written(trace, tmp_path):
    written = run_plots.plot_run(trace, tmp_path / "figures", METADATA)
    expected = [
        tmp_path / "figures" / name
        for name in (
            "fig08_panel_angle_ref.png",
            "fig09_rotor_angle_ref.png",
            "fig10_phase_currents.png",
            "fig11_torque.png",
            "fig12_rotor_angle.png",
            "fig13_panel_tracking.png",
            "fig14_torque_zoom.png",
        )
    ]
    assert written == expected
    for path in expected:
        assert path.stat().st_size > 20_000, f"{path.name} looks empty"
        width, height = png_size(path)
        assert width >= 800 and height >= 400


def test_no_steps_skips_the_torque_zoom(trace, tmp_path):
    still = trace[trace["time"] < 0.5].copy()
    still["step_index"] = 0
    written = run_plots.plot_run(still, tmp_path, METADATA)
    names = [path.name for path in written]
    assert "fig14_torque_zoom.png" not in names and not (tmp_path / "fig14_torque_zoom.png").exists()
    assert len(names) == 6


@pytest.mark.parametrize(
    ("dropped", "skipped"),
    [
        (
            ["motor.i_a", "motor.i_b", "motor.tau", "motor.v_a", "motor.v_b", "motor.power"],
            {"fig10_phase_currents.png", "fig11_torque.png", "fig14_torque_zoom.png"},
        ),
        (
            ["mechanics.theta", "mechanics.theta_p", "mechanics.omega", "mechanics.omega_p", "panel_angle_error"],
            {"fig12_rotor_angle.png", "fig13_panel_tracking.png"},
        ),
        (["step_index", "i_a_ref", "i_b_ref", "rotor_angle_cmd", "panel_angle_error"], {"fig14_torque_zoom.png"}),
        ([column for column in synthetic_trace(duration=1.0).columns if column != "time"], set(run_plots.FIGURE_FILES)),
    ],
)
def test_missing_columns_skip_their_figures(trace, tmp_path, dropped, skipped):
    written = run_plots.plot_run(trace.drop(columns=dropped), tmp_path, METADATA)
    # (an open-loop trace has no sun sensor: no tracking loop figure)
    assert {path.name for path in written} == set(run_plots.FIGURE_FILES) - skipped - {"tracking_loop.png"}


def test_torque_zoom_picks_the_step_with_the_largest_torque(trace):
    time, torque = trace["time"].to_numpy(), trace["motor.tau"].to_numpy()
    steps = run_plots.step_times(trace)
    step, peak = run_plots._largest_torque_step(time, torque, steps)
    assert steps[step] == 7.0  # the loud step of the synthetic trace
    assert 7.0 < time[peak] < 7.05 and abs(torque[peak]) == np.abs(torque).max()


def test_x_axis_shows_local_clock_time(trace):
    from matplotlib.figure import Figure

    clock = TraceClock(METADATA, trace["time"].to_numpy())
    ax = Figure().add_subplot()
    ax.plot(clock.x(np.array([0.0, 20.0])), [0.0, 1.0])
    clock.format_axis(ax)
    formatter = ax.xaxis.get_major_formatter()
    assert formatter(clock.x(np.array([0.0]))[0]) == "10:00:00"  # 09:00 UTC shown in Europe/Rome
    assert formatter(clock.x(np.array([75.0]))[0]) == "10:01:15"
    assert "Europe/Rome" in ax.get_xlabel()


def test_without_window_start_the_axis_is_in_seconds(trace, tmp_path):
    written = run_plots.plot_run(trace, tmp_path, {"scenario": "no-clock"})
    assert len(written) == 7
    clock = TraceClock({}, trace["time"].to_numpy())
    np.testing.assert_array_equal(clock.x(np.array([1.5])), [1.5])


def test_thinning_keeps_the_extremes_and_bounds_the_points():
    rng = np.random.default_rng(1)
    time = np.sort(rng.uniform(0.0, 100.0, 1_000_000))
    values = rng.normal(size=time.size)
    values[123_456] = 50.0
    values[654_321] = -50.0
    values[777] = np.nan
    shown_time, shown = min_max_line(time, values)
    assert shown.size == 2 * ENVELOPE_BINS and np.all(np.diff(shown_time) >= 0)
    assert shown.max() == 50.0 and shown.min() == -50.0
    band = Band.of_rows(time, values)
    assert band is not None and band.high.max() == 50.0 and band.low.min() == -50.0
    assert band.worst == (time[123_456], 50.0)  # the first of the largest magnitude
    assert np.all((band.low <= band.mean) & (band.mean <= band.high))
    short = np.arange(100.0)
    np.testing.assert_array_equal(min_max_line(short, short)[1], short)  # few rows: drawn as they are


def test_bad_traces_are_input_errors(trace, tmp_path):
    with pytest.raises(InputError, match="'time' column"):
        run_plots.plot_run(trace.drop(columns="time"), tmp_path, METADATA)
    with pytest.raises(InputError, match="non-decreasing"):
        run_plots.plot_run(trace.iloc[::-1], tmp_path, METADATA)
    with pytest.raises(InputError, match="empty"):
        run_plots.plot_run(trace.iloc[:0], tmp_path, METADATA)


def test_matplotlib_is_imported_only_by_the_plots():
    # every module of heliostep outside heliostep.plots, imported (all of them) in a fresh interpreter
    import heliostep

    package = Path(heliostep.__file__).parent
    modules = sorted(
        "heliostep." + ".".join(path.relative_to(package).with_suffix("").parts).removesuffix(".__init__")
        for path in package.rglob("*.py")
        if "plots" not in path.relative_to(package).parts
    )
    assert len(modules) > 40 and "heliostep.sweep.cluster" in modules and "heliostep.cli.run" in modules
    code = (
        "import importlib, sys\n"
        f"for name in {modules!r}:\n"
        "    importlib.import_module(name)\n"
        "    assert 'matplotlib' not in sys.modules, f'{name} imported matplotlib'\n"
        "import heliostep.plots.run, matplotlib\n"
        "assert matplotlib.get_backend().lower() == 'agg', matplotlib.get_backend()\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr


# --------------------------------------------------------------------------- drawn from the solution
@pytest.fixture(
    scope="module", params=[("jan21-central", ["window.duration=40"]), ("jan21-weak-motor", []), ("jan21-day", [])]
)
def solved(request, fmu_paths):
    """A shipped scenario's run and its figures as drawn (the issue's cases: the weak motor and the
    day, whose Fig. 14 drew output rows, 1.76 and 1.17 N.m against 2.075 and 2.011)."""
    from heliostep.paths import scenarios_dir
    from heliostep.run import run_scenario

    name, overrides = request.param
    run = run_scenario(scenarios_dir() / f"{name}.yaml", overrides=overrides)
    source = run.held_trace if run.held_trace is not None else run.trace_file
    return run, dict(run_plots.run_figures(source, run.trace_metadata(), run.solution_plot))


def _lines(fig, start: str, axis: int = 0):
    return [line for line in fig.axes[axis].lines if str(line.get_label()).startswith(start)]


def test_torque_zoom_draws_the_solution_and_its_peak_is_the_summarys(solved):
    run, figures = solved
    peak = run.summary["peak_torque_Nm"]
    zoom = figures["fig14_torque_zoom.png"]
    (line,) = _lines(zoom, run_plots.TORQUE_ZOOM_LABEL)
    assert float(np.max(np.abs(line.get_ydata()))) == peak  # exactly: the same solver row
    (dot,) = _lines(zoom, "peak |torque|")
    assert abs(float(dot.get_ydata()[0])) == peak and dot.get_ydata()[0] in line.get_ydata()
    assert len(line.get_ydata()) > 50  # the solver's rows, not a few output rows
    assert "of the solution" in zoom.axes[0].get_title()


def test_long_figures_draw_the_solution_envelopes_with_the_worst_marked(solved):
    run, figures = solved
    torque = figures["fig11_torque.png"]
    bands = _lines(torque, "torque: max per") + _lines(torque, "torque: min per")
    assert len(bands) == 2
    assert max(float(np.nanmax(np.abs(b.get_ydata()))) for b in bands) == run.summary["peak_torque_Nm"]
    (worst,) = _lines(torque, "largest |torque|")
    assert abs(float(worst.get_ydata()[0])) == run.summary["peak_torque_Nm"]
    currents = figures["fig10_phase_currents.png"]
    drawn = [b for axis in (0, 1) for b in _lines(currents, "i_", axis) if " per " in str(b.get_label())]
    assert len(drawn) == 4
    assert max(float(np.nanmax(np.abs(b.get_ydata()))) for b in drawn) == run.summary["peak_phase_current_A"]


def test_rotor_angle_commanded_is_drawn_on_top_and_the_difference_below(solved):
    _, figures = solved
    fig = figures["fig12_rotor_angle.png"]
    (actual,) = _lines(fig, "actual")
    (commanded,) = _lines(fig, "commanded")
    assert commanded.get_zorder() > actual.get_zorder() and commanded.get_color() != actual.get_color()
    assert commanded.get_linewidth() < actual.get_linewidth()  # the actual shows around it
    assert len(fig.axes) == 2 and "actual - commanded" in fig.axes[1].get_ylabel()


def test_the_run_writes_its_figures_from_the_solution(solved, tmp_path):
    run, _ = solved
    if run.scenario.name != "jan21-central":
        pytest.skip("one run is enough")
    written = [path.name for path in run.plot(tmp_path)]
    assert "fig14_torque_zoom.png" in written and "fig11_torque.png" in written


def _nothing_clipped_or_overlapping(name, fig):
    """Every text drawn (tick labels, axis labels, titles, offset texts, legends) inside the figure, and
    no panel's texts reaching into its neighbour's frame (the fixed layout's margins and gaps are enough)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    fig.set_dpi(run_plots._DPI)
    canvas.draw()
    renderer = canvas.get_renderer()
    edge = fig.bbox
    for ax in fig.axes:
        drawn = ax.get_tightbbox(renderer)
        assert drawn.x0 >= edge.x0 and drawn.y0 >= edge.y0, (name, "clipped left or below", drawn, edge)
        assert drawn.x1 <= edge.x1 and drawn.y1 <= edge.y1, (name, "clipped right or above", drawn, edge)
    frames = sorted(fig.axes, key=lambda ax: -ax.get_window_extent().y0)  # top to bottom
    for upper, lower in zip(frames, frames[1:]):
        assert lower.get_tightbbox(renderer).y1 <= upper.get_window_extent().y0, (
            name,
            "a panel's text in the one above",
        )
        assert upper.get_tightbbox(renderer).y0 >= lower.get_window_extent().y1, (
            name,
            "a panel's text in the one below",
        )


def test_the_fixed_layout_clips_nothing_and_panels_do_not_overlap(solved):
    from heliostep.plots.light import light_figure
    from heliostep.results.light.on_tube import light_timeseries

    run, figures = solved
    assert len([fig for fig in figures.values() if fig is not None]) == 7
    for name, fig in figures.items():
        if fig is not None:
            assert fig.get_layout_engine() is None  # fixed margins, no text-extent pass before the draw
            _nothing_clipped_or_overlapping(name, fig)
    columns = ["panel_angle_ref", run.metadata.get("roles", {}).get("panel_angle", "")]
    series = light_timeseries(run.trace_columns(columns), run.metadata, run.scenario, run.weather)
    title = f" ({run.scenario.name}, {run.scenario.window.date}, mirror at d = 0 m, secondary driven)"
    _nothing_clipped_or_overlapping("power", light_figure(series, run.metadata, title))


def _drawn_extremes(ax) -> tuple[float, float]:
    """The least and largest value drawn on ``ax``: its Line2D and PolyCollection data (no horizontal line)."""
    values = [np.asarray(line.get_ydata(), dtype=float) for line in ax.lines if len(set(line.get_ydata())) > 1]
    values += [path.vertices[:, 1] for shade in ax.collections for path in shade.get_paths()]
    drawn = np.concatenate(values)
    return float(np.nanmin(drawn)), float(np.nanmax(drawn))


def _legends_beside_the_data(name, fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None:
            box, frame = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
            assert box.x0 >= frame.x1 or box.y0 >= frame.y1 or box.y1 <= frame.y0, (name, "legend over the data")


def test_the_tracking_error_drawn_is_the_summarys_and_legends_are_beside_the_data(solved):
    """Fig. 13's error panel is drawn from every solver step: its extremes are summary.json's worst tracking
    error exactly (the day's output rows reach 0.0068 deg of its 0.0116); no legend covers an axes' data."""
    run, figures = solved
    error = figures["fig13_panel_tracking.png"].axes[1]
    low, high = _drawn_extremes(error)
    assert max(abs(low), abs(high)) == run.summary["max_tracking_error_deg"]
    (worst,) = _lines(figures["fig13_panel_tracking.png"], "largest |tracking error|", 1)
    assert abs(float(worst.get_ydata()[0])) == run.summary["max_tracking_error_deg"]
    torque = _drawn_extremes(figures["fig11_torque.png"].axes[0])
    assert max(abs(torque[0]), abs(torque[1])) == run.summary["peak_torque_Nm"]
    for name, fig in figures.items():
        if fig is not None:
            _legends_beside_the_data(name, fig)


def test_the_envelope_of_the_solution_is_in_every_run_figure(solved):
    run, figures = solved
    assert TRACKING_ERROR in run.solution_plot.maximum
    for name in ("fig10_phase_currents.png", "fig11_torque.png", "fig12_rotor_angle.png", "fig13_panel_tracking.png"):
        edges = [line for ax in figures[name].axes for line in ax.lines if line.get_gid() == EDGE_GID]
        assert edges, name
        assert "every solver step" in figures[name].axes[0].get_title() or name == "fig12_rotor_angle.png"


def test_a_multi_day_axis_carries_dates(tmp_path):
    day = synthetic_trace(duration=20.0)
    long = day.assign(time=day["time"] * 3 * 86400.0 / 20.0)  # the same rows over three days
    figures = dict(run_plots.run_figures(long, METADATA))
    fig = figures["fig13_panel_tracking.png"]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    labels = [tick.get_text() for tick in fig.axes[-1].get_xticklabels()]
    assert any(label.startswith("Jan") or "Jan" in label for label in labels), labels
    assert "2025-01-21 to 2025-01-24" in fig.axes[0].get_title()
    short = dict(run_plots.run_figures(day, METADATA))["fig13_panel_tracking.png"]
    FigureCanvasAgg(short).draw()
    assert not any("Jan" in tick.get_text() for tick in short.axes[-1].get_xticklabels())


def test_the_wind_has_a_panel_where_the_scenario_has_wind(fmu_paths):
    from heliostep.paths import scenarios_dir
    from heliostep.run import run_scenario

    run = run_scenario(scenarios_dir() / "jan21-windy.yaml")
    source = run.held_trace if run.held_trace is not None else run.trace_file
    (fig,) = [
        f for _, f in run_plots.run_figures(source, run.trace_metadata(), run.solution_plot, ["fig11_torque.png"])
    ]
    assert len(fig.axes) == 2 and "wind moment" in fig.axes[1].get_ylabel()
    low, high = _drawn_extremes(fig.axes[1])
    assert max(abs(low), abs(high)) > 0.5 * run.summary["wind_peak_moment_Nm"]
    calm = dict(run_plots.run_figures(synthetic_trace(), METADATA))["fig11_torque.png"]  # m_ext all 0
    assert len(calm.axes) == 1
