"""The figures of a run's solution: :class:`SolutionRecorder`, the master's ``monitor``.

The master shows the monitor the state at every internal CVODE step, at every event (both
sides) and at every output row; the recorder evaluates the definitions of
:mod:`heliostep.results.figures.summary` on those rows as they come (running peaks and sums, each step
judged once the next step is reached, :class:`~heliostep.results.figures.steps.StepJudge`), so its
memory does not grow with the run. Its :meth:`SolutionRecorder.figures` are stored in the run's
metadata (``solution_figures``) and are the figures of ``summary.json``.

The same figures can be accumulated in the compiled kernel instead, at each row as the kernel
records it (:mod:`heliostep.cosim.figures`): the master asks the recorder's
:meth:`SolutionRecorder.kernel_figures` and, when it gets a spec, hands the recorder no rows but the
kernel's totals at the end (:meth:`SolutionRecorder.take_kernel_figures`).

Why this module is long: the recorder, its two ways of being fed (rows, the kernel's totals) and
the plots' window and envelope belong together: each figure is defined once here.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.figures.run_summary import Peaks, StepFigures, Tracking
from heliostep.results.figures.steps import (
    FULL_STEPS_PER_PERIOD,
    MISS_TOLERANCE,
    SETTLING_BAND,
    StepJudge,
    StepOutcome,
    judged_steps,
    lost_between,
    outcome_records,
)

__all__ = [
    "ENVELOPE_BINS",
    "PEAK_WINDOW_HALF_WIDTH",
    "Envelope",
    "ErrorTrack",
    "PeakWindow",
    "SolutionPlotData",
    "SolutionRecorder",
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
        magnitude = np.abs(rows[:, self.torque])
        finite = np.isfinite(magnitude)
        k = int(np.argmax(np.where(finite, magnitude, -np.inf))) if finite.any() else -1
        recent = rows if self._trail is None else np.vstack([self._trail, rows])
        if k >= 0 and magnitude[k] > self.peak:
            self.peak, self.peak_time, self.peak_value = float(magnitude[k]), rows[k, 0], rows[k, self.torque]
            near = np.abs(recent[:, 0] - self.peak_time) <= self.half_width
            self.rows, self._until = self._bounded(recent[near]), self.peak_time + self.half_width
        elif self.rows is not None and rows[0, 0] <= self._until:
            self.rows = self._bounded(np.vstack([self.rows, rows[rows[:, 0] <= self._until]]))
        self._trail = recent[recent[:, 0] >= rows[-1, 0] - self.half_width][-self.max_rows :]
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
            if np.isfinite(magnitude).any():
                k = int(np.nanargmax(magnitude))
                if magnitude[k] > self.worst[j]:
                    self.worst[j], self.worst_at[j] = magnitude[k], (time[k], values[k])


class ErrorTrack:
    """The tracking error e [deg] over the solution's rows, for the light between the output rows
    (:mod:`heliostep.results.light.rows`): its running integral and that of e^2 (linear pieces; running sums one
    row after the other, as the kernel's) to the last row and at the first row at or after each of
    ``step_times`` [s], and per interval between those marks (the first row, each step) the rows of its
    largest and least value (t, e, panel [s, deg, rad], the first of equal ones)."""

    def __init__(self, step_times: Sequence[float] | np.ndarray):
        self.step_times = np.asarray(step_times, dtype=float)
        self.integral = 0.0
        self.marks: list[float] = []
        self.extremes = np.full((len(self.step_times) + 1, 6), np.nan)
        self.square = 0.0  # the integral of e^2 [deg^2 s], one row after the other (as the kernel's), and at the marks
        self.square_marks: list[float] = []

    def __call__(
        self,
        time: np.ndarray,
        areas: np.ndarray,
        square_areas: np.ndarray,
        continued: bool,
        error: np.ndarray,
        panel: np.ndarray,
    ):
        """The block's rows: their times, the trapezoid's areas of e and of e^2 (linear pieces) since the row before
        (``continued``: from the previous block's last row, one area per row; else one fewer), the error and the
        panel angle."""
        running = np.cumsum(np.concatenate([[self.integral], areas]))
        at_rows = running[1:] if continued else running
        self.integral = float(at_rows[-1])
        squares = np.cumsum(np.concatenate([[self.square], square_areas]))
        squares_at_rows = squares[1:] if continued else squares
        self.square = float(squares_at_rows[-1])
        steps = self.step_times[len(self.marks) :]
        steps = steps[steps <= time[-1]]
        if len(steps):
            where = np.searchsorted(time, steps, side="left")
            self.marks.extend(at_rows[where].tolist())
            self.square_marks.extend(squares_at_rows[where].tolist())
        interval = np.searchsorted(self.step_times, time, side="right")  # a row's: the steps at or before it
        starts = np.flatnonzero(np.r_[True, interval[1:] != interval[:-1]])
        for start, stop in zip(starts, np.r_[starts[1:], len(time)], strict=True):
            part = error[start:stop]
            if np.isnan(part).all():
                continue
            held = self.extremes[interval[start]]
            k, m = start + int(np.nanargmax(part)), start + int(np.nanargmin(part))
            if np.isnan(held[1]) or error[k] > held[1]:
                held[0], held[1], held[2] = time[k], error[k], panel[k]
            if np.isnan(held[4]) or error[m] < held[4]:
                held[3], held[4], held[5] = time[m], error[m], panel[m]

    def take_totals(self, totals: Any) -> None:
        """The kernel's (:class:`heliostep.cosim.figures.FigureTotals`), in place of rows."""
        self.integral, self.marks = totals.error_int, totals.error_marks.tolist()
        self.extremes[: len(totals.extremes)] = totals.extremes
        self.square, self.square_marks = totals.error_sq_int, totals.error_sq_marks.tolist()

    def figures(self) -> dict:
        """``error_integral_deg_s`` and ``error_sq_integral_deg2_s`` with their values ``..._at_steps_...`` at the
        steps reached, and ``error_extremes_deg`` (per interval reached: [t, e, panel] of the largest, then of the
        least error; None where no row) of ``solution_figures``."""
        reached = self.extremes[: len(self.marks) + 1]
        return {
            "error_integral_deg_s": self.integral,
            "error_integral_at_steps_deg_s": list(self.marks),
            "error_extremes_deg": [[None if np.isnan(v) else float(v) for v in row] for row in reached],
            "error_sq_integral_deg2_s": self.square,
            "error_sq_integral_at_steps_deg2_s": list(self.square_marks),
        }


class SolutionRecorder:
    """The master's ``monitor``: the figures of every row it is shown (each solver step, event and
    output row), computed as the rows come, in memory that does not grow with the run.

    The rows come in time order; they are taken in blocks of ``block`` rows: running peaks, the
    energy and the tracking error's RMS as sums over consecutive rows, the maximum error, and
    each step's outcome from the rotor's rows between the step and the next step (kept only until
    that step is judged). Memory is bounded by ``block`` rows plus the rotor's (time, angle) over
    one step interval, whatever the window's length. ``columns`` are the master trace's columns;
    ``panel_reference`` maps times [s] to the panel reference [rad]. With ``panel_reference=None``
    the rows are an assembled trace's (a stored trace without solution figures): the tracking
    error is its ``panel_angle_error`` column.
    """

    def __init__(
        self,
        columns: Sequence[str],
        roles: Mapping[str, str],
        sequencer: Sequencer,
        schedule: StepSchedule,
        panel_reference: Callable[[np.ndarray], np.ndarray] | None,
        block: int = 4096,
        span: tuple[float, float] | None = None,
        bins: int = ENVELOPE_BINS,
    ) -> None:
        self.columns = list(columns)
        index = {c: i for i, c in enumerate(self.columns)}
        self._panel = _role_column(index, roles, "panel_angle")
        self._error = index.get("panel_angle_error") if panel_reference is None else None
        self._tracking = self._error is not None or (self._panel is not None and panel_reference is not None)
        self._rotor = _role_column(index, roles, "rotor_angle")
        self._torque = [index[c] for c in [roles.get("torque")] if c in index]
        self._currents = [index[roles[r]] for r in ("current_a", "current_b") if roles.get(r) in index]
        self._power = _role_column(index, roles, "power")
        self.sequencer, self.schedule, self.reference = sequencer, schedule, panel_reference
        self.block = block
        self._pending: list[np.ndarray] = []
        self._pending_rows = 0
        self.count = 0
        self.unordered = 0  # rows earlier than a row already taken (none expected: the master is in order)
        self._first: np.ndarray | None = None  # the first and the last row taken
        self._last: np.ndarray | None = None
        self._last_time_repeated = False  # the last row's time equals the one before it
        self._error_max = 0.0
        self._error_sq_sum = 0.0  # sum of e^2
        # the error's integrals (of e^2, linear pieces, for the rms; of e, for the light between the output rows)
        self._error_track = ErrorTrack(schedule.times)
        self._energy = 0.0
        self._peak_torque = self._peak_current = 0.0
        self._last_error: float | None = None
        self.steps = StepJudge(sequencer, schedule)
        self._plotted = list(
            dict.fromkeys([0, *self._torque, *([self._rotor] if self._rotor is not None else []), *self._currents])
        )
        self.peak_window = PeakWindow(1) if self._torque else None  # the torque is the second kept column
        enveloped = self._torque + self._currents
        self.envelope = (
            Envelope(enveloped, span, bins) if span is not None and span[1] > span[0] and enveloped else None
        )

    @property
    def max_held(self) -> int:
        """The most rotor rows held at once for a step not yet judged."""
        return self.steps.max_held

    def kernel_figures(self) -> dict | None:
        """What the kernel accumulates for this recorder, the fields of
        :class:`heliostep.cosim.figures.FigureSpec` (None: the rows are needed here: no panel
        reference as a piecewise cubic, or rows already taken)."""
        reference = self.reference
        if self.count or self._pending or (self._tracking and not _is_cubic(reference)):
            return None
        tracked = self._tracking and reference is not None
        schedule, sequencer = self.schedule, self.sequencer
        envelope = self.envelope
        return dict(
            torque=self._torque[0] if self._torque else -1,
            currents=tuple(self._currents),
            power=-1 if self._power is None else self._power,
            panel=self._panel if tracked and self._panel is not None else -1,
            rotor=-1 if self._rotor is None else self._rotor,
            breaks=np.asarray(getattr(reference, "x", np.zeros(0)), dtype=float) if tracked else np.zeros(0),
            coefs=np.asarray(getattr(reference, "c", np.zeros((4, 0))), dtype=float) if tracked else np.zeros((4, 0)),
            step_times=np.asarray(schedule.times, dtype=float),
            commanded=np.asarray(sequencer.position(schedule.indices), dtype=float),
            initial_command=float(sequencer.position(schedule.initial_index)),
            increment=float(sequencer.increment),
            period=float(FULL_STEPS_PER_PERIOD * sequencer.step_angle),
            band=SETTLING_BAND,
            miss_tolerance=MISS_TOLERANCE,
            enveloped=tuple(envelope.columns) if envelope is not None else (),
            span=(envelope.start, envelope.end) if envelope is not None else (0.0, 1.0),
            bins=envelope.bins if envelope is not None else 1,
            plotted=tuple(self._plotted) if self.peak_window is not None else (),
            half_width=self.peak_window.half_width if self.peak_window is not None else PEAK_WINDOW_HALF_WIDTH,
            max_rows=self.peak_window.max_rows if self.peak_window is not None else 1,
        )

    def take_kernel_figures(self, totals: Any) -> None:
        """The figures the kernel accumulated (:class:`heliostep.cosim.figures.FigureTotals`, from
        :meth:`kernel_figures`'s spec), in place of rows; taken again, they replace those taken before."""
        self.count, self.unordered = totals.count, totals.unordered
        if not totals.count:
            return
        first = np.full(len(totals.last), np.nan)
        first[0] = totals.first[0]
        if self._rotor is not None:
            first[self._rotor] = totals.first[1]
        self._first, self._last = first, totals.last.copy()
        self._last_time_repeated = totals.last_time_repeated
        self._peak_torque, self._peak_current, self._energy = totals.peak_torque, totals.peak_current, totals.energy
        self._error_max, self._error_sq_sum = totals.error_max, totals.error_sq_sum
        self._last_error = totals.last_error
        self._error_track.take_totals(totals)
        self.steps = _JudgedInKernel(self.sequencer, self.schedule, totals)  # type: ignore[assignment]
        window = self.peak_window
        if window is not None and len(totals.window):
            window.rows, window.peak = totals.window.copy(), totals.peak
            window.peak_time, window.peak_value = totals.peak_time, totals.peak_value
            window.max_held = len(totals.window)
        if self.envelope is not None:
            self.envelope.low, self.envelope.high = totals.low.copy(), totals.high.copy()
            self.envelope.worst, self.envelope.worst_at = totals.worst.copy(), totals.worst_at.copy()

    def __call__(self, rows: np.ndarray) -> None:
        """Take rows: a 2-D block (the master's protocol) or a single row."""
        rows = np.array(rows, dtype=float, copy=True, ndmin=2)
        self._pending.append(rows)
        self._pending_rows += len(rows)
        if self._pending_rows >= self.block:
            self._take()

    def __len__(self) -> int:
        return self.count + self._pending_rows

    def _take(self) -> None:
        if not self._pending:
            return
        data = np.vstack(self._pending) if len(self._pending) > 1 else self._pending[0]
        self._pending, self._pending_rows = [], 0
        if np.any(data[1:, 0] < data[:-1, 0]):  # the master's rows are in order: no sort, no copy
            data = data[np.argsort(data[:, 0], kind="stable")]
        time = data[:, 0]
        if self._last is not None:
            self.unordered += int(np.sum(time < self._last[0]))
            previous_time = self._last[0]
        else:
            self._first = data[0].copy()
            previous_time = np.nan
        times = np.concatenate([[previous_time], time])
        self._last_time_repeated = bool(times[-1] == times[-2])
        if self._torque:
            self._peak_torque = max(self._peak_torque, float(np.abs(data[:, self._torque]).max()))
        if self._currents:
            self._peak_current = max(self._peak_current, float(np.abs(data[:, self._currents]).max()))
        if self._power is not None:
            self._take_energy(data, time, times)
        if self._tracking:
            self._take_error(data, time, times)
        if self._rotor is not None:
            self.steps(time, data[:, self._rotor])
        if self.peak_window is not None:
            self.peak_window(data[:, self._plotted])
        if self.envelope is not None:
            self.envelope(data)
        self._last = data[-1].copy()
        self.count += len(data)

    def _take_energy(self, data: np.ndarray, time: np.ndarray, times: np.ndarray) -> None:
        power = data[:, self._power]
        if self._last is not None:
            power, t = np.concatenate([[self._last[self._power]], power]), times
        else:
            t = time
        self._energy += float(np.sum(np.diff(t) * (power[:-1] + power[1:]) / 2.0))

    def _take_error(self, data: np.ndarray, time: np.ndarray, times: np.ndarray) -> None:
        if self._error is not None:
            error = np.degrees(data[:, self._error])
        elif self._panel is not None and self.reference is not None:
            error = np.degrees(data[:, self._panel] - self.reference(time))
        else:  # tracking needs the error's column or the panel angle and its reference
            raise RuntimeError("tracking error asked without the panel angle's error or its reference")
        self._error_max = max(self._error_max, float(np.abs(error).max()))
        self._error_sq_sum += float(np.sum(error * error))
        if self._last_error is not None:
            e, t = np.concatenate([[self._last_error], error]), times
        else:
            e, t = error, time
        e0, e1 = e[:-1], e[1:]
        square_areas = np.diff(t) * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0
        self._last_error = float(error[-1])
        panel = data[:, self._panel] if self._panel is not None else np.full(len(time), np.nan)
        self._error_track(time, np.diff(t) * (e0 + e1) / 2.0, square_areas, len(e) > len(error), error, panel)

    def figures(self) -> dict:
        """The figures of every row shown, as stored in ``metadata['solution_figures']`` (the
        definitions of :mod:`heliostep.results.figures.summary`; ``step_outcomes`` per step,
        ``solution_rows``, ``end_time_s`` [s])."""
        self._take()
        result: dict = {}
        if self.count == 0:
            return {"solution_rows": 0, "end_time_s": 0.0}
        first, last = self._first, self._last
        if first is None or last is None:  # set by the first rows taken
            raise RuntimeError("rows counted but not kept")
        start, end = float(first[0]), float(last[0])
        if self._tracking:
            span = end - start
            square = self._error_track.square  # the integral of e^2 [deg^2 s]
            rms = float(np.sqrt(square / span if span > 0 else self._error_sq_sum / self.count))
            result.update(dataclasses.asdict(Tracking(self._error_max, rms)))
            result.update(self._error_track.figures())
        result.update(
            dataclasses.asdict(
                Peaks(self._peak_torque if self._torque else None, self._peak_current if self._currents else None)
            )
        )
        if self._power is not None and self.count > 1:
            result["electrical_energy_J"] = self._energy
        if self._rotor is not None:
            outcomes = self.steps.outcomes_at_end(end)
            lost = lost_between(
                (start, first[self._rotor]),
                (end, last[self._rotor]),
                self._last_time_repeated,
                self.sequencer,
                self.schedule,
            )
            result.update(dataclasses.asdict(StepFigures.of(judged_steps(outcomes, len(outcomes)), lost)))
            result["step_outcomes"] = outcome_records(outcomes)
        result["solution_rows"] = int(self.count)
        result["end_time_s"] = end
        return result

    def plot_data(self) -> SolutionPlotData:
        """The solution rows around the peak |torque| and the envelopes, for the plots."""
        self._take()
        names = [self.columns[c] for c in self._plotted]
        times = np.asarray(self.schedule.times, dtype=float)
        end = -np.inf if self._last is None else float(self._last[0])
        window = self.peak_window
        rows, peak_time, peak_torque = None, None, None
        steps, peak_step = np.empty(0), 0
        if window is not None and window.rows is not None and len(window.rows):
            rows, peak_time, peak_torque = window.rows.copy(), float(window.peak_time), float(window.peak_value)
            steps = times[(times >= rows[0, 0]) & (times <= rows[-1, 0])]
            peak_step = int(np.searchsorted(times, peak_time, side="right"))
        envelope, low, high, worst = self.envelope, {}, {}, {}
        edges = None
        if envelope is not None and self.count:
            edges = envelope.edges.copy()
            for j, column in enumerate(envelope.columns):
                name = self.columns[column]
                low[name], high[name] = envelope.low[j].copy(), envelope.high[j].copy()
                worst[name] = (float(envelope.worst_at[j, 0]), float(envelope.worst_at[j, 1]))
        return SolutionPlotData(
            names,
            rows,
            peak_time,
            peak_torque,
            PEAK_WINDOW_HALF_WIDTH if window is None else window.half_width,
            steps,
            peak_step,
            int(np.searchsorted(times, end, side="right")),
            edges,
            low,
            high,
            worst,
        )


class _JudgedInKernel:
    """The steps the kernel judged (:class:`~heliostep.results.figures.steps.StepJudge`'s answers), made into
    :class:`StepOutcome` objects when first asked: a supervised run hands the kernel's totals over after
    every block, and building every step's outcome each time would cost steps x blocks."""

    def __init__(self, sequencer: Sequencer, schedule: StepSchedule, totals: Any):
        self.max_held, self.lag = totals.max_held, totals.lag
        self._sequencer, self._schedule, self._judged = sequencer, schedule, totals.outcomes

    @functools.cached_property
    def outcomes(self) -> list[StepOutcome]:
        schedule, sequencer = self._schedule, self._sequencer
        return [
            StepOutcome(
                float(schedule.times[k]),
                float(sequencer.position(schedule.indices[k])),
                bool(missed),
                None if np.isnan(settling) else float(settling),
                float(move),
            )
            for k, (missed, settling, move) in enumerate(self._judged)
        ]

    def outcomes_at_end(self, end: float) -> list[StepOutcome]:
        """Every step judged, the last open one up to the end (judged in the kernel's finish)."""
        return list(self.outcomes)


def _is_cubic(reference: object) -> bool:
    """Whether ``reference`` is a scalar piecewise cubic as scipy's PPoly holds it (breaks ``x``, ``c`` 4 x n)."""
    c, x = getattr(reference, "c", None), getattr(reference, "x", None)
    return (
        isinstance(c, np.ndarray)
        and isinstance(x, np.ndarray)
        and c.ndim == 2
        and c.shape[0] == 4
        and len(x) == c.shape[1] + 1
        and bool(getattr(reference, "extrapolate", False))
    )


def _role_column(index: Mapping[str, int], roles: Mapping[str, str], role: str) -> int | None:
    """The index of the column that has ``role`` (None: no such role or no such column)."""
    column = roles.get(role)
    return None if column is None else index.get(column)
