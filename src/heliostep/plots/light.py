"""Plot of one run's light on the tube: power over the window, ideal tracking against the drive.

:func:`plot_light` draws :func:`heliostep.results.light.light_timeseries`'s power on the tube
(absorbed, [kW]) for ideal two-axis tracking, for the stepped reference with the shared primary
and for the actual panel, and below it what the drive loses against ideal tracking [W], split
into the shared primary's part and the stepping part. The legend gives each energy [kJ, or J below 1 kJ].
:func:`plot_light_run` computes the series from a run and writes ``POWER_FILE``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from heliostep.plots.run import _Clock
from heliostep.plots.thinning import thin
from heliostep.results.light import light_timeseries

__all__ = ["POWER_FILE", "plot_light", "plot_light_run"]

#: PNG of the power on the tube.
POWER_FILE = "power_on_tube.png"
_DPI = 120
_MAX_BUCKETS = 2000


def _energy_text(power: np.ndarray, time: np.ndarray) -> str:
    """The energy of a power series, in kJ (or J below 1 kJ)."""
    energy = float(np.trapezoid(power, time)) if len(time) > 1 else 0.0
    return f"{energy / 1e3:,.1f} kJ" if abs(energy) >= 1e3 else f"{energy:.3g} J"


def plot_light(series: pd.DataFrame, path: str | Path, metadata: Mapping, title: str = "") -> Path | None:
    """Power on the tube over the window: ideal, stepped reference and actual; the losses below.

    Parameters
    ----------
    series : pandas.DataFrame
        :func:`heliostep.results.light.light_timeseries`: ``time`` [s], ``power_ideal_W``,
        ``power_reference_W`` and (optionally) ``power_actual_W`` [W].
    path : str or Path
        PNG to write.
    metadata : Mapping
        ``window_start`` and ``timezone`` for a clock-time axis (else seconds).
    title : str, default ""
        Appended to the figure's title (e.g. the scenario's name).

    Returns
    -------
    Path or None
        None when the series has fewer than two rows.
    """
    if len(series) < 2:
        return None
    time = series["time"].to_numpy(dtype=float)
    clock = _Clock(metadata, time)
    ideal, reference = series["power_ideal_W"].to_numpy(), series["power_reference_W"].to_numpy()
    actual = series["power_actual_W"].to_numpy() if "power_actual_W" in series else None
    fig = Figure(figsize=(9.0, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    _draw_power(top, clock, time, ideal, reference, actual, title)
    _draw_losses(bottom, clock, time, ideal, reference, actual)
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    clock.format_axis(bottom)
    path = Path(path)
    fig.savefig(path, dpi=_DPI)
    return path


def _draw_power(
    top,
    clock: _Clock,
    time: np.ndarray,
    ideal: np.ndarray,
    reference: np.ndarray,
    actual: np.ndarray | None,
    title: str,
) -> None:
    """The upper panel of :func:`plot_light`: the powers [kW] with their energies."""
    lines = [
        (ideal, "ideal two-axis tracking", "k", "--", 1.6),
        (reference, "stepped reference, shared primary", "C1", ":", 1.4),
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
            label=f"{label}: {_energy_text(values, time)}",
        )
    top.set_ylabel("power on the tube [kW]")
    top.set_ylim(bottom=0.0)
    top.legend(loc="best", fontsize="small")
    top.set_title(f"Light absorbed by the tube{title}")


def _draw_losses(
    bottom, clock: _Clock, time: np.ndarray, ideal: np.ndarray, reference: np.ndarray, actual: np.ndarray | None
) -> None:
    """The lower panel of :func:`plot_light`: the power lost [W] to sharing the primary and to stepping."""
    losses = [(ideal - reference, "shared primary (ideal - reference)", "C1")]
    if actual is not None:
        losses.append((reference - actual, "stepping (reference - actual)", "C0"))
    for values, label, color in losses:
        keep = thin(time, values, max_buckets=_MAX_BUCKETS)
        bottom.plot(
            clock.x(time[keep]),
            values[keep],
            color=color,
            linewidth=1.0,
            label=f"{label}: {_energy_text(values, time)}",
        )
    bottom.axhline(0.0, color="0.5", linewidth=0.8)
    bottom.set_ylabel("power lost [W]")
    bottom.legend(loc="best", fontsize="small")


def plot_light_run(trace: pd.DataFrame, metadata: Mapping, scenario, out_dir: str | Path, weather=None) -> list[Path]:
    """Write ``POWER_FILE`` for a run (its trace, metadata and scenario; ``weather``, its weather
    file already read, see :func:`heliostep.results.light.light_timeseries`) into ``out_dir``.

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
    path = plot_light(series, Path(out_dir) / POWER_FILE, metadata, title)
    return [] if path is None else [path]
