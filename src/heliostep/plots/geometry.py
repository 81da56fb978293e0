"""Plots of the solar geometry (end loss, two-axis angles, the paper's reference case).

Every function takes plain pandas data, writes one PNG and returns its path. Figures
are built with :class:`matplotlib.figure.Figure` (no pyplot state), so they can be
drawn from worker threads.
"""

from __future__ import annotations

import zoneinfo
from pathlib import Path

import matplotlib.dates as mdates
import pandas as pd
from matplotlib.figure import Figure

from heliostep.plots.png import save_png

__all__ = [
    "plot_end_loss",
    "plot_panel_angle_reference",
    "plot_rotor_angle_reference",
    "plot_two_axis_angles",
]

_LINESTYLES = ("-", "--", ":", "-.")


def _save(fig: Figure, path) -> Path:
    path = Path(path)
    save_png(fig, path, 120)
    return path


def plot_end_loss(frame: pd.DataFrame, path, timezone: str, tube_height: float) -> Path:
    """End-loss length k over the day, one curve per date (the paper's Fig. 2).

    Parameters
    ----------
    frame : pandas.DataFrame
        Columns ``date``, ``hour_local`` [h], ``mirror_distance_m`` [m], ``end_loss_m`` [m].
    path : str or Path
        PNG to write.
    timezone : str
        Shown in the time axis label.
    tube_height : float  [m]
        Shown in the title.
    """
    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.add_subplot()
    distances = list(dict.fromkeys(frame["mirror_distance_m"]))
    for (date, distance), group in frame.groupby(["date", "mirror_distance_m"], sort=False):
        style = _LINESTYLES[distances.index(distance) % len(_LINESTYLES)]
        label = f"{date}" if len(distances) == 1 else f"{date}, d = {distance:g} m"
        ax.plot(group["hour_local"], group["end_loss_m"], style, label=label)
    ax.axhline(0.0, color="0.6", linewidth=0.8)
    ax.set_xlabel(f"local time ({timezone}) [h]")
    ax.set_ylabel("end loss k [m]  (k > 0: light shifted toward +y)")
    ax.set_title(f"Single-axis mirror end loss, tube height h = {tube_height:g} m")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save(fig, path)


def plot_two_axis_angles(frame: pd.DataFrame, path, timezone: str) -> Path:
    """Primary and secondary angles of two-axis mirrors over the day, one column per date.

    Parameters
    ----------
    frame : pandas.DataFrame
        Columns ``date``, ``hour_local`` [h], ``mirror_distance_m`` [m],
        ``primary_deg`` [deg], ``secondary_deg`` [deg].
    path : str or Path
    timezone : str
    """
    dates = list(dict.fromkeys(frame["date"]))
    fig = Figure(figsize=(4.2 * len(dates), 7), layout="constrained")
    axes = fig.subplots(2, len(dates), sharex="col", sharey="row", squeeze=False)
    for column, date in enumerate(dates):
        day = frame[frame["date"] == date]
        for distance, group in day.groupby("mirror_distance_m", sort=False):
            axes[0, column].plot(group["hour_local"], group["primary_deg"], label=f"d = {distance:g} m")
            axes[1, column].plot(group["hour_local"], group["secondary_deg"], label=f"d = {distance:g} m")
        axes[0, column].set_title(f"{date}")
        axes[1, column].set_xlabel(f"local time ({timezone}) [h]")
        for ax in axes[:, column]:
            ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("primary angle θp [deg]")
    axes[1, 0].set_ylabel("secondary angle θq [deg]")
    axes[0, 0].legend(fontsize="small")
    fig.suptitle("Two-axis end mirrors: primary and secondary angles")
    return _save(fig, path)


def _time_plot(times: pd.DatetimeIndex, values, path, timezone: str, ylabel: str, title: str) -> Path:
    tz = zoneinfo.ZoneInfo(timezone)
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(list(times.tz_convert(timezone).to_pydatetime()), list(values))
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M:%S", tz=tz))
    ax.set_xlabel(f"local time ({timezone}), {times[0].tz_convert(timezone):%Y-%m-%d}")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_panel_angle_reference(times: pd.DatetimeIndex, panel_angle_deg, path, timezone: str, title: str) -> Path:
    """Reference panel angle over a window (the paper's Fig. 8).

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Timezone-aware.
    panel_angle_deg : array-like  [deg]
    path : str or Path
    timezone : str
    title : str
    """
    return _time_plot(times, panel_angle_deg, path, timezone, "reference panel angle [deg]", title)


def plot_rotor_angle_reference(times: pd.DatetimeIndex, rotor_angle_deg, path, timezone: str, title: str) -> Path:
    """Reference rotor angle of the stepper over a window (the paper's Fig. 9).

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Timezone-aware.
    rotor_angle_deg : array-like  [deg]
    path : str or Path
    timezone : str
    title : str
    """
    return _time_plot(times, rotor_angle_deg, path, timezone, "reference rotor angle [deg]", title)
