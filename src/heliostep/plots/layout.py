"""A fixed layout for the figures of ``heliostep run``: margins in inches, no layout engine (the
run's figures are always the same few shapes, so measuring every text before drawing buys nothing).

Details: docs/running.md, ``heliostep.plots.layout``.
"""

from __future__ import annotations

from collections.abc import Sequence

from matplotlib.figure import Figure

__all__ = ["BOTTOM", "GAP", "RIGHT", "TOP", "fixed_axes"]

#: Below the lowest axes [in]: its tick labels and the time axis label.
BOTTOM = 0.58
#: Above the highest axes [in]: the title (a lower panel's offset text, e.g. "1e-7", sits in :data:`GAP`).
TOP = 0.34
#: Right of the axes [in]: half of a date tick label at the axis' end.
RIGHT = 0.22
#: Between two panels that share their x axis [in] (no tick labels between them).
GAP = 0.3


def fixed_axes(
    size: tuple[float, float],
    rows: int,
    left: float,
    height_ratios: Sequence[float] | None = None,
    sharex: bool = True,
) -> tuple[Figure, list]:
    """A :class:`~matplotlib.figure.Figure` of ``size`` [in] with ``rows`` axes in a column,
    ``left`` [in] left of them (the y tick labels and the axis label) and the module's margins
    elsewhere; the axes share their x axis (``sharex``), only the lowest one labelled."""
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
            "right": 1.0 - RIGHT / width,
            "bottom": BOTTOM / height,
            "top": 1.0 - TOP / height,
            "hspace": GAP / mean_height,
            "height_ratios": height_ratios,
        },
    )[:, 0]
    return fig, list(axes)
