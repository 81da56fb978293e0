"""A run's figures (``summary.json``), computed in the one pass of its simulation.

:class:`RunFigures` owns them: held, streamed and figures-only runs feed it the same rows, so they
give the same figures bit for bit.

Details: docs/running.md, ``heliostep.results.figures.run_figures``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TypeAlias

import numpy as np
import pandas as pd

from heliostep.drive.inputs import DriveInputs
from heliostep.results.figures.run_summary import RunStatus, RunSummary, night
from heliostep.results.figures.solution import SolutionRecorder
from heliostep.results.figures.stow import StowMoveFigures
from heliostep.results.figures.summary import OutputRows, build_summary, summary_at_cut
from heliostep.results.figures.tradeoffs import smallest_drive_ratio, tradeoff_figures_at
from heliostep.results.light.on_tube import LightIntegrals
from heliostep.results.trace.files import ROW_GROUP_ROWS, iter_trace_blocks
from heliostep.results.trace.frame import TraceAssembler, drive_from_metadata, master_block

__all__ = [
    "FigureStream",
    "RunFigures",
    "TraceSource",
    "present_columns",
    "run_figures",
    "solution_recorder",
    "trace_blocks",
]

#: A trace: held in memory (a frame), or a Parquet trace file read by row groups.
TraceSource: TypeAlias = pd.DataFrame | Path


def present_columns(source: TraceSource, columns: list[str]) -> list[str]:
    """``time`` and those of ``columns`` the trace has (a file: from its schema, no rows read)."""
    if isinstance(source, pd.DataFrame):
        names = source.columns
    else:
        import pyarrow.parquet as pq

        names = pq.read_schema(source).names
    return _present(names, columns)


def _present(names, columns: list[str]) -> list[str]:
    """``time`` and those of ``columns`` (once each, in their order) that are among ``names``."""
    names = set(names)
    return ["time"] + [c for c in dict.fromkeys(columns) if c in names and c != "time"]


def trace_blocks(source: TraceSource, columns: list[str]) -> Iterator[pd.DataFrame]:
    """``time`` and those of ``columns`` the trace has, in blocks: a held trace as one block, a
    Parquet trace file one row group at a time."""
    present = present_columns(source, columns)
    if isinstance(source, pd.DataFrame):
        if len(source):
            yield source[present]
        return
    yield from iter_trace_blocks(source, present)


class RunFigures:
    """The figures of a run, fed while it simulates: the solver steps to :attr:`solution` (the
    master's ``monitor``; None: ``metadata['solution_figures']`` are used), the output rows (frames
    with at least ``columns``, in time order, blocks of any size) to the call. ``weather`` is the
    scenario's weather file already read (None: read when needed, or clear sky); ``window``
    (start, duration [s]) says whether the summary says ``night``; ``light_first_order``: the
    light's first-order stepping terms computed (:class:`~heliostep.results.light.on_tube.LightIntegrals`).

    The output rows are evaluated in chunks of ``block_rows`` rows counted from the first row,
    whatever blocks they come in. ``max_rows_held`` is the most output rows held at once (under
    ``block_rows`` plus the largest block received); ``chunks`` how many were evaluated.
    """

    def __init__(
        self,
        columns: Sequence[str],
        metadata: Mapping,
        scenario,
        weather=None,
        block_rows: int = ROW_GROUP_ROWS,
        solution: SolutionRecorder | None = None,
        window: tuple[pd.Timestamp, float] | None = None,
        light_first_order: bool = True,
    ):
        if block_rows < 1:
            raise ValueError(f"block_rows must be at least 1, not {block_rows}")
        self.columns = list(columns)
        self.metadata, self.scenario = metadata, scenario
        self.block_rows = block_rows
        self.solution = solution
        self.window = window
        sequencer, schedule = drive_from_metadata(metadata["drive"])
        self.output = OutputRows(self.columns, metadata.get("roles", {}), sequencer, schedule)
        self.light = LightIntegrals(metadata, scenario, weather, first_order=light_first_order)
        self.stow = StowMoveFigures(metadata, sequencer, schedule)
        self._ratio = np.inf
        self._held: list[pd.DataFrame] = []
        self._held_rows = 0
        self.rows = 0
        self.chunks = 0
        self.max_rows_held = 0
        self._solution_figures: dict | None = None

    @classmethod
    def of_run(
        cls,
        master_columns: list[str],
        inputs: DriveInputs,
        roles: Mapping[str, str],
        columns: list[str],
        metadata: Mapping,
        scenario,
        weather=None,
        block_rows: int = ROW_GROUP_ROWS,
        light_first_order: bool = True,
        solution: SolutionRecorder | None = None,
    ) -> RunFigures:
        """The figures of a run about to simulate: the master's ``master_columns``, the output rows'
        ``columns`` (those of the figures, :func:`~heliostep.results.trace.frame.figure_columns`);
        ``solution``: the recorder of its solver steps, if it has begun (:func:`solution_recorder`)."""
        solution = solution if solution is not None else solution_recorder(master_columns, inputs, roles)
        present = _present(TraceAssembler(inputs, dict(roles)).columns(master_columns), columns)
        window = (inputs.window_start, inputs.duration)
        return cls(present, metadata, scenario, weather, block_rows, solution, window, light_first_order)

    def __call__(self, block: pd.DataFrame) -> None:
        if not len(block):
            return
        self._held.append(block[self.columns])
        self._held_rows += len(block)
        self.rows += len(block)
        self.max_rows_held = max(self.max_rows_held, self._held_rows)
        if self._held_rows >= self.block_rows:
            self._evaluate(final=False)

    def _evaluate(self, final: bool) -> None:
        """Evaluate the held rows in chunks of ``block_rows`` (and, when ``final``, the rest)."""
        held = pd.concat(self._held, ignore_index=True) if len(self._held) > 1 else self._held[0]
        start = 0
        while len(held) - start >= self.block_rows or (final and start < len(held)):
            self._chunk(held.iloc[start : start + self.block_rows])
            start += self.block_rows
        rest = held.iloc[start:]
        self._held = [rest] if len(rest) else []
        self._held_rows = len(rest)

    def _chunk(self, chunk: pd.DataFrame) -> None:
        self.output(chunk)
        self.light(chunk)
        self.stow(chunk)
        self._ratio = min(self._ratio, smallest_drive_ratio(chunk["panel_angle_ref"], self.scenario))
        self.chunks += 1

    def solution_figures(self) -> dict | None:
        """The figures of every solver step (None: none was shown), for ``metadata['solution_figures']``."""
        if self.solution is None:
            return self.metadata.get("solution_figures")
        if self._solution_figures is None and len(self.solution):
            self._solution_figures = self.solution.figures()
        return self._solution_figures

    def summary(self, interrupted: bool = False) -> RunSummary | None:
        """The run's summary (None without an output row); ``interrupted``: not judging the step in
        progress at the cut (:func:`~heliostep.results.figures.summary.summary_at_cut`)."""
        if self._held:
            self._evaluate(final=True)
        if not self.rows:
            return None
        solution = self.solution_figures()
        summary = build_summary(solution, self.output, "solution" if solution else "output rows")
        if self.rows > 1:  # light on the tube: ideal tracking, the stepped reference, the actual panel
            light = self.light.figures(solution)  # corrected between the rows by the solution's error integrals
            tradeoffs = tradeoff_figures_at(self._ratio, self.metadata, self.scenario, {**summary.figures(), **light})
            summary = _replace(summary, light=light, tradeoffs=tradeoffs, wind=self._wind_figures(solution))
        if interrupted:
            summary = summary_at_cut(summary, self.output, solution)
        if self.window is not None:
            is_night, warning = night(self.scenario.site, *self.window)
            summary = _replace(summary, night=is_night, night_warning=warning)
        return summary

    def _wind_figures(self, solution: dict | None) -> dict | None:
        """The wind's figures: its peak moment and, with stow, the moves and the time stowed (None: no wind signal)."""
        worst = self.metadata.get("drive", {}).get("wind")
        if worst is None:
            return None
        figures = self.stow.figures((solution or {}).get("step_outcomes", []))
        duration = self.window[1] if self.window is not None else None
        return {
            "wind_peak_moment_Nm": worst["peak_moment_Nm"],
            **figures,
            "stowed_share": figures["stowed_time_s"] / duration if duration else None,
        }


