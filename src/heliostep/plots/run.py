"""Plots of one run's trace: the paper's Figs. 8-14.

Details: docs/running.md, ``heliostep.plots.run``.
"""

from __future__ import annotations

import logging
import zoneinfo
from collections.abc import Callable, Collection, Iterator, Mapping
from pathlib import Path

import matplotlib.dates as mdates
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from heliostep.errors import InputError
from heliostep.plots.layout import fixed_axes
from heliostep.plots.png import save_png
from heliostep.plots.thinning import thin
from heliostep.results.figures.solution import SolutionPlotData
from heliostep.results.output.run_files import (
    FIGURE_FILES,  # (PNG per figure, in the order drawn: named without matplotlib)
)
from heliostep.scenario import RolesConfig

__all__ = [
    "FIGURE_FILES",
    "LINE_WITH_ENVELOPE_MAX_SPAN",
    "MAX_BUCKETS",
    "TORQUE_ZOOM_LABEL",
    "ZOOM_HALF_WIDTH",
    "plot_run",
    "run_figures",
    "step_times",
]

logger = logging.getLogger(__name__)

#: Time buckets per drawn line; each keeps at most 4 samples (first, last, min, max).
MAX_BUCKETS = 2000
#: Half width of the torque zoom around a step (Fig. 14) [s].
ZOOM_HALF_WIDTH = 0.1
#: Longest window [s] whose Figs. 10-11 draw the output rows' line over the solution's envelope.
LINE_WITH_ENVELOPE_MAX_SPAN = 3600.0
#: Label of Fig. 14's line drawn from the solution rows (every solver step).
TORQUE_ZOOM_LABEL = "motor torque (every solver step)"

_DPI = 120
_WIDE = (9.0, 4.5)
_TALL = (9.0, 6.5)


# --------------------------------------------------------------------------- helpers
def step_times(trace: pd.DataFrame) -> np.ndarray:
    """Instants at which the sequencer steps: where ``step_index`` changes.

    Parameters
    ----------
    trace : pandas.DataFrame
        Columns ``time`` [s] and ``step_index``.

    Returns
    -------
    numpy.ndarray  [s]
        Time of the first row with the new index (empty without steps or without
        a ``step_index`` column).
    """
    if "step_index" not in trace or "time" not in trace:
        return np.empty(0)
    index = trace["step_index"].to_numpy(dtype=float)
    changed = np.flatnonzero(np.diff(index) != 0.0) + 1
    changed = changed[np.isfinite(index[changed]) & np.isfinite(index[changed - 1])]
    return trace["time"].to_numpy(dtype=float)[changed]


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


class _Clock:
    """Maps the trace's time [s from the window start] to the x axis: local clock time."""

    def __init__(self, metadata: Mapping, time: np.ndarray):
        self.start = None
        self.tz = None
        start_text = metadata.get("window_start")
        timezone = metadata.get("timezone")
        if start_text is not None:
            try:
                start = pd.Timestamp(start_text)
            except (TypeError, ValueError) as exc:
                raise InputError(f"metadata window_start {start_text!r} is not a date/time: {exc}") from None
            try:
                tz = zoneinfo.ZoneInfo(timezone) if timezone else None
            except (zoneinfo.ZoneInfoNotFoundError, ValueError):
                raise InputError(f"metadata timezone {timezone!r} is not an IANA name") from None
            if start.tzinfo is None:
                start = start.tz_localize(tz or "UTC")
            self.start = start.tz_convert(tz) if tz is not None else start
            self.tz = self.start.tzinfo
        self.span = float(time[-1] - time[0]) if time.size else 0.0
        self._origin = None if self.start is None else mdates.date2num(self.start.to_pydatetime())

    def x(self, time: np.ndarray) -> np.ndarray:
        """x values (matplotlib dates, or seconds without a window start) of times [s]."""
        return time if self._origin is None else self._origin + time / 86400.0

    def format_axis(self, ax) -> None:
        """Ticks and label of a time axis."""
        if self._origin is None:
            ax.set_xlabel("time from the window start [s]")
            return
        ax.xaxis.set_major_locator(mdates.AutoDateLocator(tz=self.tz, minticks=4, maxticks=9))
        pattern = "%H:%M:%S" if self.span <= 3600.0 else "%H:%M"
        ax.xaxis.set_major_formatter(mdates.DateFormatter(pattern, tz=self.tz))
        shown = "hh:mm:ss" if pattern == "%H:%M:%S" else "hh:mm"
        ax.set_xlabel(f"local time ({self.tz}) [{shown}]")

    def label(self, time: float) -> str:
        """A trace time as local clock time (or seconds)."""
        if self.start is None:
            return f"t = {time:.4f} s"
        return (self.start + pd.Timedelta(seconds=float(time))).strftime("%H:%M:%S.%f")[:-3]


