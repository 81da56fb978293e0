"""Plots of one run's trace: the paper's Figs. 8-14.

Details: docs/running.md, ``heliostep.plots.run``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection, Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from heliostep.errors import InputError
from heliostep.plots.layout import LEGEND, RIGHT, fixed_axes, outside_legend
from heliostep.plots.png import save_png
from heliostep.plots.run_trace import TraceClock, TraceColumns, step_times
from heliostep.plots.thinning import EDGE_GID, Band, draw_band, min_max_line
from heliostep.results.figures.plot_data import ROTOR_LAG, TRACKING_ERROR, SolutionPlotData
from heliostep.results.output.run_files import (
    FIGURE_FILES,  # (PNG per figure, in the order drawn: named without matplotlib)
)
from heliostep.scenario import RolesConfig

__all__ = [
    "FIGURE_FILES",
    "TORQUE_ZOOM_LABEL",
    "ZOOM_HALF_WIDTH",
    "plot_run",
    "run_figures",
    "step_times",
]

logger = logging.getLogger(__name__)

#: Half width of the torque zoom around a step (Fig. 14) [s].
ZOOM_HALF_WIDTH = 0.1
#: Label of Fig. 14's line drawn from the solution rows (every solver step).
TORQUE_ZOOM_LABEL = "motor torque (every solver step)"

_DPI = 120
_WIDE = (11.5, 4.5)
_TALL = (11.5, 6.5)
_DEGREES = 180.0 / np.pi


# --------------------------------------------------------------------------- helpers
def _largest_torque_step(time: np.ndarray, torque: np.ndarray, steps: np.ndarray) -> tuple[int, int] | None:
    """(position in ``steps``, row of the peak) of the step followed by the largest |torque|.

    Each step owns the rows from its instant up to the next step; rows before the
    first step belong to none. None when no owned row has a finite torque.
    """
    if steps.size == 0:
        return None
    after_first = int(np.searchsorted(time, steps[0], side="left"))
    magnitude = np.abs(torque[after_first:])
    if not np.isfinite(magnitude).any():
        return None
    peak = after_first + int(np.nanargmax(magnitude))
    step = int(np.searchsorted(steps, time[peak], side="right")) - 1
    return step, peak


def _line(ax, clock: TraceClock, time: np.ndarray, values: np.ndarray, *args, **kwargs) -> None:
    """A curve of the output rows (a reference, the commanded angle), thinned to the pixels."""
    shown_time, shown = min_max_line(time, values)
    ax.plot(clock.x(shown_time), shown, *args, **kwargs)


def _figure(left: float, rows: int = 1, size=_WIDE, right: float = LEGEND):
    """A figure of ``rows`` panels sharing their time axis, ``left`` [in] for the y labels, ``right`` [in]
    for the legends beside them (a fixed layout)."""
    fig, axes = fixed_axes(size, rows, left, right=right)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig, axes


def _finish(fig: Figure, axes, clock: TraceClock) -> Figure:
    for ax in axes:
        outside_legend(ax, EDGE_GID)
    clock.format_axis(axes[-1])
    return fig


def _title(what: str, figure_number: int, context: str) -> str:
    return f"Fig. {figure_number}: {what}{context}"


# --------------------------------------------------------------------------- figures
def _band(ax, clock: TraceClock, band: Band | None, color, label: str, what: str, unit: str, worst: bool, **style):
    """Draw a series' envelope (nothing: None), with its largest magnitude marked when ``worst``."""
    if band is None:
        return None
    draw_band(ax, clock.x, band, color, label, what, **style)
    if worst:
        time, value = band.worst
        text = f"largest |{what}| = {abs(value):.4g} {unit} at {clock.label(time)}"
        ax.plot(clock.x(np.array([time])), [value], "o", color="C3", markersize=5, zorder=4, label=text)
    return band


def _series(trace: TraceColumns, solution: SolutionPlotData | None, column: str, rows=None, scale: float = 1.0):
    """A series' envelope: of every solver step where the solution has it, else of the output rows
    (``rows``: the values, else the trace's ``column``); times ``scale``; and where it comes from."""
    band = Band.of_solution(solution, column)
    if band is not None:
        return band.scaled(scale) if scale != 1.0 else band, "every solver step"
    values = rows if rows is not None else trace[column] if trace.has(column) else None
    band = None if values is None else Band.of_rows(trace.time, values)
    return (None if band is None else band.scaled(scale) if scale != 1.0 else band), "the output rows"


