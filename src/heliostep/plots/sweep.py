"""Plots of a sweep's results table (:mod:`heliostep.sweep`): heat maps over day of year x mirror.

Details: docs/sweep.md, ``heliostep.plots.sweep``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from heliostep.plots.png import save_png
from heliostep.solar import N_FIELD_MIRRORS

__all__ = [
    "HEATMAPS",
    "HEATMAP_SCALES",
    "MAX_ANNOTATED_CELLS",
    "STEP_COLUMNS",
    "TORQUE_FILE",
    "heatmap_figure",
    "plot_heatmap",
    "plot_sweep",
]

#: (column, PNG, colour-bar label) of each heatmap.
HEATMAPS = (
    ("peak_torque_Nm", "heatmap_peak_torque.png", "peak motor torque [N.m]"),
    ("max_tracking_error_deg", "heatmap_max_tracking_error.png", "max secondary tracking error [deg]"),
    (
        "primary_sharing_error_max_deg",
        "heatmap_primary_sharing_error.png",
        "max primary error from sharing the central law [deg]",
    ),
    ("light_lost_J", "heatmap_light_lost.png", "light lost against ideal tracking, ideal - actual [kJ]"),
    ("light_lost_fraction", "heatmap_light_lost_fraction.png", "light lost, share of ideal tracking [%]"),
)
#: Factor from a heatmap column's unit to its colour bar's (J -> kJ, fraction -> %).
HEATMAP_SCALES = {"light_lost_J": 1e-3, "light_lost_fraction": 100.0}
#: Heatmap columns that a case without steps has no value of: its cell says "no steps".
STEP_COLUMNS = frozenset({"peak_torque_Nm"})
#: Most cells of a heatmap whose values are printed in them.
MAX_ANNOTATED_CELLS = 600
#: The retired torque requirement figure (no longer written; still owned by a sweep's folder, module docstring).
TORQUE_FILE = "torque_requirement.png"
#: Most tick labels on a heatmap axis: one per mirror of the field.
_MAX_TICKS = N_FIELD_MIRRORS
_DPI = 120
_WHITE = ListedColormap(["white"])


def _ok_drive_rows(table: pd.DataFrame) -> pd.DataFrame:
    rows = table[table["status"] == "ok"]
    if "role" in rows:
        rows = rows[rows["role"].fillna("drive") == "drive"]
    return rows


def _ticks(count: int) -> np.ndarray:
    return np.unique(np.linspace(0, count - 1, min(count, _MAX_TICKS)).round().astype(int))


def _no_steps(rows: pd.DataFrame) -> pd.Series:
    """Rows of cases that commanded no step (``steps_commanded`` 0, or no peak torque)."""
    none = pd.Series(False, index=rows.index)
    if "steps_commanded" in rows:
        none |= rows["steps_commanded"].fillna(-1).to_numpy() == 0
    if "peak_torque_Nm" in rows:
        none |= rows["peak_torque_Nm"].isna()
    return none


def _cells(rows: pd.DataFrame, column: str) -> tuple[pd.DataFrame, np.ndarray]:
    """The grid of ``column`` (mirror x day, the largest value per cell; NaN: no value) and which
    cells are of cases without steps only (for :data:`STEP_COLUMNS`)."""
    stepless = _no_steps(rows) if column in STEP_COLUMNS else pd.Series(False, index=rows.index)
    shown = rows[~stepless].dropna(subset=[column])
    mirrors = sorted(rows["mirror_index"].unique())
    days = sorted(rows["day_of_year"].unique())
    if shown.empty:
        grid = pd.DataFrame(np.nan, index=mirrors, columns=days)
    else:
        grid = shown.pivot_table(index="mirror_index", columns="day_of_year", values=column, aggfunc="max")
        grid = grid.reindex(index=mirrors, columns=days)
    none = rows[stepless].pivot_table(index="mirror_index", columns="day_of_year", values="status", aggfunc="size")
    none = none.reindex(index=mirrors, columns=days).notna().to_numpy() & grid.isna().to_numpy()
    return grid, none


def _annotate(ax, values: np.ma.MaskedArray, none: np.ndarray, image) -> None:
    """Each cell's value (and "no steps"), when the cells are few enough to be read."""
    if values.size > MAX_ANNOTATED_CELLS:
        return
    size = 8 if values.size <= 100 else 6 if values.size <= 300 else 4.5
    norm = image.norm
    for (row, col), value in np.ndenumerate(values.filled(np.nan)):
        if none[row, col]:
            ax.text(col, row, "no steps", ha="center", va="center", fontsize=size, color="0.2")
        elif np.isfinite(value):
            dark = norm(value) < 0.6  # viridis is dark below ~0.6
            ax.text(col, row, f"{value:.3g}", ha="center", va="center", fontsize=size, color="w" if dark else "k")


