"""A run's figures (``summary.json``) from the solution, recomputable from trace and metadata.

A run computes its figures from **the solution itself**: the master's monitor sees the state
at every internal CVODE step, at every event (both sides) and at every output row, and
:class:`SolutionRecorder` evaluates the definitions below on those rows as they come (running
peaks and sums, each step judged once the next step is reached), so its memory does not grow
with the run; :func:`solution_figures` evaluates the same definitions on rows held in a frame. The run stores them in its metadata (``solution_figures``), so :func:`summarize`
needs nothing but the trace and the metadata (:func:`summarize_files` recomputes a stored
run's summary). For a trace without solution figures (an older run, a hand-built trace) the
same definitions are evaluated on the trace's rows, and ``figures_from`` says so.

Definitions:

- tracking error: the panel angle minus its reference; max of its magnitude and its RMS
  over time (the error taken as linear between rows) [deg];
- peak torque, peak phase current: max magnitude over the rows (every solver step);
- electrical energy drawn: the integral of the motor's electrical power, trapezoidal over
  every solver step [J];
- a step is *missed* when it did not move the rotor by its increment: the rotor's move
  from the step to the next step (or to the end) differs from the commanded increment by
  more than :data:`MISS_TOLERANCE` increments (the rotor then ends in another detent; a slip
  falls back by whole electrical periods, 4 full steps). Steps executed = commanded − missed;
- steps lost: how many step increments the rotor ends behind the commanded position, net of
  the elastic lag (the static deflection under load, which the run holds from its first row:
  it starts at the loaded detent): round((cmd − rotor)/increment − lag), negative when ahead.
  The lag is the one at the start, or, when the run ends on a reduced idle current, the lag
  the same load causes at that current (:func:`held_lag`, from the detent's sine torque law). A slip under load loses whole electrical periods (4 full steps).
  ``final_lag_steps`` is what is left, the elastic lag at the end, in increments;
- settling time of a step: from the step until the rotor stays within ``settling_band`` ×
  the increment of its rest position (the commanded position minus the elastic lag held at
  the start, in the detent the rotor ends in; the crossing time is interpolated linearly
  between rows); ``None`` when at the next step (or the end) it is still outside.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.trace import drive_from_metadata
from heliostep.results.trace_io import read_trace

#: Band around the rest position that counts as settled, in step increments.
SETTLING_BAND = 0.05
#: A step is missed when the rotor's move differs from the increment by more than this [increments].
MISS_TOLERANCE = 0.5
#: Full steps per electrical period (2 pi / N_c): a slipping rotor falls back by multiples of it.
FULL_STEPS_PER_PERIOD = 4
#: Summary fields that judge steps (per-step outcomes, settling, missed and lost steps).
STEP_FIELDS = ("missed_steps", "steps_executed", "settling_time_s", "missed_step_times_s", "steps_lost",
               "final_lag_steps")


class SolutionRecorder:
    """The master's ``monitor``: the figures of every row it is shown (each solver step, event and
    output row), computed as the rows come, in memory that does not grow with the run.

    It evaluates the same definitions as :func:`figures` on the same rows (the rows come in time
    order; they are taken in blocks of ``block`` rows): running peaks, the energy and the
    tracking error's RMS as sums over consecutive rows, the maximum error, and each step's
    outcome from the rotor's rows between the step and the next step (kept only until that step
    is judged). Memory is bounded by ``block`` rows plus the rotor's (time, angle) over one step
    interval, whatever the window's length. ``columns`` are the master trace's columns;
    ``panel_reference`` maps times [s] to the panel reference [rad]. With ``panel_reference=None``
    the rows are an assembled trace's (:class:`TraceSummary`): the tracking error is its
    ``panel_angle_error`` column.
    """

    def __init__(self, columns, roles: Mapping, sequencer: Sequencer, schedule: StepSchedule,
                 panel_reference, block: int = 4096) -> None:
        self.columns = list(columns)
        index = {c: i for i, c in enumerate(self.columns)}
        self._panel = index.get(roles.get("panel_angle"))
        self._error = index.get("panel_angle_error") if panel_reference is None else None
        self._tracking = self._error is not None or (self._panel is not None and panel_reference is not None)
        self._rotor = index.get(roles.get("rotor_angle"))
        self._torque = [index[c] for c in [roles.get("torque")] if c in index]
        self._currents = [index[roles[r]] for r in ("current_a", "current_b") if roles.get(r) in index]
        self._power = index.get(roles.get("power"))
        self.sequencer, self.schedule, self.reference = sequencer, schedule, panel_reference
        self.block = block
        self._pending: list[np.ndarray] = []
        self._pending_rows = 0
        self.count = 0
        self.unordered = 0  # rows earlier than a row already taken (none expected: the master is in order)
        self._first = self._last = None  # the first and the last row taken
        self._last_time_repeated = False  # the last row's time equals the one before it
        self._error_max = 0.0
        self._error_sq_int = self._error_sq_sum = 0.0  # integral of e^2 (linear pieces), sum of e^2
        self._energy = 0.0
        self._peak_torque = self._peak_current = 0.0
        self._last_error = None
        # per-step outcomes
        self._k = 0  # the next step to judge
        self._open = False  # its first row (the row at the step) has been seen
        self._step_t: list[np.ndarray] = []
        self._step_x: list[np.ndarray] = []
        self._previous = float(sequencer.position(schedule.initial_index))
        self._lag = None
        self.outcomes: list[tuple] = []
        self.max_held = 0  # the most rotor rows held at once for a step not yet judged

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
            power = data[:, self._power]
            if self._last is not None:
                power, t = np.concatenate([[self._last[self._power]], power]), times
            else:
                t = time
            self._energy += float(np.sum(np.diff(t) * (power[:-1] + power[1:]) / 2.0))
        if self._tracking:
            error = np.degrees(data[:, self._error] if self._error is not None
                               else data[:, self._panel] - self.reference(time))
            self._error_max = max(self._error_max, float(np.abs(error).max()))
            self._error_sq_sum += float(np.sum(error * error))
            if self._last_error is not None:
                e, t = np.concatenate([[self._last_error], error]), times
            else:
                e, t = error, time
            e0, e1 = e[:-1], e[1:]
            self._error_sq_int += float(np.sum(np.diff(t) * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0))
            self._last_error = float(error[-1])
        if self._rotor is not None:
            if self._lag is None:
                self._lag = float(self.sequencer.position(self.schedule.initial_index) - data[0, self._rotor])
            self._steps(time, data[:, self._rotor])
        self._last = data[-1].copy()
        self.count += len(data)

    def _steps(self, time: np.ndarray, rotor: np.ndarray) -> None:
        """Judge the steps whose interval ends in this block; keep the rotor rows of the open one."""
        try:
            self._judge_steps(time, rotor)
        finally:
            self.max_held = max(self.max_held, sum(len(t) for t in self._step_t))

    def _judge_steps(self, time: np.ndarray, rotor: np.ndarray) -> None:
        times, n, pos = self.schedule.times, len(self.schedule), 0
        while self._k < n:
            if not self._open:
                pos += int(np.searchsorted(time[pos:], times[self._k], side="left"))
                if pos == len(time):
                    return
                self._open = True
            if self._k + 1 == n:  # the last step lasts to the end of the run
                self._step_t.append(time[pos:])
                self._step_x.append(rotor[pos:])
                return
            last = pos + int(np.searchsorted(time[pos:], times[self._k + 1], side="left"))
            if last == len(time):
                self._step_t.append(time[pos:])
                self._step_x.append(rotor[pos:])
                return
            self._step_t.append(time[pos:last + 1])
            self._step_x.append(rotor[pos:last + 1])
            self.max_held = max(self.max_held, sum(len(t) for t in self._step_t))
            self._judge(np.concatenate(self._step_t), np.concatenate(self._step_x))
            pos = last

    def _judge(self, t: np.ndarray, x: np.ndarray) -> None:
        t_step, index = self.schedule.times[self._k], self.schedule.indices[self._k]
        commanded = float(self.sequencer.position(index))
        missed, settling, move = _outcome(t_step, commanded, self._previous, t, x, self._lag, self.sequencer)
        self.outcomes.append((float(t_step), commanded, missed, settling, move))
        self._previous = commanded
        self._k += 1
        self._open = False
        self._step_t, self._step_x = [], []

    def figures(self) -> dict:
        """The figures of every row shown (as :func:`solution_figures` of those rows)."""
        self._take()
        result: dict = {}
        if self.count == 0:
            return {"solution_rows": 0, "end_time_s": 0.0}
        start, end = float(self._first[0]), float(self._last[0])
        if self._tracking:
            result["max_tracking_error_deg"] = self._error_max
            span = end - start
            result["rms_tracking_error_deg"] = float(np.sqrt(self._error_sq_int / span if span > 0
                                                             else self._error_sq_sum / self.count))
        result["peak_torque_Nm"] = self._peak_torque if self._torque else None
        result["peak_phase_current_A"] = self._peak_current if self._currents else None
        if self._power is not None and self.count > 1:
            result["electrical_energy_J"] = self._energy
        if self._rotor is not None:
            outcomes = list(self.outcomes)
            if self._open and self._k < len(self.schedule):  # the step open at the end
                t, x = np.concatenate(self._step_t), np.concatenate(self._step_x)
                if self._k + 1 == len(self.schedule):  # judged up to the first row at the end
                    cut = int(np.searchsorted(t, end, side="left"))
                    t, x = t[:cut + 1], x[:cut + 1]
                t_step, index = self.schedule.times[self._k], self.schedule.indices[self._k]
                commanded = float(self.sequencer.position(index))
                missed, settling, move = _outcome(t_step, commanded, self._previous, t, x, self._lag,
                                                  self.sequencer)
                outcomes.append((float(t_step), commanded, missed, settling, move))
            result.update(_step_fields(outcomes, len(outcomes)))
            first_cmd = float(self.sequencer.position(self.schedule.index_at(np.array([start]), side="left"))[0])
            side = "right" if self._last_time_repeated else "left"
            last_cmd = float(self.sequencer.position(self.schedule.index_at(np.array([end]), side=side))[0])
            increment = self.sequencer.increment
            behind = (last_cmd - float(self._last[self._rotor])) / increment
            lag = (first_cmd - float(self._first[self._rotor])) / increment
            result["steps_lost"], result["final_lag_steps"] = lost_steps(behind, lag, self.sequencer, self.schedule,
                                                                         start, end)
            result["step_outcomes"] = [{"time_s": o[0], "missed": o[2], "settling_s": o[3], "move_steps": o[4]}
                                       for o in outcomes]
        result["solution_rows"] = int(self.count)
        result["end_time_s"] = end
        return result


def _time_rms(values: np.ndarray, time: np.ndarray) -> float:
    """RMS over time of a signal taken as linear between rows (exact for the square of a linear
    piece, so long solver steps over which the error drifts linearly do not inflate it)."""
    span = time[-1] - time[0]
    if span <= 0:
        return float(np.sqrt(np.mean(values**2)))
    e0, e1, h = values[:-1], values[1:], np.diff(time)
    return float(np.sqrt(np.sum(h * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0) / span))


def _peak(trace: pd.DataFrame, *columns: str) -> float | None:
    present = [c for c in columns if c in trace]
    return float(np.abs(trace[present].to_numpy()).max()) if present and len(trace) else None


def held_lag(start_lag: float, current_fraction: float, sequencer: Sequencer) -> float:
    """The elastic lag [rad] under the same load when the holding current has fallen to
    ``current_fraction`` of the current that held ``start_lag`` [rad] (idle current reduction).

    A detent holds the load with the torque k_e I sin(N_c δ) ([paper], eq. 9; one full step is a
    quarter of the electrical period 2π/N_c), so sin(N_c δ_end) = sin(N_c δ_start) / fraction;
    past the pull-out point (a ratio above 1) the lag is one full step, where the rotor slips.
    """
    quarter = np.pi / 2 / sequencer.step_angle  # N_c
    ratio = np.sin(quarter * start_lag) / current_fraction
    return float(np.arcsin(np.clip(ratio, -1.0, 1.0)) / quarter)


def _end_current_fraction(sequencer: Sequencer, schedule: StepSchedule, start: float, end: float) -> float:
    """The fraction of the full current the drive holds at ``end`` (see
    :func:`heliostep.drive.sequencer.idle_currents`)."""
    steps = schedule.times[(schedule.times > start) & (schedule.times <= end)]
    last = float(steps[-1]) if len(steps) else start
    return sequencer.idle_current_fraction if end - last > sequencer.idle_delay else 1.0


def lost_steps(behind: float, start_lag: float, sequencer: Sequencer, schedule: StepSchedule, start: float,
               end: float) -> tuple[int, float]:
    """(steps lost, elastic lag left) [increments] from how far the rotor ends behind the command
    and the lag it held at the start (both [increments]): the lost steps are net of the elastic
    lag the load causes at the end, at the holding current of the end (:func:`held_lag`)."""
    increment = sequencer.increment
    fraction = _end_current_fraction(sequencer, schedule, start, end)
    lag = start_lag if fraction == 1.0 else held_lag(start_lag * increment, fraction, sequencer) / increment
    lost = int(np.round(behind - lag))
    return lost, float(behind - lost)


def _period(sequencer: Sequencer) -> float:
    """One electrical period of the rotor [rad]: 4 full steps."""
    return FULL_STEPS_PER_PERIOD * sequencer.step_angle


def _outcome(t_step: float, commanded: float, previous: float, t: np.ndarray, x: np.ndarray, lag: float,
             sequencer: Sequencer, settling_band: float = SETTLING_BAND):
    """One step's (missed, settling time or None, move in increments) from the rows ``t, x`` of the
    rotor from the row at the step to the row at the next step (or the end), both included."""
    increment = sequencer.increment
    period = _period(sequencer)
    move = (x[-1] - x[0]) / increment
    missed = bool(abs(move - (commanded - previous) / increment) > MISS_TOLERANCE)
    rest = commanded - lag
    rest -= period * np.round((rest - x[-1]) / period)  # the detent the rotor ends in
    outside = np.nonzero(np.abs(x - rest) > settling_band * increment)[0]
    if len(outside) == 0:
        settling = 0.0
    elif outside[-1] == len(x) - 1:
        settling = None
    else:
        j = outside[-1]  # last row outside the band; the crossing lies between j and j + 1
        band = settling_band * increment
        d0, d1 = abs(x[j] - rest) - band, abs(x[j + 1] - rest) - band
        fraction = d0 / (d0 - d1) if d0 != d1 else 1.0
        settling = float(t[j] + fraction * (t[j + 1] - t[j]) - t_step)
    return missed, settling, float(move)


def step_outcomes(trace: pd.DataFrame, rotor_column: str, sequencer: Sequencer, schedule: StepSchedule,
                  settling_band: float = SETTLING_BAND):
    """Per commanded step: (time, commanded angle, missed, settling time or None, move in increments)."""
    time = trace["time"].to_numpy()
    rotor = trace[rotor_column].to_numpy()
    end = time[-1]
    lag = float(sequencer.position(schedule.initial_index) - rotor[0])  # elastic lag held at the start
    outcomes = []
    previous = float(sequencer.position(schedule.initial_index))
    for k, (t_step, index) in enumerate(zip(schedule.times, schedule.indices)):
        if t_step > end:
            break  # the run stopped before this step
        t_next = schedule.times[k + 1] if k + 1 < len(schedule) else end
        commanded = float(sequencer.position(index))
        first = int(np.searchsorted(time, t_step, side="left"))  # the row at the step (before it)
        last = int(np.searchsorted(time, t_next, side="left"))  # the row at the next step (before it)
        last = min(max(last, first), len(time) - 1)
        missed, settling, move = _outcome(t_step, commanded, previous, time[first:last + 1],
                                          rotor[first:last + 1], lag, sequencer, settling_band)
        outcomes.append((float(t_step), commanded, missed, settling, move))
        previous = commanded
    return outcomes


def figures(trace: pd.DataFrame, metadata: Mapping) -> dict:
    """The figures (see the module docstring) evaluated on the rows of ``trace``.

    ``trace`` is an assembled trace (with ``rotor_angle_cmd`` and ``panel_angle_error``): the
    run's output trace, or the solution rows the monitor saw, assembled the same way.
    """
    roles = metadata.get("roles", {})
    sequencer, schedule = drive_from_metadata(metadata["drive"])
    rotor_column = roles.get("rotor_angle")
    time = trace["time"].to_numpy()
    result: dict = {}
    if "panel_angle_error" in trace and len(trace):
        error = np.degrees(trace["panel_angle_error"].to_numpy())
        result["max_tracking_error_deg"] = float(np.abs(error).max())
        result["rms_tracking_error_deg"] = _time_rms(error, time)
    result["peak_torque_Nm"] = _peak(trace, *(c for c in [roles.get("torque")] if c))
    result["peak_phase_current_A"] = _peak(trace, *(roles[r] for r in ("current_a", "current_b") if r in roles))
    power = roles.get("power")
    if power in trace and len(trace) > 1:
        result["electrical_energy_J"] = float(np.trapezoid(trace[power].to_numpy(), time))
    if rotor_column in trace and len(trace):
        outcomes = step_outcomes(trace, rotor_column, sequencer, schedule)
        result.update(_step_fields(outcomes, len(outcomes)))
        behind = float(trace["rotor_angle_cmd"].iloc[-1] - trace[rotor_column].iloc[-1]) / sequencer.increment
        lag = float(trace["rotor_angle_cmd"].iloc[0] - trace[rotor_column].iloc[0]) / sequencer.increment
        result["steps_lost"], result["final_lag_steps"] = lost_steps(behind, lag, sequencer, schedule,
                                                                     float(time[0]), float(time[-1]))
        result["step_outcomes"] = [{"time_s": o[0], "missed": o[2], "settling_s": o[3], "move_steps": o[4]}
                                   for o in outcomes]
    return result


def _step_fields(outcomes, commanded: int) -> dict:
    missed = [o for o in outcomes if o[2]]
    settling = [o[3] for o in outcomes]
    settled = [s for s in settling if s is not None]
    return {"missed_steps": len(missed), "steps_executed": commanded - len(missed),
            "settling_time_s": {"max": max(settled) if settled else None,
                                "mean": float(np.mean(settled)) if settled else None,
                                "not_settled": sum(1 for s in settling if s is None), "per_step": settling},
            "missed_step_times_s": [o[0] for o in missed]}


def solution_figures(solution: pd.DataFrame, metadata: Mapping) -> dict:
    """The figures from the solution rows (assembled like a trace), for ``metadata['solution_figures']``."""
    result = figures(solution, metadata)
    result["solution_rows"] = int(len(solution))
    result["end_time_s"] = float(solution["time"].iloc[-1]) if len(solution) else 0.0
    return result


class TraceSummary:
    """:func:`summarize` accumulated over a trace's rows taken in blocks (frames with the
    trace's ``columns``, in time order): the definitions evaluated on the output rows by a
    :class:`SolutionRecorder` on the assembled trace, and the rows, first and last time and last
    panel angle. It holds one block (``max_block_rows``, the largest) and the rotor's rows over
    one step interval, whatever the trace's length."""

    def __init__(self, columns, metadata: Mapping):
        self.metadata = metadata
        roles = metadata.get("roles", {})
        sequencer, schedule = drive_from_metadata(metadata["drive"])
        self.columns = list(columns)
        self.schedule = schedule
        self._recorder = SolutionRecorder(self.columns, roles, sequencer, schedule, None, block=1)
        self._panel = roles.get("panel_angle") if roles.get("panel_angle") in self.columns else None
        self.rows = 0
        self.max_block_rows = 0
        self._first_time = self._last_time = None
        self._last_panel = None

    def __call__(self, block: pd.DataFrame) -> None:
        if not len(block):
            return
        time = block["time"].to_numpy(dtype=float)
        self._recorder(block[self.columns].to_numpy(dtype=float))
        if self._first_time is None:
            self._first_time = float(time[0])
        self._last_time = float(time[-1])
        if self._panel is not None:
            self._last_panel = float(block[self._panel].iloc[-1])
        self.rows += len(block)
        self.max_block_rows = max(self.max_block_rows, len(block))

    @property
    def max_step_rows(self) -> int:
        """The most rotor rows held for a step not yet judged (one step interval)."""
        return self._recorder.max_held

    @property
    def end_time(self) -> float | None:
        return self._last_time

    def summary(self, solution: Mapping | None = None) -> dict:
        """The figures of the rows taken (see :func:`summarize`)."""
        metadata, schedule = self.metadata, self.schedule
        summary: dict = {"duration_s": self._last_time - self._first_time if self.rows else 0.0, "rows": self.rows}
        end = self._last_time if self.rows else -np.inf
        commanded = int(np.sum(schedule.times <= end))
        grid = self._recorder.figures() if self.rows else {}
        for key in ("solution_rows", "end_time_s"):
            grid.pop(key, None)
        solution = solution if solution is not None else metadata.get("solution_figures")
        chosen = dict(grid)
        if solution:
            chosen.update({k: v for k, v in solution.items() if k not in STEP_FIELDS and k != "step_outcomes"
                           and k in grid})
            outcomes = [o for o in solution.get("step_outcomes", []) if o["time_s"] <= end]
            if len(outcomes) == commanded and "step_outcomes" in grid:
                chosen.update(_step_fields([(o["time_s"], None, o["missed"], o["settling_s"], o["move_steps"])
                                            for o in outcomes], commanded))
                if solution.get("end_time_s") == float(end):
                    chosen["steps_lost"] = solution["steps_lost"]
                    chosen["final_lag_steps"] = solution["final_lag_steps"]
        chosen.pop("step_outcomes", None)
        summary.update({k: chosen.get(k) for k in ("max_tracking_error_deg", "rms_tracking_error_deg")
                        if k in chosen})
        for key in ("peak_torque_Nm", "peak_phase_current_A", "electrical_energy_J"):
            if key in chosen:
                summary[key] = chosen[key]
        summary["steps_commanded"] = commanded
        for key in STEP_FIELDS:
            if key in chosen:
                summary[key] = chosen[key]
        summary["figures_from"] = "solution" if solution else "output rows"
        if self._last_panel is not None:
            summary["final_panel_angle_deg"] = float(np.degrees(self._last_panel))
        return summary


def summarize(trace: pd.DataFrame, metadata: Mapping, solution: Mapping | None = None) -> dict:
    """The run's figures (see the module docstring) from its trace and metadata.

    ``metadata`` needs ``roles`` (role -> column) and ``drive`` (see
    :func:`heliostep.results.trace.drive_metadata`); its ``solution_figures`` (or
    ``solution``, the same dict) are the figures from every solver step, which take
    precedence over the ones the trace's rows give. (:class:`TraceSummary` fed the whole trace
    as one block.)
    """
    accumulator = TraceSummary(list(trace.columns), metadata)
    accumulator(trace)
    return accumulator.summary(solution)


def summarize_files(out_dir: str | Path) -> dict:
    """Recompute a stored run's figures from its ``trace.parquet`` and ``metadata.json``."""
    out_dir = Path(out_dir)
    trace, _ = read_trace(out_dir / "trace.parquet")
    metadata = json.loads((out_dir / "metadata.json").read_text())
    return summarize(trace, metadata)