class _Trace:
    """Columns of a trace as float arrays, fetched on demand; FMU columns found by role.

    The trace is a DataFrame or a Parquet trace file; from a file only the columns a figure
    draws are read, and :meth:`release` drops them once it is drawn (a long trace is never
    loaded whole).
    """

    def __init__(self, source: pd.DataFrame | Path, roles: Mapping[str, str]):
        self.roles = dict(roles)
        self._cache: dict[str, np.ndarray] = {}
        if isinstance(source, pd.DataFrame):
            self.frame, self.path = source, None
            self.columns = [str(c) for c in source.columns]
            self.time = source["time"].to_numpy(dtype=float)
        else:
            import pyarrow.parquet as pq

            self.frame, self.path = None, Path(source)
            try:
                self.columns = list(pq.read_schema(self.path).names)
            except Exception as exc:  # pyarrow raises several types for bad files
                raise InputError(f"{self.path}: cannot read as Parquet: {exc}") from None
            if "time" not in self.columns:
                raise InputError(f"{self.path}: trace has no 'time' column")
            self.time = self._read("time")

    def _read(self, column: str) -> np.ndarray:
        if self.frame is not None:
            return self.frame[column].to_numpy(dtype=float)
        import pyarrow.parquet as pq

        # ParquetFile.read takes the name as it is (read_table would split "motor.tau" at the dot)
        return pq.ParquetFile(self.path).read(columns=[column]).column(0).to_numpy().astype(float, copy=False)

    def release(self) -> None:
        """Forget the columns read from a file (a DataFrame's stay: they cost nothing)."""
        if self.path is not None:
            self._cache = {}

    def step_times(self) -> np.ndarray:
        if not self.has("step_index"):
            return np.empty(0)
        return step_times(pd.DataFrame({"time": self.time, "step_index": self["step_index"]}))

    def col(self, role: str) -> str:
        """The column of a role (a name no trace has when the role is absent)."""
        return self.roles.get(role, f"<no {role}>")

    def has(self, *columns: str) -> bool:
        return all(column in self.columns for column in columns)

    def __getitem__(self, column: str) -> np.ndarray:
        if column not in self._cache:
            self._cache[column] = self._read(column)
        return self._cache[column]

    def degrees(self, column: str) -> np.ndarray:
        return np.degrees(self[column])


def _line(ax, clock: _Clock, time: np.ndarray, values: np.ndarray, *args, **kwargs) -> None:
    keep = thin(time, values, max_buckets=MAX_BUCKETS)
    ax.plot(clock.x(time[keep]), values[keep], *args, **kwargs)


def _figure(left: float, rows: int = 1, size=_WIDE):
    """A figure of ``rows`` panels sharing their time axis, ``left`` [in] for the y labels (a fixed layout)."""
    fig, axes = fixed_axes(size, rows, left)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig, axes


def _finish(fig: Figure, axes, clock: _Clock) -> Figure:
    clock.format_axis(axes[-1])
    return fig


def _title(what: str, figure_number: int, context: str) -> str:
    return f"Fig. {figure_number}: {what}{context}"


# --------------------------------------------------------------------------- figures
def _envelope(ax, clock: _Clock, solution: SolutionPlotData | None, column: str, color, what: str, unit: str) -> bool:
    """Draw ``column``'s per-bin min and max over every solver step, its largest magnitude marked
    (False, nothing drawn: no envelope of that column)."""
    if solution is None or solution.edges is None or column not in solution.maximum:
        return False
    x = clock.x(solution.edges)
    low, high = solution.minimum[column], solution.maximum[column]
    low, high = np.r_[low, low[-1]], np.r_[high, high[-1]]  # the last bin drawn to its end
    width = float(solution.edges[1] - solution.edges[0])
    ax.fill_between(x, low, high, step="post", color=color, alpha=0.35, linewidth=0.0)
    ax.plot(x, high, drawstyle="steps-post", color=color, linewidth=0.7, label=f"{what}: max per {width:.3g} s bin")
    ax.plot(x, low, drawstyle="steps-post", color=color, linewidth=0.7, label=f"{what}: min per {width:.3g} s bin")
    time, value = solution.worst[column]
    label = f"largest |{what}| = {abs(value):.4g} {unit} at {clock.label(time)}"
    ax.plot(clock.x(np.array([time])), [value], "o", color="C3", markersize=5, zorder=4, label=label)
    return True


