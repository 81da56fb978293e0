"""The figures of a run's solution: :class:`SolutionRecorder`, the master's ``monitor``.

The master shows the monitor the state at every internal CVODE step, at every event (both
sides) and at every output row; the recorder evaluates the definitions of
:mod:`heliostep.results.summary` on those rows as they come (running peaks and sums, each step
judged once the next step is reached, :class:`~heliostep.results.steps.StepJudge`), so its
memory does not grow with the run. Its :meth:`SolutionRecorder.figures` are stored in the run's
metadata (``solution_figures``) and are the figures of ``summary.json``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.run_summary import Peaks, StepFigures, Tracking
from heliostep.results.steps import StepJudge, judged_steps, lost_between, outcome_records

__all__ = ["SolutionRecorder"]


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
        self._error_sq_int = self._error_sq_sum = 0.0  # integral of e^2 (linear pieces), sum of e^2
        self._energy = 0.0
        self._peak_torque = self._peak_current = 0.0
        self._last_error: float | None = None
        self.steps = StepJudge(sequencer, schedule)

    @property
    def max_held(self) -> int:
        """The most rotor rows held at once for a step not yet judged."""
        return self.steps.max_held

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
        self._error_sq_int += float(np.sum(np.diff(t) * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0))
        self._last_error = float(error[-1])

    def figures(self) -> dict:
        """The figures of every row shown, as stored in ``metadata['solution_figures']`` (the
        definitions of :mod:`heliostep.results.summary`; ``step_outcomes`` per step,
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
            rms = float(np.sqrt(self._error_sq_int / span if span > 0 else self._error_sq_sum / self.count))
            result.update(dataclasses.asdict(Tracking(self._error_max, rms)))
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


def _role_column(index: Mapping[str, int], roles: Mapping[str, str], role: str) -> int | None:
    """The index of the column that has ``role`` (None: no such role or no such column)."""
    column = roles.get(role)
    return None if column is None else index.get(column)
