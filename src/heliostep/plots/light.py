"""Plot of one run's light on the tube: power over the window, ideal tracking against the drive.

Details: docs/light.md, ``heliostep.plots.light``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from heliostep.plots.layout import LEGEND, fixed_axes, outside_legend
from heliostep.plots.png import save_png
from heliostep.plots.run_trace import TraceClock
from heliostep.plots.thinning import EDGE_GID, Band, draw_band, min_max_line
from heliostep.plots.units import si_scale
from heliostep.results.figures.plot_data import ENVELOPE_BINS
from heliostep.results.light.on_tube import light_timeseries
from heliostep.results.output.run_files import POWER_FILE  # (named where matplotlib is not imported)

__all__ = ["POWER_FILE", "light_figure", "plot_light", "plot_light_run"]

#: PNG of the power on the tube.
_DPI = 120
#: Left of the panels [in]: the powers' tick labels (e.g. 0.0435, -0.0010) and the axis labels.
_LEFT = 1.05


#: What a note of ``light_notes`` says of a figure whose curve is not drawn.
_NOT_SHOWN = ("not meaningful", " is exactly 0", " is 0:")
#: The run's figure of each curve's energy (its label's start), for the legends.
FIGURE_OF = {
    "ideal two-axis tracking": "light_energy_ideal_J",
    "reference (the drive's law), shared primary": "light_energy_reference_J",
    "actual panel (co-simulated)": "light_energy_J",
    "shared primary (ideal - shared)": "light_lost_shared_primary_J",
    "reference law (shared - reference)": "light_lost_reference_law_J",
    "stepping change (actual - reference): not a loss": "light_stepping_change_J",
    "its first-order term": "light_stepping_first_order_J",
}


def _energy_text(power: np.ndarray, time: np.ndarray, figure: float | None = None) -> str:
    """The energy of a power series (``figure`` [J] where given, else its trapezoid), in kJ (or J below 1 kJ)."""
    energy = figure if figure is not None else float(np.trapezoid(power, time)) if len(time) > 1 else 0.0
    return f"{energy / 1e3:,.1f} kJ" if abs(energy) >= 1e3 else f"{energy:.3g} J"


def plot_light(
    series: Mapping | pd.DataFrame, path: str | Path, metadata: Mapping, title: str = "", figures: Mapping | None = None
) -> Path | None:
    """Power on the tube over the window (:func:`light_figure`), written to ``path``.

    Parameters
    ----------
    series : pandas.DataFrame or Mapping of arrays
        :func:`heliostep.results.light.on_tube.light_timeseries`: ``time`` [s], ``power_ideal_W``,
        ``power_reference_W`` and (optionally) ``power_shared_W``, ``power_actual_W`` and
        ``stepping_first_order_W`` [W].
    path : str or Path
        PNG to write.
    metadata : Mapping
        ``window_start`` and ``timezone`` for a clock-time axis (else seconds).
    title : str, default ""
        Appended to the figure's title (e.g. the scenario's name).
    figures : Mapping, optional
        The run's light figures (``summary.json``), for the legends' energies (:data:`FIGURE_OF`).

    Returns
    -------
    Path or None
        None when the series has fewer than two rows.
    """
    fig = light_figure(series, metadata, title, figures)
    if fig is None:
        return None
    path = Path(path)
    save_png(fig, path, _DPI)
    return path


def light_figure(
    series: Mapping | pd.DataFrame, metadata: Mapping, title: str = "", figures: Mapping | None = None
) -> Figure | None:
    """The figure of :func:`plot_light`: the powers on an axis zoomed to them; below, the shared
    primary's loss and the reference law's part; with the actual panel, a panel of the stepping's
    change and its first-order term; each in the unit its values read in (W, mW, kW: :func:`si_scale`;
    a long difference as its envelope, :func:`~heliostep.plots.thinning.draw_band`). A curve whose
    figure ``figures``' ``light_notes`` call not meaningful or exactly 0 is not drawn, nor a panel left
    without curves. None for fewer than two rows. ``series``:
    :func:`~heliostep.results.light.on_tube.light_timeseries`' frame, or its columns as arrays."""
    time = np.asarray(series["time"], dtype=float)
    if len(time) < 2:
        return None
    clock = TraceClock(metadata, time)
    ideal, reference = (np.asarray(series[key], dtype=float) for key in ("power_ideal_W", "power_reference_W"))
    shared = np.asarray(series["power_shared_W"], dtype=float) if "power_shared_W" in series else ideal
    actual = np.asarray(series["power_actual_W"], dtype=float) if "power_actual_W" in series else None
    given = dict(figures or {})
    sharing = [
        (ideal - shared, "shared primary (ideal - shared)", "C1", "-"),
        (shared - reference, "reference law (shared - reference)", "C2", ":"),
    ]
    panels = [(_meaningful(sharing, given), "power lost")]
    if actual is not None:
        stepping = [(actual - reference, "stepping change (actual - reference): not a loss", "C0", "-")]
        if "stepping_first_order_W" in series:
            first = np.asarray(series["stepping_first_order_W"], dtype=float)
            stepping.append((first, "its first-order term", "k", "--"))
        panels.append((_meaningful(stepping, given), "power change"))
    panels = [(curves, what) for curves, what in panels if curves]
    rows = 1 + len(panels)
    size = (11.5, 3.0 + 2.0 * rows)
    fig, axes = fixed_axes(size, rows, _LEFT, height_ratios=(2,) + (1,) * (rows - 1), right=LEGEND)
    _draw_power(axes[0], clock, time, ideal, reference, actual, title, given)
    for ax, (curves, what) in zip(axes[1:], panels):
        _draw_differences(ax, clock, time, curves, what, given)
    for ax in axes:
        ax.grid(True, alpha=0.3)
        outside_legend(ax, EDGE_GID)
    clock.format_axis(axes[-1])
    return fig