def _with_rows(solution: SolutionPlotData | None, clock: _Clock) -> bool:
    """Whether the output rows are drawn too: without an envelope, or over a short window."""
    return solution is None or solution.edges is None or clock.span <= LINE_WITH_ENVELOPE_MAX_SPAN


def _fig08(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
    if not trace.has("panel_angle_ref"):
        return None
    fig, axes = _figure(0.95)
    _line(axes[0], clock, trace.time, trace.degrees("panel_angle_ref"), color="C0")
    axes[0].set_ylabel("panel angle reference [deg]")
    axes[0].set_title(_title("panel angle reference", 8, context))
    return _finish(fig, axes, clock)


def _fig09(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
    if not trace.has("rotor_angle_ref"):
        return None
    fig, axes = _figure(0.85)
    _line(axes[0], clock, trace.time, trace.degrees("rotor_angle_ref"), color="C1")
    axes[0].set_ylabel("rotor angle reference [deg]")
    axes[0].set_title(_title("rotor angle reference (0 at the window start)", 9, context))
    return _finish(fig, axes, clock)


def _fig10(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
    if not trace.has(trace.col("current_a"), trace.col("current_b")):
        return None
    fig, axes = _figure(0.7, 2, _TALL)
    for ax, phase, color in zip(axes, ("a", "b"), ("C0", "C3")):
        column = trace.col(f"current_{phase}")
        enveloped = _envelope(ax, clock, solution, column, "C0" if phase == "a" else "C9", f"i_{phase}", "A")
        if not enveloped or _with_rows(solution, clock):
            _line(ax, clock, trace.time, trace[column], "-", color=color, linewidth=1.0, label=f"actual i_{phase}")
        if trace.has(f"i_{phase}_ref"):
            _line(
                ax, clock, trace.time, trace[f"i_{phase}_ref"], "--", color="k", linewidth=0.8, label=f"i_{phase},ref"
            )
        ax.set_ylabel(f"phase {phase.upper()} current [A]")
        ax.legend(loc="best", fontsize="small")
    what = "per-bin envelopes of every solver step" if solution is not None and solution.edges is not None else ""
    axes[0].set_title(_title(f"phase currents{', ' + what if what else ''}", 10, context))
    return _finish(fig, axes, clock)


def _fig11(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
    column = trace.col("torque")
    if not trace.has(column):
        return None
    fig, axes = _figure(0.8)
    enveloped = _envelope(axes[0], clock, solution, column, "C2", "torque", "N.m")
    if not enveloped or _with_rows(solution, clock):
        _line(axes[0], clock, trace.time, trace[column], color="C2", linewidth=1.0, label="output rows")
    axes[0].axhline(0.0, color="0.5", linewidth=0.8)
    axes[0].set_ylabel("motor torque [N.m]")
    what = ", per-bin envelope of every solver step" if enveloped else ""
    axes[0].set_title(_title(f"motor torque{what}", 11, context))
    if enveloped:
        axes[0].legend(loc="best", fontsize="small")
    return _finish(fig, axes, clock)


def _fig12(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
    rotor = trace.col("rotor_angle")
    if not trace.has(rotor):
        return None
    commanded = trace.has("rotor_angle_cmd")
    fig, axes = _figure(0.9, 2 if commanded else 1, _TALL if commanded else _WIDE)
    ax = axes[0]
    actual = trace.degrees(rotor)
    if trace.has("rotor_angle_ref"):
        _line(
            ax, clock, trace.time, trace.degrees("rotor_angle_ref"), ":", color="0.4", linewidth=1.0, label="reference"
        )
    _line(ax, clock, trace.time, actual, "-", color="C0", linewidth=2.2, alpha=0.6, label="actual", zorder=2)
    if commanded:  # a step line, thin and dashed on top of the actual one
        cmd = trace.degrees("rotor_angle_cmd")
        _line(ax, clock, trace.time, cmd, "--", color="C3", linewidth=1.0, label="commanded (sequencer)", zorder=3)
        _line(axes[1], clock, trace.time, actual - cmd, "-", color="C3", linewidth=0.9)
        axes[1].axhline(0.0, color="0.5", linewidth=0.8)
        axes[1].set_ylabel("actual - commanded [deg]")
    ax.set_ylabel("rotor angle [deg]")
    ax.set_title(_title("rotor angle, commanded and actual", 12, context))
    ax.legend(loc="best")
    return _finish(fig, axes, clock)


def _fig13(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
    if not trace.has(trace.col("panel_angle"), "panel_angle_ref"):
        return None
    fig, axes = _figure(0.95, 2, _TALL)
    desired, actual = trace.degrees("panel_angle_ref"), trace.degrees(trace.col("panel_angle"))
    _line(axes[0], clock, trace.time, desired, "--", color="k", linewidth=1.2, label="desired (reference)")
    _line(axes[0], clock, trace.time, actual, "-", color="C0", linewidth=1.0, label="actual")
    axes[0].set_ylabel("panel angle [deg]")
    axes[0].set_title(_title("panel tracking", 13, context))
    axes[0].legend(loc="best")
    error = trace.degrees("panel_angle_error") if trace.has("panel_angle_error") else actual - desired
    _line(axes[1], clock, trace.time, error, color="C3", linewidth=1.0)
    axes[1].axhline(0.0, color="0.5", linewidth=0.8)
    axes[1].set_ylabel("tracking error, actual - desired [deg]")
    return _finish(fig, axes, clock)


def _fig14(trace: _Trace, clock: _Clock, context: str, solution=None) -> Figure | None:
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
    keep = thin(window_time, window_torque, max_buckets=MAX_BUCKETS)
    shown = window_time[keep], window_torque[keep]
    nearby = steps[(steps >= window_time[0]) & (steps <= window_time[-1])]
    title = f"torque around step {step + 1} of {steps.size}, the largest |torque| of the output rows"
    return _zoom(clock, context, title, centre, shown, nearby, (time[peak], torque[peak]), "motor torque (output rows)")


def _solution_zoom(solution: SolutionPlotData, clock: _Clock, context: str) -> Figure:
    """Fig. 14 from the solution rows around the peak |torque| (its peak is ``summary.json``'s)."""
    time, torque = solution.column("time"), solution.column(solution.columns[1])
    peak = (float(solution.peak_time or 0.0), float(solution.peak_torque or 0.0))
    owning = solution.steps[solution.steps <= peak[0]]
    centre = float(owning[-1]) if owning.size else peak[0]
    what = f"step {solution.peak_step} of {solution.step_count}" if owning.size else "the peak"
    title = f"torque around {what}, the largest |torque| of the solution"
    return _zoom(clock, context, title, centre, (time, torque), solution.steps, peak, TORQUE_ZOOM_LABEL)


def _zoom(clock: _Clock, context: str, title: str, centre: float, shown, steps: np.ndarray, peak, label: str) -> Figure:
    """Fig. 14: torque against the time from ``centre`` [ms], the step instants and the peak marked."""
    fig, (ax,) = fixed_axes(_WIDE, 1, 0.8)
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
    ax.legend(loc="best")
    return fig


_FIGURES: tuple[tuple[str, Callable], ...] = tuple(
    zip(FIGURE_FILES, (_fig08, _fig09, _fig10, _fig11, _fig12, _fig13, _fig14))
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
    columns = _Trace(trace, roles)
    if not columns.time.size:
        raise InputError("trace is empty: nothing to plot")
    if np.any(np.diff(columns.time) < 0.0) or not np.all(np.isfinite(columns.time)):
        raise InputError("trace time must be finite and non-decreasing")
    clock = _Clock(metadata, columns.time)
    parts = [str(metadata["scenario"])] if metadata.get("scenario") else []
    if clock.start is not None:
        parts.append(f"{clock.start:%Y-%m-%d}")
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
        ``summary.json``'s ``peak_torque_Nm``) and Figs. 10-11 the per-bin envelopes (min and
        max over the solver steps in each bin, the largest magnitude marked), with the output
        rows' line over windows up to :data:`LINE_WITH_ENVELOPE_MAX_SPAN`. Without it (a stored
        trace) they draw the trace's rows.

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
