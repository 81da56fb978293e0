"""A run's figures (``summary.json``): their definitions, the output rows' part, the summary.

The figures come from the solution itself (:class:`~heliostep.results.figures.solution.SolutionRecorder`);
the output rows add what only they give (:class:`OutputRows`); :func:`build_summary` joins both and
:func:`summary_at_cut` summarizes an interrupted run.

Details: docs/running.md, ``heliostep.results.figures.summary``.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.figures.run_summary import STEP_FIELDS, Peaks, RunSummary, StepFigures, Tracking
from heliostep.results.figures.solution import SolutionRecorder
from heliostep.results.figures.steps import (
    FULL_STEPS_PER_PERIOD,
    MISS_TOLERANCE,
    SETTLING_BAND,
    StepJudge,
    StepOutcome,
    held_lag,
    judged_steps,
    lost_between,
    lost_steps,
)
from heliostep.results.trace.files import read_trace
from heliostep.results.trace.frame import drive_from_metadata

__all__ = [
    "FULL_STEPS_PER_PERIOD",
    "MISS_TOLERANCE",
    "SETTLING_BAND",
    "STEP_FIELDS",
    "CutHead",
    "OutputRows",
    "SolutionRecorder",
    "TraceRow",
    "build_summary",
    "held_lag",
    "lost_steps",
    "summarize",
    "summarize_files",
    "summary_at_cut",
    "trace_summary",
]


@dataclass(frozen=True)
class TraceRow:
    """A trace row as the step figures need it: its time [s], the rotor angle [rad] (None without
    the role) and whether the row before it has the same time (the second row at a step)."""

    time: float
    rotor: float | None
    repeated: bool


@dataclass(frozen=True)
class CutHead:
    """The trace up to the last step reached, ``step_s`` [s]: its rows before the step and the
    first at it (``exact``: there is one; the master writes a row just before every step), as
    the summary at a cut judges them: ``rows`` of them, the last one ``last``."""

    step_s: float
    rows: int
    last: TraceRow | None
    exact: bool


class OutputRows:
    """What the summary takes from the trace's output rows (frames with ``columns``, in time
    order, in blocks of any size): their number, first and last row, the last panel angle, and
    the steps judged on them (:class:`~heliostep.results.figures.steps.StepJudge`), with the rows up to
    the last step reached (:class:`CutHead`) for :func:`summary_at_cut`. It holds the rotor's
    rows of one step interval, whatever the trace's length."""

    def __init__(
        self, columns: Sequence[str], roles: Mapping[str, str], sequencer: Sequencer, schedule: StepSchedule
    ) -> None:
        self.columns = list(columns)
        self.sequencer, self.schedule = sequencer, schedule
        self._panel = roles.get("panel_angle") if roles.get("panel_angle") in self.columns else None
        self._rotor = roles.get("rotor_angle") if roles.get("rotor_angle") in self.columns else None
        self.tracked = "panel_angle_error" in self.columns  # the tracking figures apply
        self.powered = roles.get("power") in self.columns  # the energy applies (two rows or more)
        self.steps = StepJudge(sequencer, schedule) if self._rotor is not None else None
        self.rows = 0
        self.max_block_rows = 0
        self.first: TraceRow | None = None
        self.last: TraceRow | None = None
        self.last_panel: float | None = None  # [rad]
        self.head: CutHead | None = None
        self._reached = 0  # the steps whose time the rows have reached

    @property
    def max_step_rows(self) -> int:
        """The most rotor rows held for a step not yet judged (one step interval)."""
        return self.steps.max_held if self.steps is not None else 0

    def __call__(self, block: pd.DataFrame) -> None:
        if not len(block):
            return
        time = block["time"].to_numpy(dtype=float)
        rotor = block[self._rotor].to_numpy(dtype=float) if self._rotor is not None else None
        previous = self.last
        self._note_head(time, rotor, previous)
        if self.steps is not None:
            if rotor is None:  # the judge exists only with the rotor's column
                raise RuntimeError("steps judged without the rotor angle's column")
            self.steps(time, rotor)
        if self.first is None:
            self.first = TraceRow(float(time[0]), None if rotor is None else float(rotor[0]), False)
        self.last = TraceRow(
            float(time[-1]), None if rotor is None else float(rotor[-1]), _repeated(time, len(time) - 1, previous)
        )
        if self._panel is not None:
            self.last_panel = float(block[self._panel].iloc[-1])
        self.rows += len(block)
        self.max_block_rows = max(self.max_block_rows, len(block))

    def _note_head(self, time: np.ndarray, rotor: np.ndarray | None, previous: TraceRow | None) -> None:
        """The rows up to the last step these rows reach, if they reach a step not reached before."""
        reached = int(np.searchsorted(self.schedule.times, time[-1], side="right"))
        if reached <= self._reached:
            return
        self._reached = reached
        step = float(self.schedule.times[reached - 1])
        i = int(np.searchsorted(time, step, side="left"))  # the first row at or after the step
        exact = bool(time[i] == step)
        j = i if exact else i - 1  # the last row kept: the one at the step, or the one before it
        if j < 0:
            last = previous
        else:
            last = TraceRow(float(time[j]), None if rotor is None else float(rotor[j]), _repeated(time, j, previous))
        self.head = CutHead(step, self.rows + j + 1, last, exact)

    def ends(self) -> tuple[TraceRow, TraceRow]:
        """The first and the last row taken; RuntimeError before any row."""
        if self.first is None or self.last is None:
            raise RuntimeError("no output row taken")
        return self.first, self.last

    def judge(self) -> StepJudge:
        """The steps judged on the rows; RuntimeError without the rotor angle's column."""
        if self.steps is None:
            raise RuntimeError("no steps judged: the trace has no rotor angle")
        return self.steps

    def lost(self, last: TraceRow, schedule: StepSchedule) -> tuple[int, float]:
        """(steps lost, elastic lag left) [increments] of the rows from the first to ``last``."""
        first, _ = self.ends()
        if first.rotor is None or last.rotor is None:
            raise RuntimeError("steps lost asked of rows without the rotor angle")
        return lost_between((first.time, first.rotor), (last.time, last.rotor), last.repeated, self.sequencer, schedule)


