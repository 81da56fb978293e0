"""The figures of a run's solution: :class:`SolutionRecorder`, the master's ``monitor``.

Each figure of ``summary.json`` is defined here once, evaluated on every solver step as it comes,
with running sums, so the figures are the same bit for bit whatever the blocks.

Details: docs/running.md, ``heliostep.results.figures.solution``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.figures.plot_data import (
    ENVELOPE_BINS,
    PEAK_WINDOW_HALF_WIDTH,
    ROTOR_LAG,
    TRACKING_ERROR,
    Envelope,
    PeakWindow,
    SolutionPlotData,
)
from heliostep.results.figures.run_summary import Peaks, StepFigures, Tracking
from heliostep.results.figures.steps import (
    StepJudge,
    judged_steps,
    lost_between,
    outcome_records,
)
from heliostep.results.trace.frame import step_indices

__all__ = [
    "ENVELOPE_BINS",
    "PEAK_WINDOW_HALF_WIDTH",
    "Envelope",
    "ErrorTrack",
    "PeakWindow",
    "RecorderTotals",
    "SolutionPlotData",
    "SolutionRecorder",
]


class ErrorTrack:
    """The tracking error e [deg] over the solution's rows, for the light between the output rows
    (:mod:`heliostep.results.light.rows`): its running integral and that of e^2 (linear pieces; running sums one
    row after the other) to the last row and at the first row at or after each of
    the ``schedule``'s steps [s], and per interval between those marks (the first row, each step) the rows of
    its largest and least value (t, e, panel [s, deg, rad], the first of equal ones). The schedule may grow
    while the rows come (a controller's steps), never before the rows taken."""

    def __init__(self, schedule: StepSchedule):
        self.schedule = schedule
        self.integral = 0.0
        self.marks: list[float] = []
        self.extremes = np.full((len(schedule.times) + 1, 6), np.nan)
        self.square = 0.0  # the integral of e^2 [deg^2 s], one row after the other, and at the marks
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
        self.grow(len(self.schedule.times))
        at_rows = _running_sums(self.integral, areas, continued)
        self.integral = float(at_rows[-1])
        squares_at_rows = _running_sums(self.square, square_areas, continued)
        self.square = float(squares_at_rows[-1])
        step_times = np.asarray(self.schedule.times, dtype=float)
        steps = step_times[len(self.marks) :]
        steps = steps[steps <= time[-1]]
        if len(steps):
            where = np.searchsorted(time, steps, side="left")
            self.marks.extend(at_rows[where].tolist())
            self.square_marks.extend(squares_at_rows[where].tolist())
        # the rows in time order: runs of one interval (a row's: the number of steps at or before it)
        first, last = np.searchsorted(step_times, time[[0, -1]], side="right")
        bounds = np.searchsorted(time, step_times[first:last], side="left")
        starts = np.unique(np.concatenate([[0], bounds]))
        intervals = first + np.searchsorted(bounds, starts, side="right")
        lengths = np.diff(np.append(starts, len(time)))
        for column, reduce, better in ((0, np.fmax, np.greater), (3, np.fmin, np.less)):
            best = reduce.reduceat(error, starts)  # NaN only where the whole run is
            hits = np.flatnonzero(error == np.repeat(best, lengths))
            valid = ~np.isnan(best)
            k = hits[np.searchsorted(hits, starts[valid])]  # the first row of each run's best value
            held = self.extremes[intervals[valid], column + 1]
            take = np.isnan(held) | better(error[k], held)
            k = k[take]
            self.extremes[intervals[valid][take], column : column + 3] = np.column_stack([time[k], error[k], panel[k]])

    def grow(self, steps: int) -> None:
        """Room for the extremes of ``steps`` steps' intervals (the schedule grew)."""
        if steps + 1 > len(self.extremes):
            more = np.full((max(steps + 1, 2 * len(self.extremes)) - len(self.extremes), 6), np.nan)
            self.extremes = np.concatenate([self.extremes, more])

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


#: The recorder's own running values handed over whole by :meth:`SolutionRecorder.totals`.
_RUNNING = (
    "count",
    "unordered",
    "_first",
    "_last",
    "_last_time_repeated",
    "_error_max",
    "_error_sq_sum",
    "_energy",
    "_peak_torque",
    "_peak_current",
    "_last_error",
)


@dataclasses.dataclass(frozen=True)
class RecorderTotals:
    """What a :class:`SolutionRecorder` has taken so far, for the recorder of the same run in another
    process: its running values (``running``: the recorder's, the step judge's, the error's integrals,
    the peak window's, the envelope's), and the step outcomes and error marks new since the totals
    before (sent once each); ``extremes`` are the error's extremes per interval from ``extremes_from`` on."""

    running: dict
    outcomes: list
    marks: list
    square_marks: list
    extremes_from: int
    extremes: np.ndarray


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
        block: int = 16384,
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
        self._sent = (0, 0)  # the step outcomes and error marks handed over by totals()
        self._pending: np.ndarray | None = None  # rows not yet taken: the first _pending_rows of a block
        self._pending_rows = 0
        self.count = 0
        self.unordered = 0  # rows earlier than a row already taken (none expected: the master is in order)
        self._first: np.ndarray | None = None  # the first and the last row taken
        self._last: np.ndarray | None = None
        self._last_time_repeated = False  # the last row's time equals the one before it
        self._error_max = 0.0
        self._error_sq_sum = 0.0  # sum of e^2
        # the error's integrals (of e^2, linear pieces, for the rms; of e, for the light between the output rows)
        self._error_track = ErrorTrack(schedule)
        self._energy = 0.0
        self._peak_torque = self._peak_current = 0.0
        self._last_error: float | None = None
        self.steps = StepJudge(sequencer, schedule)
        self._plotted = list(
            dict.fromkeys([0, *self._torque, *([self._rotor] if self._rotor is not None else []), *self._currents])
        )
        self.peak_window = PeakWindow(1) if self._torque else None  # the torque is the second kept column
        # enveloped for the plots: the master's columns drawn, then the tracking error and the rotor's lag
        angles = [c for c in (self._rotor, self._panel, index.get("m_ext")) if c is not None]
        self._enveloped = list(dict.fromkeys(self._torque + self._currents + angles))
        self._derived = [TRACKING_ERROR] * self._tracking + [ROTOR_LAG] * (self._rotor is not None)
        count = len(self._enveloped) + len(self._derived)
        self.envelope = Envelope(count, span, bins) if span is not None and span[1] > span[0] and count else None

    @property
    def max_held(self) -> int:
        """The most rotor rows held at once for a step not yet judged."""
        return self.steps.max_held

    def __call__(self, rows: np.ndarray) -> None:
        """Take rows: a 2-D block (the master's protocol) or a single row."""
        rows = np.asarray(rows, dtype=float)
        if rows.ndim == 1:
            rows = rows[None, :]
        n, held = len(rows), self._pending_rows
        if self._pending is not None and held + n < self.block:  # most calls: into the block begun
            self._pending[held : held + n] = rows
            self._pending_rows = held + n
            return
        while len(rows):
            if self._pending is None:  # a new one each time: what the figures keep of a block stays theirs
                self._pending = np.empty((self.block, rows.shape[1]), order="F")  # columns contiguous
            n = min(len(rows), self.block - self._pending_rows)
            self._pending[self._pending_rows : self._pending_rows + n] = rows[:n]
            self._pending_rows += n
            rows = rows[n:]
            if self._pending_rows == self.block:
                self._take()

    def __len__(self) -> int:
        return self.count + self._pending_rows

    def totals(self) -> RecorderTotals:
        """The figures of every row taken so far, for :meth:`take_totals` of the run's recorder in
        another process (a supervised run's child sends them with every block of output rows)."""
        self._take()
        steps, track = self.steps, self._error_track
        outcomes_sent, marks_sent = self._sent
        running: dict = {name: getattr(self, name) for name in _RUNNING}
        running["steps"] = {k: v for k, v in vars(steps).items() if k not in ("sequencer", "schedule", "outcomes")}
        running["steps"]["_step_t"], running["steps"]["_step_x"] = list(steps._step_t), list(steps._step_x)
        running["track"] = (track.integral, track.square)
        if self.peak_window is not None:
            running["window"] = dict(vars(self.peak_window))
        if self.envelope is not None:
            envelope = self.envelope
            running["envelope"] = {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in vars(envelope).items()}
        self._sent = (len(steps.outcomes), len(track.marks))
        return RecorderTotals(
            running,
            steps.outcomes[outcomes_sent:],
            track.marks[marks_sent:],
            track.square_marks[marks_sent:],
            marks_sent,
            track.extremes[marks_sent : len(track.marks) + 1].copy(),
        )

    def take_totals(self, totals: RecorderTotals) -> None:
        """The figures of another process's recorder of the same run (:meth:`totals`, each in turn), in
        place of rows: this recorder's figures are then that one's."""
        running = totals.running
        for name in _RUNNING:
            setattr(self, name, running[name])
        vars(self.steps).update(running["steps"])
        self.steps.outcomes.extend(totals.outcomes)
        track = self._error_track
        track.integral, track.square = running["track"]
        track.marks.extend(totals.marks)
        track.square_marks.extend(totals.square_marks)
        track.grow(totals.extremes_from + len(totals.extremes))
        track.extremes[totals.extremes_from : totals.extremes_from + len(totals.extremes)] = totals.extremes
        if self.peak_window is not None:
            vars(self.peak_window).update(running["window"])
        if self.envelope is not None:
            vars(self.envelope).update(running["envelope"])

    def steps_decided(self, schedule: StepSchedule) -> None:
        """The steps the rows were simulated on, known at the end (a controller decided them while simulating)."""
        self._take()
        self.schedule = self.steps.schedule = self._error_track.schedule = schedule

    def _take(self) -> None:
        if self._pending is None or not self._pending_rows:
            return
        data = self._pending[: self._pending_rows]
        self._pending, self._pending_rows = None, 0
        if np.any(data[1:, 0] < data[:-1, 0]):  # the master's rows are in order: no sort, no copy
            data = data[np.argsort(data[:, 0], kind="stable")]
        time = data[:, 0]
        if self._last is not None:
            self.unordered += int(np.searchsorted(time, self._last[0], side="left"))
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
        error = self._take_error(data, time, times) if self._tracking else None
        if self._rotor is not None:
            self.steps(time, data[:, self._rotor])
        if self.peak_window is not None:
            self.peak_window(data[:, self._plotted])
        if self.envelope is not None:
            self._take_envelope(data, time, error)
        self._last = data[-1].copy()
        self.count += len(data)

    def _take_energy(self, data: np.ndarray, time: np.ndarray, times: np.ndarray) -> None:
        power = data[:, self._power]
        if self._last is not None:
            power, t = np.concatenate([[self._last[self._power]], power]), times
        else:
            t = time
        self._energy = _running_sum(self._energy, np.diff(t) * (power[:-1] + power[1:]) / 2.0)

    def _take_envelope(self, data: np.ndarray, time: np.ndarray, error: np.ndarray | None) -> None:
        """The block's rows to the envelope: its columns, the tracking error [deg] (the one of the figures)
        and the rotor's actual - commanded angle [rad]."""
        series = [data[:, self._enveloped]]
        if error is not None:
            series.append(error[:, None])
        if self._rotor is not None:
            previous = None if self._last is None else float(self._last[0])
            commanded = self.sequencer.position(step_indices(time, self.schedule, previous))
            series.append((data[:, self._rotor] - commanded)[:, None])
        if self.envelope is not None:
            self.envelope(time, np.hstack(series))

    def _take_error(self, data: np.ndarray, time: np.ndarray, times: np.ndarray) -> np.ndarray:
        if self._error is not None:
            error = np.degrees(data[:, self._error])
        elif self._panel is not None and self.reference is not None:
            error = np.degrees(data[:, self._panel] - self.reference(time))
        else:  # tracking needs the error's column or the panel angle and its reference
            raise RuntimeError("tracking error asked without the panel angle's error or its reference")
        self._error_max = max(self._error_max, float(np.abs(error).max()))
        self._error_sq_sum = _running_sum(self._error_sq_sum, error * error)
        if self._last_error is not None:
            e, t = np.concatenate([[self._last_error], error]), times
        else:
            e, t = error, time
        e0, e1 = e[:-1], e[1:]
        square_areas = np.diff(t) * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0
        self._last_error = float(error[-1])
        panel = data[:, self._panel] if self._panel is not None else np.full(len(time), np.nan)
        self._error_track(time, np.diff(t) * (e0 + e1) / 2.0, square_areas, len(e) > len(error), error, panel)
        return error

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
        envelope, low, high, mean, worst = self.envelope, {}, {}, {}, {}
        edges = None
        if envelope is not None and self.count:
            edges = envelope.edges.copy()
            means = envelope.mean()
            for j, name in enumerate([self.columns[c] for c in self._enveloped] + self._derived):
                low[name], high[name], mean[name] = envelope.low[j].copy(), envelope.high[j].copy(), means[j]
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
            mean,
        )


def _running_sums(total: float, terms: np.ndarray, continued: bool = True) -> np.ndarray:
    """``total`` plus ``terms`` added one after the other, at each term (``continued=False``: ``total``
    first); numpy's sum adds pairwise, so its rounding would depend on the blocks the rows come in.
    ``terms`` (a temporary) is overwritten."""
    if not len(terms):
        return np.array([total])
    terms[0] = total + terms[0]
    sums = np.cumsum(terms, out=terms)
    return sums if continued else np.concatenate([[total], sums])


def _running_sum(total: float, terms: np.ndarray) -> float:
    """``total`` plus ``terms`` added one after the other (``terms``, a temporary, overwritten)."""
    return float(_running_sums(total, terms)[-1])


def _role_column(index: Mapping[str, int], roles: Mapping[str, str], role: str) -> int | None:
    """The index of the column that has ``role`` (None: no such role or no such column)."""
    column = roles.get(role)
    return None if column is None else index.get(column)
