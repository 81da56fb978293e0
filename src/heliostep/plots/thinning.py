"""Thinning a curve for drawing, one way for every figure: its envelope per pixel column
(:class:`~heliostep.results.figures.plot_data.Envelope`: the least, largest and mean value per time bin),
so the extremes drawn are the curve's own (a figure of ``summary.json`` equals the one drawn).

A run's solution is enveloped as it is simulated (``SolutionPlotData``); rows at hand are enveloped
here (:meth:`Band.of_rows`). A band is drawn as a shaded range with its mean (:func:`draw_band`), or
as one line through each bin's least and largest value (:func:`min_max_line`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from heliostep.results.figures.plot_data import ENVELOPE_BINS, Envelope, SolutionPlotData

__all__ = ["EDGE_GID", "Band", "draw_band", "min_max_line"]

#: The ``gid`` of a band's least and largest lines (drawn, left out of the legends: the shading stands for them).
EDGE_GID = "envelope-edge"


@dataclasses.dataclass(frozen=True)
class Band:
    """A curve's envelope: ``edges`` [s] (bins + 1) and per bin its ``low``, ``high`` and ``mean``
    (a bin without a row: interpolated from its neighbours, within their range), ``worst`` the
    (time [s], value) of its largest magnitude, ``width`` a bin's [s]."""

    edges: np.ndarray
    low: np.ndarray
    high: np.ndarray
    mean: np.ndarray
    worst: tuple[float, float]

    @property
    def width(self) -> float:
        return float(self.edges[1] - self.edges[0])

    @classmethod
    def of_rows(cls, time: np.ndarray, values: np.ndarray, bins: int = ENVELOPE_BINS) -> Band | None:
        """The envelope of rows (``time`` [s], non-decreasing; None: no finite value or no span)."""
        time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
        if len(time) < 2 or not time[-1] > time[0] or not np.isfinite(values).any():
            return None
        envelope = Envelope(1, (float(time[0]), float(time[-1])), bins)
        envelope(time, values[:, None])
        worst = (float(envelope.worst_at[0, 0]), float(envelope.worst_at[0, 1]))
        return cls._filled(envelope.edges, envelope.low[0], envelope.high[0], envelope.mean()[0], worst)

    @classmethod
    def of_solution(cls, solution: SolutionPlotData | None, name: str) -> Band | None:
        """The envelope of a series of the solution (None: not enveloped)."""
        if solution is None or solution.edges is None or name not in solution.maximum:
            return None
        if not np.isfinite(solution.maximum[name]).any():
            return None
        mean = solution.mean.get(name, (solution.minimum[name] + solution.maximum[name]) / 2.0)
        return cls._filled(solution.edges, solution.minimum[name], solution.maximum[name], mean, solution.worst[name])

    @classmethod
    def _filled(cls, edges, low, high, mean, worst) -> Band:
        centres = (edges[:-1] + edges[1:]) / 2.0
        seen = np.isfinite(low) & np.isfinite(high)
        low, high, mean = (
            np.interp(centres, centres[seen], a[seen]) if not seen.all() else a for a in (low, high, mean)
        )
        return cls(np.asarray(edges, dtype=float), low, high, mean, worst)

    def scaled(self, factor: float) -> Band:
        """The band with its values times ``factor`` (units)."""
        time, value = self.worst
        return Band(self.edges, self.low * factor, self.high * factor, self.mean * factor, (time, value * factor))


def draw_band(ax, x, band: Band, color, label: str, what: str, **style) -> None:
    """Draw ``band`` on ``ax`` (``x`` maps times [s] to the axis): its range per bin shaded, its least and
    largest value as thin step lines (labelled ``"{what}: min per ..."`` and ``"{what}: max per ..."``, their
    ``gid`` :data:`EDGE_GID`: the shading stands for them in a legend) and its mean as a line labelled
    ``"{label}: mean per ..."`` (``style``: that line's, e.g. ``linewidth``)."""
    edges = x(band.edges)
    per = f"per {band.width:.3g} s bin"
    ax.fill_between(
        edges, np.r_[band.low, band.low[-1]], np.r_[band.high, band.high[-1]], step="post", color=color, alpha=0.25,
        linewidth=0.0, label=f"{label}: least to largest {per}",
    )  # fmt: skip
    for values, which in ((band.high, "max"), (band.low, "min")):
        (line,) = ax.plot(
            edges, np.r_[values, values[-1]], drawstyle="steps-post", color=color, linewidth=0.4, alpha=0.8,
            label=f"{what}: {which} {per}",
        )  # fmt: skip
        line.set_gid(EDGE_GID)
    centres = x((band.edges[:-1] + band.edges[1:]) / 2.0)
    ax.plot(centres, band.mean, "-", color=color, **{"linewidth": 1.1, **style}, label=f"{label}: mean {per}")


def min_max_line(time: np.ndarray, values: np.ndarray, bins: int = ENVELOPE_BINS) -> tuple[np.ndarray, np.ndarray]:
    """The points [s, value] of a line drawn as ``values`` is at pixel resolution: the rows as they are
    when there are no more than ``2 * bins``, else each bin's least and largest value at its centre (the
    least first)."""
    time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    if len(time) <= 2 * bins:
        return time, values
    band = Band.of_rows(time, values, bins)
    if band is None:
        return time[[0, -1]], values[[0, -1]]
    centres = (band.edges[:-1] + band.edges[1:]) / 2.0
    return np.repeat(centres, 2), np.column_stack([band.low, band.high]).ravel()