def plot_heatmap(table: pd.DataFrame, column: str, path: str | Path, label: str, scale: float = 1.0) -> Path | None:
    """One figure of the table over day of year (x) x mirror index (y), each cell's value printed
    (up to :data:`MAX_ANNOTATED_CELLS` cells); for :data:`STEP_COLUMNS` a cell whose cases
    commanded no step is white and says "no steps" (not 0).

    Parameters
    ----------
    table : pandas.DataFrame
        The sweep table: ``day_of_year``, ``mirror_index``, ``status``, ``column`` (and
        ``steps_commanded``).
    column : str
        The figure to show; the largest value over the table's other axes per cell.
    path : str or Path
        PNG to write.
    label : str
        Colour-bar label (with unit).
    scale : float, default 1
        Factor from the column's unit to the label's.

    Returns
    -------
    Path or None
        None when the table has no value of ``column`` to show.
    """
    fig = heatmap_figure(table, column, label, scale)
    if fig is None:
        return None
    path = Path(path)
    save_png(fig, path, _DPI)
    return path


def heatmap_figure(table: pd.DataFrame, column: str, label: str, scale: float = 1.0) -> Figure | None:
    """The figure :func:`plot_heatmap` writes (None: no value to show), for reading back what it draws."""
    rows = _ok_drive_rows(table).dropna(subset=["day_of_year", "mirror_index"])
    if rows.empty or column not in rows:
        return None
    grid, none = _cells(rows, column)
    if grid.isna().all().all() and not none.any():
        return None
    days = [int(d) for d in grid.columns]
    mirrors = [int(m) for m in grid.index]
    values = np.ma.masked_invalid(grid.to_numpy(dtype=float) * scale)
    fig = Figure(figsize=(max(6.0, min(14.0, 3.0 + 0.25 * len(days))), 5.0), layout="constrained")
    ax = fig.add_subplot()
    colormap = colormaps["viridis"].with_extremes(bad="0.85")  # failed cases: grey
    image = ax.imshow(values, origin="lower", aspect="auto", interpolation="nearest", cmap=colormap)
    if none.any():
        ax.imshow(np.ma.masked_where(~none, none), origin="lower", aspect="auto", interpolation="nearest", cmap=_WHITE)
        fig.legend(  # below the figure, never over a cell or the title
            handles=[Patch(facecolor="w", edgecolor="0.5", label="no steps")],
            loc="outside lower right",
            fontsize="small",
        )
    _annotate(ax, values, none, image)
    x_ticks, y_ticks = _ticks(len(days)), _ticks(len(mirrors))
    ax.set_xticks(x_ticks, [str(days[k]) for k in x_ticks])
    ax.set_yticks(y_ticks, [str(mirrors[k]) for k in y_ticks])
    ax.set_xlabel("day of year")
    ax.set_ylabel("mirror index (6: central)")
    varied = [c for c in ("current_A", "motor", "mechanics", "wind_moment_Nm") if c in rows and rows[c].nunique() > 1]
    note = f" (max over {', '.join(varied)})" if varied else ""
    ax.set_title(f"{label}{note}")
    fig.colorbar(image, ax=ax, label=label)
    return fig


def plot_sweep(table: pd.DataFrame, out_dir: str | Path) -> list[Path]:
    """Write the sweep's figures (see the module docstring) into ``out_dir``.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`heliostep.sweep.read_results` or ``SweepOutcome.table``.
    out_dir : str or Path
        Created when missing.

    Returns
    -------
    list of Path
        The heatmaps written (only when the table spans two or more days and mirrors; none otherwise).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    drive = _ok_drive_rows(table)
    if drive["day_of_year"].nunique() >= 2 and drive["mirror_index"].nunique() >= 2:
        for column, name, label in HEATMAPS:
            path = plot_heatmap(table, column, out_dir / name, label, HEATMAP_SCALES.get(column, 1.0))
            if path is not None:
                written.append(path)
    return written
