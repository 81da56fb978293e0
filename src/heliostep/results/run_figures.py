"""A run's figures after the simulation (``summary.json``), from its trace one block at a time.

:class:`RunFigures` feeds each block of a trace's figure columns
(:func:`~heliostep.results.trace.figure_columns`) to the accumulators of the summary
(:class:`~heliostep.results.summary.TraceSummary`), the light on the tube
(:class:`~heliostep.results.light.LightIntegrals`) and the holding torque (the smallest drive
ratio, :func:`~heliostep.results.tradeoffs.smallest_drive_ratio`). A trace held in memory is one
block; a streamed trace is read back from its Parquet file one row group at a time
(:func:`~heliostep.results.trace_io.iter_trace_blocks`), so the figures of a long window are
computed in memory bounded by one row group (plus the rotor's rows over one step interval), and
both are the same code. :func:`summary_at_cut` corrects the summary of an interrupted run the
same way.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.results.light import LightIntegrals
from heliostep.results.summary import TraceSummary
from heliostep.results.trace import master_block
from heliostep.results.trace_io import ROW_GROUP_ROWS, iter_trace_blocks
from heliostep.results.tradeoffs import smallest_drive_ratio, tradeoff_figures_at

__all__ = ["FigureStream", "RunFigures", "TraceSource", "present_columns", "run_figures", "summary_at_cut",
           "trace_blocks"]

#: A trace: held in memory (a frame), or a Parquet trace file read by row groups.
TraceSource = pd.DataFrame | Path


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
    """The figures of a run's trace taken in blocks (time order): the summary, and for two rows
    or more the light on the tube and the drive's trade-offs. ``columns`` are the blocks'
    columns; ``weather`` the scenario's weather file already read (None: read when needed, or
    clear sky).

    The rows are evaluated in chunks of ``block_rows`` rows counted from the trace's first row,
    whatever blocks they come in: a trace held whole and the same trace read by row groups give
    the same figures, bit for bit. ``max_rows_held`` is the most trace rows held at once (under
    ``block_rows`` plus the largest block received); ``chunks`` how many were evaluated.
    """

    def __init__(self, columns: list[str], metadata: Mapping, scenario, weather=None,
                 block_rows: int = ROW_GROUP_ROWS):
        if block_rows < 1:
            raise ValueError(f"block_rows must be at least 1, not {block_rows}")
        self.metadata, self.scenario = metadata, scenario
        self.block_rows = block_rows
        self.summary = TraceSummary(columns, metadata)
        self.light = LightIntegrals(metadata, scenario, weather)
        self._ratio = np.inf
        self._held: list[pd.DataFrame] = []
        self._held_rows = 0
        self.rows = 0
        self.chunks = 0
        self.max_rows_held = 0

    def __call__(self, block: pd.DataFrame) -> None:
        if not len(block):
            return
        self._held.append(block)
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
            self._chunk(held.iloc[start:start + self.block_rows])
            start += self.block_rows
        rest = held.iloc[start:]
        self._held = [rest] if len(rest) else []
        self._held_rows = len(rest)

    def _chunk(self, chunk: pd.DataFrame) -> None:
        self.summary(chunk)
        self.light(chunk)
        self._ratio = min(self._ratio, smallest_drive_ratio(chunk["panel_angle_ref"], self.scenario))
        self.chunks += 1

    def figures(self) -> dict:
        """The run's summary figures (empty without rows)."""
        if self._held:
            self._evaluate(final=True)
        if not self.rows:
            return {}
        figures = self.summary.summary()
        if self.rows > 1:  # light on the tube: ideal tracking, the stepped reference, the actual panel
            figures.update(self.light.figures())
            figures.update(tradeoff_figures_at(self._ratio, self.metadata, self.scenario, figures))
        return figures


def run_figures(source: TraceSource, columns: list[str], metadata: Mapping, scenario, weather=None,
                block_rows: int = ROW_GROUP_ROWS) -> RunFigures:
    """:class:`RunFigures` of a trace (held, or a Parquet file read one row group at a time),
    fed every block of those of ``columns`` it has."""
    present = present_columns(source, columns)
    figures = RunFigures(present, metadata, scenario, weather, block_rows)
    for block in trace_blocks(source, present):
        figures(block)
    return figures


