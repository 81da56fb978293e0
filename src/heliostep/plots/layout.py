"""A fixed layout for the figures of ``heliostep run``: margins in inches, no layout engine (the
run's figures are always the same few shapes, so measuring every text before drawing buys nothing).

Details: docs/running.md, ``heliostep.plots.layout``.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

from matplotlib.figure import Figure

__all__ = ["BOTTOM", "GAP", "LEGEND", "LEGEND_CHARS", "RIGHT", "TOP", "fixed_axes", "outside_legend"]

#: Below the lowest axes [in]: its tick labels and the time axis label.
BOTTOM = 0.58
#: Above the highest axes [in]: the title (a lower panel's offset text, e.g. "1e-7", sits in :data:`GAP`).
TOP = 0.34
#: Right of the axes [in]: half of a date tick label at the axis' end.
RIGHT = 0.22
#: Right of the axes when their legend is beside them [in].
LEGEND = 2.9
#: Characters per line of a legend's label beside the axes (longer labels wrap).
LEGEND_CHARS = 36
#: Between two panels that share their x axis [in] (no tick labels between them).
GAP = 0.3


def fixed_axes(
    size: tuple[float, float],
    rows: int,
    left: float,
    height_ratios: Sequence[float] | None = None,
    sharex: bool = True,
    right: float = RIGHT,
) -> tuple[Figure, list]:
    """A :class:`~matplotlib.figure.Figure` of ``size`` [in] with ``rows`` axes in a column,
    ``left`` [in] left of them (the y tick labels and the axis label), ``right`` [in] right of them
    (:data:`LEGEND` for legends beside them) and the module's margins elsewhere; the axes share their
    x axis (``sharex``), only the lowest one labelled."""
    width, height = size
    fig = Figure(figsize=size)
    span = height - TOP - BOTTOM
    mean_height = (span - (rows - 1) * GAP) / rows  # GridSpec's hspace is the gap over the mean axes height
    axes = fig.subplots(
        rows,
        1,
        sharex=sharex,
        squeeze=False,
        gridspec_kw={
            "left": left / width,
            "right": 1.0 - right / width,
            "bottom": BOTTOM / height,
            "top": 1.0 - TOP / height,
            "hspace": GAP / mean_height,
            "height_ratios": height_ratios,
        },
    )[:, 0]
    return fig, list(axes)


def outside_legend(ax, hidden_gid: str | None = None, **options) -> None:
    """``ax``'s legend beside it, right of its top corner (never over the data), its labels wrapped at
    :data:`LEGEND_CHARS`; artists whose ``gid`` is ``hidden_gid`` are left out. ``options`` go to ``legend``."""
    handles, labels = ax.get_legend_handles_labels()
    shown = [(h, textwrap.fill(label, LEGEND_CHARS)) for h, label in zip(handles, labels) if h.get_gid() != hidden_gid]
    if not shown:
        return
    ax.legend(
        [h for h, _ in shown], [label for _, label in shown], loc="upper left", bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0.0, fontsize="small", **options,
    )  # fmt: skip