def _replace(summary: RunSummary, **changes) -> RunSummary:
    return dataclasses.replace(summary, **changes)


def run_figures(
    source: TraceSource,
    columns: list[str],
    metadata: Mapping,
    scenario,
    weather=None,
    block_rows: int = ROW_GROUP_ROWS,
    window: tuple[pd.Timestamp, float] | None = None,
) -> RunFigures:
    """:class:`RunFigures` of a stored trace (held, or a Parquet file read one row group at a
    time) and its metadata (``solution_figures``), fed every block of those of ``columns`` it has."""
    present = present_columns(source, columns)
    figures = RunFigures(present, metadata, scenario, weather, block_rows, window=window)
    for block in trace_blocks(source, present):
        figures(block)
    return figures


def solution_recorder(master_columns: list[str], inputs: DriveInputs, roles: Mapping[str, str]) -> SolutionRecorder:
    """The recorder of a run's solver steps (the master's ``master_columns``) on its inputs' steps."""
    return SolutionRecorder(
        master_columns,
        roles,
        inputs.sequencer,
        inputs.schedule,
        inputs.panel_reference(),
        span=(0.0, inputs.duration),  # the envelopes' bins span the window
    )


class FigureStream:
    """Row sink of a run that keeps no trace: the master's row blocks, assembled block by block
    (:class:`~heliostep.results.trace.frame.TraceAssembler`) and fed to ``figures`` as they come,
    nothing written or held beyond one chunk (a
    :class:`~heliostep.results.trace.sinks.RowSink`).

    For sweeps, whose cases need the figures only. The figures equal, bit for bit, those of the
    same run with its trace held or streamed (the same rows, in chunks counted from the first
    row). ``rows`` counts the rows received, ``last_time`` is the time of the last one.
    """

    trace_kept = False
    held_trace = None
    trace_file = None

    def __init__(self, master_columns: list[str], assembler: TraceAssembler, figures: RunFigures):
        self.master_columns = list(master_columns)
        self.assembler = assembler
        self.columns = assembler.columns(self.master_columns)
        self.accumulator = figures
        self.rows = 0
        self.last_time: float | None = None

    def __call__(self, block: np.ndarray) -> None:
        block = master_block(block, self.master_columns, "the figures of a run without trace")
        if not len(block):
            return
        frame = self.assembler(pd.DataFrame(block, columns=self.master_columns))
        self.accumulator(frame)
        self.rows += len(frame)
        self.last_time = float(block[-1, 0])

    def finish(self, status: RunStatus) -> RunStatus:
        return status

    def close(self, metadata: Mapping[str, str]) -> None:
        pass

    def abort(self) -> None:
        pass