def _repeated(time: np.ndarray, j: int, previous: TraceRow | None) -> bool:
    """Row ``j`` of a block has the time of the row before it (the previous block's last)."""
    if j >= 1:
        return bool(time[j] == time[j - 1])
    return previous is not None and previous.time == float(time[0])


def _part(kind: type, figures: Mapping):
    """The typed part ``kind`` (a dataclass) of stored figures, by its field names."""
    return kind(**{f.name: figures[f.name] for f in dataclasses.fields(kind)})


def _step_figures(
    solution: Mapping | None,
    end: float,
    commanded: int,
    output_outcomes: Callable[[], list[StepOutcome]],
    output_lost: Callable[[], tuple[int, float]],
) -> StepFigures:
    """The step figures up to ``end`` [s] (``commanded`` steps): the solution's outcomes of the
    steps up to ``end`` when there is one for each, with its steps lost when it ends at ``end``
    too; else (no solution, or it misses steps) those judged on the output rows."""
    outcomes = [StepOutcome.from_record(o) for o in (solution or {}).get("step_outcomes", []) if o["time_s"] <= end]
    if solution and len(outcomes) == commanded:
        if solution.get("end_time_s") == float(end):
            lost = (solution["steps_lost"], solution["final_lag_steps"])
        else:  # the solution went on past the last output row (a run that failed or was stopped)
            lost = output_lost()
        return StepFigures.of(judged_steps(outcomes, commanded), lost)
    outcomes = output_outcomes()
    return StepFigures.of(judged_steps(outcomes, len(outcomes)), output_lost())


def build_summary(solution: Mapping | None, rows: OutputRows, figures_from: str = "solution") -> RunSummary:
    """The summary of a run from its solution's figures (:meth:`SolutionRecorder.figures`) and
    its output rows: the solution gives every figure; the output rows say which apply (the roles
    the trace has, two rows for an energy), the rows, the duration, the final panel angle, and
    the steps lost when the solution went on past the last output row.

    The solution's rows include every output row (the master shows the monitor each row it
    writes), so it has each figure that the output rows would have and an outcome for each step
    up to the last output row.
    """
    if not rows.rows:
        return RunSummary(0.0, 0, None, None, None, 0, None, figures_from, None)
    if solution is None:
        raise RuntimeError("a summary of output rows needs their solution's figures")
    first, last = rows.ends()
    end = last.time
    commanded = int(np.sum(rows.schedule.times <= end))
    steps = None
    if rows.steps is not None:
        judge = rows.steps
        steps = _step_figures(
            solution,
            end,
            commanded,
            lambda: judge.outcomes_at_end(end),
            lambda: rows.lost(last, rows.schedule),
        )
    return RunSummary(
        duration_s=end - first.time,
        rows=rows.rows,
        tracking=_part(Tracking, solution) if rows.tracked else None,
        peaks=_part(Peaks, solution),
        electrical_energy_J=solution.get("electrical_energy_J") if rows.powered and rows.rows > 1 else None,
        steps_commanded=commanded,
        steps=steps,
        figures_from=figures_from,
        final_panel_angle_deg=None if rows.last_panel is None else float(np.degrees(rows.last_panel)),
    )


