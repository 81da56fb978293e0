"""The solution rows the plots draw beyond ``summary.json``: the rows around the peak |torque|
(:class:`PeakWindow`) and the envelopes of the torque and currents (:class:`Envelope`), each fed the
solution's rows in blocks by :class:`~heliostep.results.figures.solution.SolutionRecorder` in memory that does
not grow with the run, and what the plots get of them (:class:`SolutionPlotData`)."""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = [
    "ENVELOPE_BINS",
    "PEAK_WINDOW_HALF_WIDTH",
    "PEAK_WINDOW_MAX_ROWS",
    "Envelope",
    "ROTOR_LAG",
    "TRACKING_ERROR",
    "PeakWindow",
    "SolutionPlotData",
    "largest",
]


#: The envelope's name of the tracking error, actual - reference panel angle [deg] (``summary.json``'s).
TRACKING_ERROR = "tracking_error_deg"
#: The envelope's name of the rotor's actual - commanded angle [rad].
ROTOR_LAG = "rotor_angle_minus_cmd"
#: Half width of the solution rows held around the peak |torque| (Fig. 14's zoom) [s].
PEAK_WINDOW_HALF_WIDTH = 0.1
#: Most solution rows held around the peak (beyond it the window is thinned, the peak row kept).
PEAK_WINDOW_MAX_ROWS = 20_000
#: Time bins of an envelope over its span: at least one per pixel column of a run figure's axes (under
#: 1000 px wide at 120 dpi), so the envelope drawn is the curve of every row as the pixels show it.
ENVELOPE_BINS = 1000


@dataclasses.dataclass(frozen=True)
class SolutionPlotData:
    """What the plots draw from the solution (every row the master showed), not in ``summary.json``.

    ``columns`` name the columns of ``peak_rows`` (``time`` first, then the torque, rotor angle and
    phase currents present, by the master's names); ``peak_rows`` are the solution rows within
    ``half_width`` [s] of the row with the largest |torque| (``peak_time`` [s], ``peak_torque``
    [N.m], signed: its magnitude is ``summary.json``'s ``peak_torque_Nm``); ``steps`` the step
    instants [s] within those rows' span, ``peak_step`` the 1-based number of the step owning the
    peak (0: before the first step) and ``step_count`` the steps up to the last row.
    ``edges`` [s] bound the envelope's bins; ``minimum``, ``maximum`` and ``mean`` map each enveloped
    series (the torque, currents, rotor and panel angles and the wind moment by the master's names,
    and :data:`TRACKING_ERROR` [deg] and :data:`ROTOR_LAG` [rad]) to its least, largest and
    time-weighted mean value per bin (NaN: no row in the bin), ``worst`` to the (time [s], value) of
    its largest magnitude.
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
    mean: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

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
    """The least, largest and time-weighted mean value of some series per time bin (``bins`` bins over
    ``span`` [s]), and each series' largest magnitude and its time, over every row fed in time order
    (rows outside the span count in the first or last bin): the one way heliostep thins a curve for
    drawing, fed the solution in blocks or an array whole. Memory: ``4 * bins`` values per series.

    The mean is the trapezoid's integral of the series' linear pieces over the time they cover, each
    piece counted in its later row's bin; a bin whose rows cover no time has the mean of its least and
    largest.
    """

    def __init__(self, count: int, span: tuple[float, float], bins: int = ENVELOPE_BINS):
        start, end = span
        if not end > start or bins < 1:
            raise ValueError(f"an envelope needs a span with end > start and bins >= 1, not {span}, {bins}")
        self.count, self.start, self.end, self.bins = count, float(start), float(end), bins
        self.edges = np.linspace(self.start, self.end, bins + 1)
        self.low = np.full((count, bins), np.nan)
        self.high = np.full((count, bins), np.nan)
        self.area = np.zeros((count, bins))  # the integral of each series per bin [unit s]
        self.weight = np.zeros((count, bins))  # the time it covers [s]
        self.worst = np.full(count, -np.inf)
        self.worst_at = np.full((count, 2), np.nan)  # (time, value)
        self.last: np.ndarray | None = None  # the last row fed: its time, then its values

    def __call__(self, time: np.ndarray, values: np.ndarray) -> None:
        """Feed rows: ``time`` [s] (n,), ``values`` (n, count), not earlier than the rows fed before."""
        if not len(time):
            return
        values = np.asarray(values, dtype=float).reshape(len(time), self.count)
        where = self.bin_of(time)
        starts = np.flatnonzero(np.r_[True, where[1:] != where[:-1]])  # rows in time order: one run per bin
        bins = where[starts]
        self.low[:, bins] = np.fmin(self.low[:, bins], np.fmin.reduceat(values, starts, axis=0).T)
        self.high[:, bins] = np.fmax(self.high[:, bins], np.fmax.reduceat(values, starts, axis=0).T)
        if self.last is not None:
            t, v = np.r_[self.last[0], time], np.vstack([self.last[1:], values])
        else:
            t, v, where = time, values, where[1:]
        middle = (v[:-1] + v[1:]) / 2.0
        covered = np.isfinite(middle)
        width = np.diff(t)[:, None] * covered
        runs = np.flatnonzero(np.r_[True, where[1:] != where[:-1]]) if len(where) else where
        touched = where[runs]
        for j in range(self.count):
            # summed one piece after the other from the bin's total so far: the same whatever the blocks
            for total, pieces in ((self.area[j], np.where(covered[:, j], middle[:, j], 0.0) * width[:, j]),
                                  (self.weight[j], width[:, j].copy())):  # fmt: skip
                pieces[runs] += total[touched]
                total[touched] = np.bincount(where, pieces, self.bins)[touched]
            magnitude = np.abs(values[:, j])
            k = largest(magnitude, finite_only=False)
            if k >= 0 and magnitude[k] > self.worst[j]:
                self.worst[j], self.worst_at[j] = magnitude[k], (time[k], values[k, j])
        self.last = np.r_[time[-1], values[-1]]

    def bin_of(self, time: np.ndarray) -> np.ndarray:
        """The bin of each time [s] (the first or the last outside the span)."""
        where = np.clip(np.floor((time - self.start) / (self.end - self.start) * self.bins), 0, self.bins - 1)
        return where.astype(int)

    def mean(self) -> np.ndarray:
        """The time-weighted mean per series and bin (NaN: no row in the bin)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.weight > 0, self.area / self.weight, (self.low + self.high) / 2.0)


def largest(magnitude: np.ndarray, finite_only: bool = True) -> int:
    """The index of the first largest of ``magnitude`` ignoring NaN, or -1 where it has no finite value
    (``finite_only``: infinities ignored too)."""
    finite = np.isfinite(magnitude)
    if not finite.any():
        return -1
    if finite_only:
        return int(np.argmax(np.where(finite, magnitude, -np.inf)))
    return int(np.argmax(np.where(np.isnan(magnitude), -np.inf, magnitude)))