def _fig08(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    if not trace.has("panel_angle_ref"):
        return None
    fig, axes = _figure(0.95, right=RIGHT)
    _line(axes[0], clock, trace.time, trace.degrees("panel_angle_ref"), color="C0")
    axes[0].set_ylabel("panel angle reference [deg]")
    axes[0].set_title(_title("panel angle reference", 8, context))
    return _finish(fig, axes, clock)


def _fig09(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    if not trace.has("rotor_angle_ref"):
        return None
    fig, axes = _figure(0.85, right=RIGHT)
    _line(axes[0], clock, trace.time, trace.degrees("rotor_angle_ref"), color="C1")
    axes[0].set_ylabel("rotor angle reference [deg]")
    axes[0].set_title(_title("rotor angle reference (0 at the window start)", 9, context))
    return _finish(fig, axes, clock)


def _fig10(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    if not trace.has(trace.col("current_a"), trace.col("current_b")):
        return None
    fig, axes = _figure(0.7, 2, _TALL)
    source = ""
    for ax, phase, color in zip(axes, ("a", "b"), ("C0", "C9")):
        band, source = _series(trace, solution, trace.col(f"current_{phase}"))
        _band(ax, clock, band, color, f"actual i_{phase}", f"i_{phase}", "A", worst=True)
        if trace.has(f"i_{phase}_ref"):
            _line(
                ax, clock, trace.time, trace[f"i_{phase}_ref"], "--", color="k", linewidth=0.8, label=f"i_{phase},ref"
            )
        ax.set_ylabel(f"phase {phase.upper()} current [A]")
    axes[0].set_title(_title(f"phase currents, envelopes of {source}", 10, context))
    return _finish(fig, axes, clock)


def _fig11(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    column = trace.col("torque")
    if not trace.has(column):
        return None
    wind, _ = _series(trace, solution, "m_ext")
    windy = wind is not None and bool(np.any(wind.low != 0.0) or np.any(wind.high != 0.0))
    fig, axes = _figure(0.95 if windy else 0.8, 2 if windy else 1, _TALL if windy else _WIDE)
    band, source = _series(trace, solution, column)
    _band(axes[0], clock, band, "C2", "motor torque", "torque", "N.m", worst=True)
    axes[0].axhline(0.0, color="0.5", linewidth=0.8)
    axes[0].set_ylabel("motor torque [N.m]")
    axes[0].set_title(_title(f"motor torque, envelope of {source}", 11, context))
    if windy:
        _band(axes[1], clock, wind, "C4", "wind moment", "wind moment", "N.m", worst=True)
        axes[1].axhline(0.0, color="0.5", linewidth=0.8)
        axes[1].set_ylabel("wind moment [N.m]")
    return _finish(fig, axes, clock)


def _fig12(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    rotor = trace.col("rotor_angle")
    if not trace.has(rotor):
        return None
    commanded = trace.has("rotor_angle_cmd")
    fig, axes = _figure(0.9, 2 if commanded else 1, _TALL if commanded else _WIDE)
    ax = axes[0]
    if trace.has("rotor_angle_ref"):
        _line(
            ax, clock, trace.time, trace.degrees("rotor_angle_ref"), ":", color="0.4", linewidth=1.0, label="reference"
        )
    band, _ = _series(trace, solution, rotor, scale=_DEGREES)
    _band(ax, clock, band, "C0", "actual", "rotor angle", "deg", worst=False, linewidth=2.2, alpha=0.6)
    if commanded:  # a step line, thin and dashed on top of the actual one
        cmd = trace.degrees("rotor_angle_cmd")
        _line(ax, clock, trace.time, cmd, "--", color="C3", linewidth=1.0, label="commanded (sequencer)", zorder=3)
        lag, _ = _series(trace, solution, ROTOR_LAG, trace.degrees(rotor) - cmd, _DEGREES)
        _band(axes[1], clock, lag, "C3", "actual - commanded", "actual - commanded", "deg", worst=True)
        axes[1].axhline(0.0, color="0.5", linewidth=0.8)
        axes[1].set_ylabel("actual - commanded [deg]")
    ax.set_ylabel("rotor angle [deg]")
    ax.set_title(_title("rotor angle, commanded and actual", 12, context))
    return _finish(fig, axes, clock)


def _fig13(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    panel = trace.col("panel_angle")
    if not trace.has(panel, "panel_angle_ref"):
        return None
    fig, axes = _figure(1.15, 2, _TALL)
    desired = trace.degrees("panel_angle_ref")
    _line(axes[0], clock, trace.time, desired, "--", color="k", linewidth=1.2, label="desired (reference)", zorder=3)
    band, source = _series(trace, solution, panel, scale=_DEGREES)
    _band(axes[0], clock, band, "C0", "actual", "panel angle", "deg", worst=False)
    axes[0].set_ylabel("panel angle [deg]")
    axes[0].set_title(_title(f"panel tracking, envelopes of {source}", 13, context))
    error = trace.degrees("panel_angle_error") if trace.has("panel_angle_error") else trace.degrees(panel) - desired
    band, _ = _series(trace, solution, TRACKING_ERROR, error)
    _band(axes[1], clock, band, "C3", "tracking error", "tracking error", "deg", worst=True)
    axes[1].axhline(0.0, color="0.5", linewidth=0.8)
    axes[1].set_ylabel("tracking error,\nactual - desired [deg]")
    return _finish(fig, axes, clock)


def _fig14(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    if solution is not None and solution.peak_rows is not None and solution.peak_torque is not None:
        return _solution_zoom(solution, clock, context) if solution.step_count else None
    if not trace.has(trace.col("torque")):
        return None
    steps = trace.step_times()
    time, torque = trace.time, trace[trace.col("torque")]
    found = _largest_torque_step(time, torque, steps)
    if found is None:
        return None
    step, peak = found
    centre = steps[step]
    lo = np.searchsorted(time, centre - ZOOM_HALF_WIDTH, side="left")
    hi = np.searchsorted(time, centre + ZOOM_HALF_WIDTH, side="right")
    window_time, window_torque = time[lo:hi], torque[lo:hi]
    shown = min_max_line(window_time, window_torque)
    nearby = steps[(steps >= window_time[0]) & (steps <= window_time[-1])]
    title = f"torque around step {step + 1} of {steps.size}, the largest |torque| of the output rows"
    return _zoom(clock, context, title, centre, shown, nearby, (time[peak], torque[peak]), "motor torque (output rows)")


def _solution_zoom(solution: SolutionPlotData, clock: TraceClock, context: str) -> Figure:
    """Fig. 14 from the solution rows around the peak |torque| (its peak is ``summary.json``'s)."""
    time, torque = solution.column("time"), solution.column(solution.columns[1])
    peak = (float(solution.peak_time or 0.0), float(solution.peak_torque or 0.0))
    owning = solution.steps[solution.steps <= peak[0]]
    centre = float(owning[-1]) if owning.size else peak[0]
    what = f"step {solution.peak_step} of {solution.step_count}" if owning.size else "the peak"
    title = f"torque around {what}, the largest |torque| of the solution"
    return _zoom(clock, context, title, centre, (time, torque), solution.steps, peak, TORQUE_ZOOM_LABEL)


def _zoom(
    clock: TraceClock, context: str, title: str, centre: float, shown, steps: np.ndarray, peak, label: str
) -> Figure:
    """Fig. 14: torque against the time from ``centre`` [ms], the step instants and the peak marked."""
    fig, (ax,) = fixed_axes(_WIDE, 1, 0.8, right=LEGEND)
    ax.grid(True, alpha=0.3)
    time, torque = shown
    style = ".-" if time.size <= 400 else "-"
    ax.plot((time - centre) * 1e3, torque, style, color="C2", linewidth=1.0, markersize=3, label=label)
    for other in steps[steps != centre]:
        ax.axvline((other - centre) * 1e3, color="0.6", linestyle=":", linewidth=0.9)
    if np.any(steps == centre):
        ax.axvline(0.0, color="C1", linestyle="--", linewidth=0.9, label="step instant")
    peak_label = f"peak |torque| = {abs(peak[1]):.4g} N.m"
    ax.plot((peak[0] - centre) * 1e3, peak[1], "o", color="C3", markersize=5, label=peak_label)
    ax.axhline(0.0, color="0.5", linewidth=0.8)
    origin = "step" if np.any(steps == centre) else "peak"
    ax.set_xlabel(f"time from the {origin} at {clock.label(centre)} [ms]")
    ax.set_ylabel("motor torque [N.m]")
    ax.set_title(_title(title, 14, context), fontsize="medium")
    outside_legend(ax)
    return fig


def _tracking_loop(trace: TraceColumns, clock: TraceClock, context: str, solution=None) -> Figure | None:
    """A closed or hybrid loop: the law's and the panel's angle, the error, the sensor's signal and light."""
    panel = trace.col("panel_angle")
    if not trace.has("sensor.signal", "sensor.irradiance", "panel_angle_ref", "panel_angle_error", panel):
        return None
    fig, axes = _figure(1.0, rows=4, size=_TALL)
    _line(axes[0], clock, trace.time, trace.degrees("panel_angle_ref"), color="C0", label="tracking law")
    _line(axes[0], clock, trace.time, trace.degrees(panel), color="C1", label="panel")
    axes[0].set_ylabel("panel angle [deg]")
    _line(axes[1], clock, trace.time, trace.degrees("panel_angle_error"), color="C3", label="panel - law")
    axes[1].set_ylabel("error [deg]")
    _line(axes[2], clock, trace.time, trace["sensor.signal"], color="C2", label="(A - B) / (A + B)")
    axes[2].set_ylabel("sensor signal [-]")
    _line(axes[3], clock, trace.time, trace["sensor.irradiance"], color="C4", label="A + B")
    axes[3].set_ylabel("on the sensor [W/m2]")
    axes[0].set_title(f"Tracking loop: the law, the panel, the sun sensor{context}")
    return _finish(fig, axes, clock)


_FIGURES: tuple[tuple[str, Callable], ...] = tuple(
    zip(FIGURE_FILES, (_fig08, _fig09, _fig10, _fig11, _fig12, _fig13, _fig14, _tracking_loop))
)


# --------------------------------------------------------------------------- public
def run_figures(
    trace: pd.DataFrame | str | Path,
    metadata: Mapping | None,
    solution: SolutionPlotData | None = None,
    only: Collection[str] | None = None,
) -> Iterator[tuple[str, Figure | None]]:
    """The figures of :func:`plot_run`, one at a time: (file name, :class:`~matplotlib.figure.Figure`
    or None when skipped), for reading back what is drawn (same arguments as :func:`plot_run`)."""
    if isinstance(trace, (str, Path)):
        trace = Path(trace)
    elif not isinstance(trace, pd.DataFrame) or "time" not in trace.columns:
        raise InputError("trace must be a pandas DataFrame with a 'time' column [s] or a Parquet trace file")
    metadata = {} if metadata is None else metadata
    roles = {**RolesConfig().present(), **{k[5:]: v for k, v in metadata.items() if str(k).startswith("role.")}}
    columns = TraceColumns(trace, roles)
    if not columns.time.size:
        raise InputError("trace is empty: nothing to plot")
    if np.any(np.diff(columns.time) < 0.0) or not np.all(np.isfinite(columns.time)):
        raise InputError("trace time must be finite and non-decreasing")
    clock = TraceClock(metadata, columns.time)
    parts = [str(metadata["scenario"])] if metadata.get("scenario") else []
    if clock.start is not None:
        end = clock.start + pd.Timedelta(seconds=clock.span)
        days = f"{clock.start:%Y-%m-%d}" + (f" to {end:%Y-%m-%d}" if end.date() != clock.start.date() else "")
        parts.append(days)
    context = f" ({', '.join(parts)})" if parts else ""
    for file_name, draw in _FIGURES:
        if only is not None and file_name not in only:
            continue
        figure = draw(columns, clock, context, solution)
        columns.release()
        yield file_name, figure


def plot_run(
    trace: pd.DataFrame | str | Path,
    out_dir,
    metadata: Mapping,
    solution: SolutionPlotData | None = None,
    only: Collection[str] | None = None,
) -> list[Path]:
    """Write the paper's Figs. 8-14 for one run as PNGs (``only``: those of these file names).

    Parameters
    ----------
    trace : pandas.DataFrame, or the path of a Parquet trace
        From a file (a long window's streamed trace) only the columns each figure draws are
        read, one figure at a time. Column ``time`` [s from the window start], non-decreasing (a step instant
        has two rows with the same time, before and after), and any of
        ``panel_angle_ref``, ``rotor_angle_ref``, ``rotor_angle_cmd`` [rad],
        ``step_index``, ``i_a_ref``, ``i_b_ref``, ``motor.i_a``, ``motor.i_b`` [A],
        ``motor.tau`` [N.m], ``mechanics.theta`` [rad], ``mechanics.theta_p`` [rad],
        ``panel_angle_error`` [rad].
    out_dir : str or Path
        Folder for the PNGs, created if missing.
    metadata : Mapping
        ``window_start`` (ISO local time with offset, e.g. "2025-01-21T10:00:00+01:00"),
        ``timezone`` (IANA name), ``scenario`` (name, shown in the titles) and ``role.NAME``
        (the column of each role; default: the shipped FMUs' names). Without
        ``window_start`` the x axis is in seconds from the window start.
    solution : SolutionPlotData, optional
        What the run's solution recorder kept of every solver step (``RunResult.solution_plot``):
        Fig. 14 then draws the solution rows around the largest |torque| (its peak is
        ``summary.json``'s ``peak_torque_Nm``) and Figs. 10-13 the per-bin envelopes of the
        torque, currents, wind moment, rotor and panel angles, the rotor's lag and the tracking
        error (least, largest and mean over the solver steps in each of about one bin per pixel
        column, the largest magnitude marked: ``summary.json``'s figure). Without it (a stored
        trace) they draw the envelopes of the trace's rows. References and the commanded angle
        are drawn from the trace's rows.

    Returns
    -------
    list of Path
        The PNGs written, in figure order (names in :data:`FIGURE_FILES`): a figure
        whose columns are missing is skipped, and so is Fig. 14 without steps.
    """
    figures = run_figures(trace, metadata, solution, only)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for file_name, figure in figures:
        if figure is None:
            logger.info("%s skipped: its columns (or steps) are not in the trace", file_name)
            continue
        save_png(figure, out_dir / file_name, _DPI)
        written.append(out_dir / file_name)
    return written