def summary_at_cut(summary: RunSummary, rows: OutputRows, solution: Mapping | None) -> RunSummary:
    """The summary of an interrupted run without judging the step in progress at the cut.

    If the last step commanded before the cut is missed or unsettled at the cut (it has not had
    its time to complete), or steps are lost, the step figures are those of the rows up to that
    step (:attr:`OutputRows.head`: the rows before it and the row just before it), without it
    (the earlier steps judged at its time, as in a complete run), and ``step_in_progress_at_cut_s``
    says which step that is.
    """
    if not rows.rows:
        return summary
    times, end = rows.schedule.times, rows.ends()[1].time
    before = times[times <= end]
    steps = summary.steps
    if not len(before) or steps is None:
        return summary
    last_step = float(before[-1])
    missed_last = last_step in set(steps.missed_step_times_s or [])
    per_step = steps.settling_time_s.per_step or []
    unsettled_last = bool(per_step) and per_step[-1] is None
    if not (missed_last or unsettled_last or (steps.steps_lost not in (None, 0))):
        return summary
    head = rows.head
    if head is None or head.step_s != last_step:
        raise RuntimeError(f"the rows up to the step at {last_step} s were not kept")
    head_last = head.last
    if not head.rows:
        return dataclasses.replace(summary, steps_commanded=None, steps=None, step_in_progress_at_cut_s=last_step)
    if head_last is None:  # the head has rows, so a last one
        raise RuntimeError(f"the last row before the step at {last_step} s was not kept")
    keep = times < last_step
    schedule = StepSchedule(
        times=times[keep], indices=np.asarray(rows.schedule.indices)[keep], initial_index=rows.schedule.initial_index
    )
    commanded = int(np.sum(schedule.times <= head_last.time))
    # on the output rows, the steps before the cut's were judged at the row at the next step, as
    # the rows up to the cut's step judge them (the row at the step is there: ``head.exact``)
    step_figures = _step_figures(
        solution,
        head_last.time,
        commanded,
        lambda: rows.judge().outcomes[: len(schedule)],
        lambda: rows.lost(head_last, schedule),
    )
    return dataclasses.replace(
        summary, steps_commanded=commanded, steps=step_figures, step_in_progress_at_cut_s=last_step
    )


def trace_summary(
    trace: pd.DataFrame, metadata: Mapping, solution: Mapping | None = None
) -> tuple[RunSummary, OutputRows, Mapping | None]:
    """(summary, output rows, solution figures used or None) of a stored trace and its metadata
    (see :func:`summarize`); the rows and the solution figures are those :func:`summary_at_cut` takes."""
    roles = metadata.get("roles", {})
    sequencer, schedule = drive_from_metadata(metadata["drive"])
    columns = list(trace.columns)
    rows = OutputRows(columns, roles, sequencer, schedule)
    rows(trace)
    stored = solution if solution is not None else metadata.get("solution_figures")
    if stored:
        return build_summary(stored, rows), rows, stored
    recorder = SolutionRecorder(columns, roles, sequencer, schedule, None, block=1)  # the trace's rows alone
    if len(trace):
        recorder(trace[columns].to_numpy(dtype=float))
    return build_summary(recorder.figures(), rows, figures_from="output rows"), rows, None


def summarize(trace: pd.DataFrame, metadata: Mapping, solution: Mapping | None = None) -> dict:
    """The run's figures (see the module docstring) from its trace and metadata.

    ``metadata`` needs ``roles`` (role -> column) and ``drive`` (see
    :func:`heliostep.results.trace.frame.drive_metadata`); its ``solution_figures`` (or ``solution``,
    the same dict) are the figures from every solver step (:func:`build_summary`). Without them
    the definitions are evaluated on the trace's rows (``figures_from``: ``"output rows"``).
    """
    return trace_summary(trace, metadata, solution)[0].figures()


def summarize_files(out_dir: str | Path) -> dict:
    """Recompute a stored run's figures from its ``trace.parquet`` and ``metadata.json``."""
    out_dir = Path(out_dir)
    trace, _ = read_trace(out_dir / "trace.parquet")
    metadata = json.loads((out_dir / "metadata.json").read_text())
    return summarize(trace, metadata)