class FigureStream:
    """Row sink of a run that keeps no trace: the master's row blocks, assembled block by block
    (:class:`~heliostep.results.trace.TraceAssembler`) and fed to :class:`RunFigures` as they
    come, nothing written or held beyond one chunk.

    For sweeps, whose cases need the figures only. The figures equal, bit for bit, those of the
    same run with its trace held or streamed (the same rows, in chunks of ``block_rows`` counted
    from the first row). ``metadata`` is the run's metadata dict itself: the summary takes its
    ``solution_figures`` when ``accumulator.figures()`` is asked, after the simulation. ``rows`` counts the
    rows received, ``last_time`` is the time of the last one.
    """

    def __init__(self, master_columns: list[str], assembler, columns: list[str], metadata: Mapping, scenario,
                 weather=None, block_rows: int = ROW_GROUP_ROWS):
        self.master_columns = list(master_columns)
        self.assembler = assembler
        self.columns = _present(assembler.columns(self.master_columns), columns)
        self.accumulator = RunFigures(self.columns, metadata, scenario, weather, block_rows)
        self.rows = 0
        self.last_time: float | None = None

    def __call__(self, block: np.ndarray) -> None:
        block = master_block(block, self.master_columns, "the figures of a run without trace")
        if not len(block):
            return
        frame = self.assembler(pd.DataFrame(block, columns=self.master_columns))
        self.accumulator(frame[self.columns])
        self.rows += len(frame)
        self.last_time = float(block[-1, 0])


#: Step figures of a summary that depend on judging each step (see :func:`summary_at_cut`).
_STEP_FIELDS = ("steps_commanded", "missed_steps", "steps_executed", "settling_time_s",
                "missed_step_times_s", "steps_lost", "final_lag_steps")


def _head(blocks: Iterable[pd.DataFrame], step: float) -> Iterator[pd.DataFrame]:
    """The rows before ``step`` [s] and the first row at it (the row just before the step)."""
    for block in blocks:
        time = block["time"].to_numpy()
        i = int(np.searchsorted(time, step, side="left"))
        if i < len(time):
            yield block.iloc[:i + 1] if time[i] == step else block.iloc[:i]
            return
        yield block


def summary_at_cut(source: TraceSource, columns: list[str], metadata: Mapping, summary: dict) -> dict:
    """The summary of an interrupted run without judging the step in progress at the cut.

    If the last step commanded before the cut is missed or unsettled at the cut (it has not had
    its time to complete), the step figures are recomputed up to the row just before that step,
    without it (the earlier steps judged at its time, as in a complete run). ``source`` is the
    trace (held or a file, read in blocks of ``columns``).
    """
    drive = metadata.get("drive") or {}
    times = np.asarray(drive.get("step_times", []), dtype=float)
    end = None
    for block in trace_blocks(source, ["time"]):
        end = float(block["time"].iloc[-1])
    if end is None:
        return summary
    before = times[times <= end]
    if not len(before):
        return summary
    last_step = float(before[-1])
    missed_last = last_step in set(summary.get("missed_step_times_s") or [])
    per_step = (summary.get("settling_time_s") or {}).get("per_step") or []
    unsettled_last = bool(per_step) and per_step[-1] is None
    lost = summary.get("steps_lost")
    if not (missed_last or unsettled_last or (lost not in (None, 0))):
        return summary
    keep = times < last_step
    drive_before = {**drive, "step_times": [float(t) for t in times[keep]],
                    "step_indices": [int(k) for k in np.asarray(drive["step_indices"])[keep]]}
    head = TraceSummary(present_columns(source, columns), {**metadata, "drive": drive_before})
    for block in _head(trace_blocks(source, columns), last_step):
        head(block)
    fixed = dict(summary)
    if head.rows:
        partial = head.summary()
        for key in _STEP_FIELDS:
            if key in partial:
                fixed[key] = partial[key]
    else:
        for key in _STEP_FIELDS:
            fixed.pop(key, None)
    fixed["step_in_progress_at_cut_s"] = last_step
    return fixed
