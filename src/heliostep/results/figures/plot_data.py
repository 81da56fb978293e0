"""The solution rows the plots draw beyond ``summary.json``: the rows around the peak |torque|
(:class:`PeakWindow`) and the envelopes of the torque and currents (:class:`Envelope`), each fed the
solution's rows in blocks by :class:`~heliostep.results.figures.solution.SolutionRecorder` in memory that does
not grow with the run, and what the plots get of them (:class:`SolutionPlotData`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

__all__ = [
    "ENVELOPE_BINS",
    "PEAK_WINDOW_HALF_WIDTH",
    "PEAK_WINDOW_MAX_ROWS",
    "Envelope",
    "PeakWindow",
    "SolutionPlotData",
    "largest",
]


#: Half width of the solution rows held around the peak |torque| (Fig. 14's zoom) [s].
PEAK_WINDOW_HALF_WIDTH = 0.1
#: Most solution rows held around the peak (beyond it the window is thinned, the peak row kept).
PEAK_WINDOW_MAX_ROWS = 20_000
#: Time bins of the solution's envelopes over the window (Figs. 10-11).
ENVELOPE_BINS = 2000


@dataclasses.dataclass(frozen=True)
class SolutionPlotData:
    """What the plots draw from the solution (every row the master showed), not in ``summary.json``.

    ``columns`` name the columns of ``peak_rows`` (``time`` first, then the torque, rotor angle and
    phase currents present, by the master's names); ``peak_rows`` are the solution rows within
    ``half_width`` [s] of the row with the largest |torque| (``peak_time`` [s], ``peak_torque``
    [N.m], signed: its magnitude is ``summary.json``'s ``peak_torque_Nm``); ``steps`` the step
    instants [s] within those rows' span, ``peak_step`` the 1-based number of the step owning the
    peak (0: before the first step) and ``step_count`` the steps up to the last row.
    ``edges`` [s] bound the envelope's bins; ``minimum`` and ``maximum`` map each enveloped column
    (torque, currents) to its least and largest value per bin (NaN: no row in the bin), ``worst``
    to the (time [s], value) of its largest magnitude.
    """

    columns: list[str]
    peak_rows: np.ndarray | None
    peak_time: float | None
    peak_torque: float | None
    half_width: float
    steps: np.ndarray
    peak_step: int
    step_count: int
    edges: np.ndarray | None
    minimum: dict[str, np.ndarray]
    maximum: dict[str, np.ndarray]
    worst: dict[str, tuple[float, float]]

    def column(self, name: str) -> np.ndarray:
        """A column of ``peak_rows`` by its name (empty without a window)."""
        if self.peak_rows is None:
            return np.empty(0)
        return self.peak_rows[:, self.columns.index(name)]


class PeakWindow:
    """The solution rows around the running peak |torque|, in bounded memory.

    Fed the rows' ``time`` and kept columns (``rows[:, 0]`` time, ``rows[:, torque]`` the torque),
    in time order: it holds the rows of the last ``half_width`` [s] (the lead-in of a new peak) and
    the rows within ``half_width`` of the largest |torque| so far, replaced when a larger one
    comes. Each part is at most ``max_rows`` rows (a part over it is thinned evenly, the peak row
    kept), so at most ``2 * max_rows`` rows are held whatever the run's length.
    """

    def __init__(self, torque: int, half_width: float = PEAK_WINDOW_HALF_WIDTH, max_rows: int = PEAK_WINDOW_MAX_ROWS):
        self.torque, self.half_width, self.max_rows = torque, half_width, max_rows
        self.rows: np.ndarray | None = None
        self.peak = -np.inf
        self.peak_time = self.peak_value = np.nan
        self._until = -np.inf
        self._trail: np.ndarray | None = None
        self.max_held = 0

    def __call__(self, rows: np.ndarray) -> None:
        time, torque = rows[:, 0], rows[:, self.torque]
        magnitude = np.abs(torque)
        k = largest(magnitude)
        if k >= 0 and magnitude[k] > self.peak:
            recent = rows if self._trail is None else np.vstack([self._trail, rows])
            self.peak, self.peak_time, self.peak_value = float(magnitude[k]), time[k], torque[k]
            near = np.abs(recent[:, 0] - self.peak_time) <= self.half_width
            self.rows, self._until = self._bounded(recent[near]), self.peak_time + self.half_width
        elif self.rows is not None and time[0] <= self._until:
            self.rows = self._bounded(np.vstack([self.rows, rows[time <= self._until]]))
        cut = time[-1] - self.half_width
        if self._trail is not None and time[0] >= cut:  # the block within the last half width: the trail goes on
            recent = np.vstack([self._trail, rows])
            self._trail = recent[recent[:, 0] >= cut][-self.max_rows :]
        else:  # rows in time order: the trail's rows are older than the block's first
            self._trail = rows[time >= cut][-self.max_rows :]
        self.max_held = max(self.max_held, len(self._trail) + (0 if self.rows is None else len(self.rows)))

    def _bounded(self, rows: np.ndarray) -> np.ndarray:
        """``rows``, thinned evenly to ``max_rows`` (the peak row kept) when longer."""
        if len(rows) <= self.max_rows:
            return rows
        peak = int(np.flatnonzero((rows[:, 0] == self.peak_time) & (np.abs(rows[:, self.torque]) == self.peak))[0])
        keep = np.unique(np.r_[np.linspace(0, len(rows) - 1, self.max_rows - 1).round().astype(int), peak])
        return rows[keep]


class Envelope:
    """The least and largest value of some columns per time bin (``bins`` bins over ``span`` [s]),
    and each column's largest magnitude and its time, over every row fed (rows outside the span
    count in the first or last bin). Memory: ``2 * bins`` values per column."""

    def __init__(self, columns: Sequence[int], span: tuple[float, float], bins: int = ENVELOPE_BINS):
        start, end = span
        if not end > start or bins < 1:
            raise ValueError(f"an envelope needs a span with end > start and bins >= 1, not {span}, {bins}")
        self.columns, self.start, self.end, self.bins = list(columns), float(start), float(end), bins
        self.edges = np.linspace(self.start, self.end, bins + 1)
        self.low = np.full((len(self.columns), bins), np.nan)
        self.high = np.full((len(self.columns), bins), np.nan)
        self.worst = np.full(len(self.columns), -np.inf)
        self.worst_at = np.full((len(self.columns), 2), np.nan)  # (time, value)

    def __call__(self, rows: np.ndarray) -> None:
        time = rows[:, 0]
        where = np.clip(np.floor((time - self.start) / (self.end - self.start) * self.bins), 0, self.bins - 1)
        where = where.astype(int)
        starts = np.flatnonzero(np.r_[True, where[1:] != where[:-1]])  # rows in time order: one run per bin
        bins = where[starts]
        for j, column in enumerate(self.columns):
            values = rows[:, column]
            self.low[j, bins] = np.fmin(self.low[j, bins], np.fmin.reduceat(values, starts))
            self.high[j, bins] = np.fmax(self.high[j, bins], np.fmax.reduceat(values, starts))
            magnitude = np.abs(values)
            k = largest(magnitude, finite_only=False)
            if k >= 0 and magnitude[k] > self.worst[j]:
                self.worst[j], self.worst_at[j] = magnitude[k], (time[k], values[k])


def largest(magnitude: np.ndarray, finite_only: bool = True) -> int:
    """The index of the first largest of ``magnitude`` ignoring NaN, or -1 where it has no finite value
    (``finite_only``: infinities ignored too)."""
    finite = np.isfinite(magnitude)
    if not finite.any():
        return -1
    if finite_only:
        return int(np.argmax(np.where(finite, magnitude, -np.inf)))
    return int(np.argmax(np.where(np.isnan(magnitude), -np.inf, magnitude)))
