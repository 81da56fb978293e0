"""Plot of the end-loss gain over a year: energy on the tube per day, single-axis vs two-axis end mirrors.

:func:`plot_end_loss_year` draws :func:`heliostep.solar.endloss.end_loss_days`'s table: the
energy absorbed per day [kWh] by a single-axis plant and by the same plant with two-axis end
mirrors, the light a single-axis plant sends past the tube's end, and below it the gain [%]
and the tube's dark length at the day's highest sun [m] ([paper], eq. 2).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from heliostep.plots.png import save_png

__all__ = ["END_LOSS_FILE", "plot_end_loss_year"]

#: PNG of the year's end-loss gain.
END_LOSS_FILE = "end_loss_year.png"
_DPI = 120
_KWH = 3.6e6  # [J]


def plot_end_loss_year(days: pd.DataFrame, path: str | Path, title: str = "") -> Path | None:
    """Energy per day (single-axis plant vs two-axis end mirrors), the gain and the dark length.

    Parameters
    ----------
    days : pandas.DataFrame
        :func:`heliostep.solar.endloss.end_loss_days`.
    path : str or Path
        PNG to write.
    title : str, default ""
        Appended to the title (the plant and site).

    Returns
    -------
    Path or None
        None for an empty table.
    """
    if days.empty:
        return None
    x = days.index.to_numpy()
    style = "-" if len(x) > 40 else "o-"
    fig = Figure(figsize=(9.0, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    top.plot(x, days["energy_two_axis_J"] / _KWH, style, color="C2", label="with two-axis end mirrors")
    top.plot(x, days["energy_single_J"] / _KWH, style, color="C0", label="single-axis plant")
    top.plot(
        x,
        days["end_spill_single_J"] / _KWH,
        style,
        color="C3",
        linewidth=1.0,
        label="single-axis light past the tube's end",
    )
    top.set_ylabel("energy on the tube [kWh/day]")
    top.set_ylim(bottom=0.0)
    top.legend(loc="best", fontsize="small")
    top.set_title(f"End-loss gain of two-axis end mirrors, clear sky{title}")
    bottom.plot(x, 100.0 * days["gain"], style, color="C2", label="gain, two-axis / single-axis - 1 [%]")
    bottom.set_ylabel("gain [%]")
    bottom.set_ylim(bottom=0.0)
    dark = bottom.twinx()
    dark.plot(
        x,
        days["unlit_length_noon_m"],
        "--",
        color="0.3",
        linewidth=1.0,
        label="dark length at the tube's start, highest sun [m]",
    )
    dark.set_ylabel("dark length at noon [m]")
    dark.set_ylim(bottom=0.0)
    lines = bottom.get_legend_handles_labels()
    more = dark.get_legend_handles_labels()
    bottom.legend(lines[0] + more[0], lines[1] + more[1], loc="upper center", fontsize="small")
    bottom.set_xlabel("day of year")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    path = Path(path)
    save_png(fig, path, _DPI)
    return path