def _meaningful(curves: list, given: Mapping) -> list:
    """The curves whose figure (:data:`FIGURE_OF`) the run's ``light_notes`` do not call not meaningful
    or exactly 0 (all of them without notes)."""
    notes = [str(note) for note in given.get("light_notes", [])]

    def said(figure: str | None) -> bool:
        return figure is not None and any(
            note.startswith(figure) and any(word in note for word in _NOT_SHOWN) for note in notes
        )

    return [curve for curve in curves if not said(FIGURE_OF.get(curve[1]))]


def _draw_power(
    top,
    clock: TraceClock,
    time: np.ndarray,
    ideal: np.ndarray,
    reference: np.ndarray,
    actual: np.ndarray | None,
    title: str,
    given: Mapping,
) -> None:
    """The upper panel: the powers with their energies, the axis zoomed to them (autoscaled)."""
    lines = [
        (ideal, "ideal two-axis tracking", "k", "--", 1.6),
        (reference, "reference (the drive's law), shared primary", "C1", ":", 1.4),
    ]
    if actual is not None:
        lines.append((actual, "actual panel (co-simulated)", "C0", "-", 1.0))
    factor, unit = si_scale(*(values for values, *_ in lines), unit="W")
    for values, label, color, style, width in lines:
        shown_time, shown = min_max_line(time, values * factor)
        text = f"{label}: {_energy_text(values, time, given.get(FIGURE_OF[label]))}"
        top.plot(clock.x(shown_time), shown, style, color=color, linewidth=width, label=text)
    top.set_ylabel(f"power on the tube [{unit}]")
    top.set_title(f"Light absorbed by the tube{title}", fontsize="medium")  # (a long scenario name fits)


def _draw_differences(ax, clock: TraceClock, time: np.ndarray, curves: list, what: str, given: Mapping) -> None:
    """A panel of power differences [W] (values, label, colour, style), each with its energy, in the unit
    they read in; a curve of more rows than a figure has pixel columns drawn as its envelope."""
    factor, unit = si_scale(*(values for values, *_ in curves), unit="W")
    for values, label, color, style in curves:
        text = f"{label}: {_energy_text(values, time, given.get(FIGURE_OF[label]))}"
        band = Band.of_rows(time, values * factor) if len(time) > 2 * ENVELOPE_BINS else None
        if band is not None:
            draw_band(ax, clock.x, band, color, text, label)
        else:
            shown_time, shown = min_max_line(time, values * factor)
            ax.plot(clock.x(shown_time), shown, style, color=color, linewidth=1.0, label=text)
    ax.axhline(0.0, color="0.5", linewidth=0.8)
    ax.set_ylabel(f"{what} [{unit}]")


def plot_light_run(
    trace: pd.DataFrame,
    metadata: Mapping,
    scenario,
    out_dir: str | Path,
    weather=None,
    figures: Mapping | None = None,
) -> list[Path]:
    """Write ``POWER_FILE`` for a run (its trace, metadata and scenario; ``weather``, its weather
    file already read, see :func:`heliostep.results.light.on_tube.light_timeseries`; ``figures``, its light figures for
    the legends) into ``out_dir``.

    Returns
    -------
    list of Path
        The PNG written; empty for a trace of fewer than two rows.
    """
    if len(trace) < 2:
        return []
    series = light_timeseries(trace, metadata, scenario, weather)
    mirror = scenario.mirror
    title = (
        f" ({scenario.name}, {scenario.window.date}, mirror at d = {mirror.mirror_distance:g} m, {mirror.axis} driven)"
    )
    path = plot_light(series, Path(out_dir) / POWER_FILE, metadata, title, figures)
    return [] if path is None else [path]
