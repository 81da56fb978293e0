"""Plot of one run's light on the tube: power over the window, ideal tracking against the drive.

Details: docs/light.md, ``heliostep.plots.light``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from heliostep.plots.layout import fixed_axes
from heliostep.plots.png import save_png
from heliostep.plots.run import _Clock
from heliostep.plots.thinning import thin
from heliostep.results.light.on_tube import light_timeseries
from heliostep.results.output.run_files import POWER_FILE  # (named where matplotlib is not imported)

__all__ = ["POWER_FILE", "light_figure", "plot_light", "plot_light_run"]

#: PNG of the power on the tube.
_DPI = 120
_MAX_BUCKETS = 2000
#: Left of the panels [in]: the powers' tick labels (e.g. 0.0435, -0.0010) and the axis labels.
_LEFT = 1.05


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
    """The figure of :func:`plot_light`: the powers [kW] on an axis zoomed to them; below, the
    shared primary's loss and the reference law's part [W]; with the actual panel, a third panel
    of the stepping's change and its first-order term [W]. None for fewer than two rows. ``series``:
    :func:`~heliostep.results.light.on_tube.light_timeseries`' frame, or its columns as arrays."""
    time = np.asarray(series["time"], dtype=float)
    if len(time) < 2:
        return None
    clock = _Clock(metadata, time)
    ideal, reference = (np.asarray(series[key], dtype=float) for key in ("power_ideal_W", "power_reference_W"))
    shared = np.asarray(series["power_shared_W"], dtype=float) if "power_shared_W" in series else ideal
    actual = np.asarray(series["power_actual_W"], dtype=float) if "power_actual_W" in series else None
    rows = 2 if actual is None else 3
    fig, axes = fixed_axes((9.0, 3.0 + 2.0 * rows), rows, _LEFT, height_ratios=(2,) + (1,) * (rows - 1))
    given = dict(figures or {})
    _draw_power(axes[0], clock, time, ideal, reference, actual, title, given)
    sharing = [
        (ideal - shared, "shared primary (ideal - shared)", "C1", "-"),
        (shared - reference, "reference law (shared - reference)", "C2", ":"),
    ]
    _draw_differences(axes[1], clock, time, sharing, "power lost [W]", given)
    if actual is not None:
        stepping = [(actual - reference, "stepping change (actual - reference): not a loss", "C0", "-")]
        if "stepping_first_order_W" in series:
            first = np.asarray(series["stepping_first_order_W"], dtype=float)
            stepping.append((first, "its first-order term", "k", "--"))
        _draw_differences(axes[2], clock, time, stepping, "power change [W]", given)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    clock.format_axis(axes[-1])
    return fig


def _draw_power(
    top,
    clock: _Clock,
    time: np.ndarray,
    ideal: np.ndarray,
    reference: np.ndarray,
    actual: np.ndarray | None,
    title: str,
    given: Mapping,
) -> None:
    """The upper panel: the powers [kW] with their energies, the axis zoomed to them (autoscaled)."""
    lines = [
        (ideal, "ideal two-axis tracking", "k", "--", 1.6),
        (reference, "reference (the drive's law), shared primary", "C1", ":", 1.4),
    ]
    if actual is not None:
        lines.append((actual, "actual panel (co-simulated)", "C0", "-", 1.0))
    for values, label, color, style, width in lines:
        keep = thin(time, values, max_buckets=_MAX_BUCKETS)
        top.plot(
            clock.x(time[keep]),
            values[keep] / 1e3,
            style,
            color=color,
            linewidth=width,
            label=f"{label}: {_energy_text(values, time, given.get(FIGURE_OF[label]))}",
        )
    top.set_ylabel("power on the tube [kW]")
    top.legend(loc="best", fontsize="small")
    top.set_title(f"Light absorbed by the tube{title}", fontsize="medium")  # (a long scenario name fits)


def _draw_differences(ax, clock: _Clock, time: np.ndarray, curves: list, ylabel: str, given: Mapping) -> None:
    """A panel of power differences [W] (values, label, colour, style), each with its energy."""
    for values, label, color, style in curves:
        keep = thin(time, values, max_buckets=_MAX_BUCKETS)
        ax.plot(
            clock.x(time[keep]),
            values[keep],
            style,
            color=color,
            linewidth=1.0,
            label=f"{label}: {_energy_text(values, time, given.get(FIGURE_OF[label]))}",
        )
    ax.axhline(0.0, color="0.5", linewidth=0.8)
    ax.set_ylabel(ylabel)
    ax.legend(loc="best", fontsize="small")


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
