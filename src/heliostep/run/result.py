"""The outcome of a run: :class:`RunResult` (trace, figures, metadata, status) and :class:`RunFailed`.

The output folder is written by :mod:`heliostep.results` (:func:`~heliostep.results.output.run_files.write_run_records`,
:func:`~heliostep.results.output.rescue.write_rescue`) and the figures drawn by
:func:`heliostep.plots.drawing.draw_run_figures`; :meth:`RunResult.write` and :meth:`RunResult.plot` call them.
"""

from __future__ import annotations

import shutil
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from heliostep.drive.inputs import DriveInputs
from heliostep.errors import InputError, RunFailure
from heliostep.results.figures.run_figures import present_columns
from heliostep.results.figures.run_summary import RunMetadata, RunStatus, RunSummary, summary_record
from heliostep.results.figures.solution import SolutionPlotData
from heliostep.results.output.folder import check_foreign, hold_folder, manifest_files, write_swapped
from heliostep.results.output.rescue import write_rescue
from heliostep.results.output.run_files import run_file_names, write_run_records
from heliostep.results.trace.csv_text import LOCAL_TIME
from heliostep.results.trace.files import read_trace
from heliostep.results.trace.format import local_times
from heliostep.results.trace.frame import trace_metadata
from heliostep.scenario import Scenario

__all__ = ["RunFailed", "RunResult", "run_file_names"]


@dataclass
class RunResult:
    """The outcome of :func:`~heliostep.run.run_scenario`.

    ``complete`` is False when the simulation failed or was interrupted part-way; ``error`` then
    says why, ``reason`` is ``"failed"`` or ``"interrupted"``, ``time_reached`` the simulated time
    reached [s], and ``trace`` holds the rows computed until then.

    ``trace`` is the trace in memory (``held_trace``) for windows up to
    :data:`~heliostep.run.HELD_TRACE_MAX_DURATION`; for longer windows it was streamed to
    ``trace_file`` (a Parquet trace) while simulating and each access reads it from there (use
    :meth:`trace_columns` for only some columns). After :meth:`write` ``trace_file`` is the
    output folder's ``trace.parquet``; a file in a temporary folder of the run's own is removed
    with the result.

    ``figures`` is the run's :class:`~heliostep.results.figures.run_summary.RunSummary` (None without a
    trace row) and ``summary`` the same as a dict (``summary.json`` after the status). The
    summary of an interrupted run does not judge the step in progress at the cut: when the
    last step before the cut looks missed or unsettled there, the step figures (steps commanded,
    executed, missed, lost, settling) are those up to that step, and ``step_in_progress_at_cut_s``
    gives its time.

    ``unwritten_trace`` holds the rows computed after the last row of ``trace_file`` that could
    not be written to it (a full disk, a file-size limit; the run then failed there): :attr:`trace`
    and :meth:`write` give them after the file's rows, :meth:`write_rescue` saves them all.

    ``solution_plot`` is what the plots draw from every solver step (the rows around the peak
    |torque|, the per-bin envelopes; :class:`~heliostep.results.figures.solution.SolutionPlotData`), not in
    ``summary.json``; None for a result made without the master's monitor.
    """

    scenario: Scenario
    held_trace: pd.DataFrame | None
    figures: RunSummary | None
    metadata: RunMetadata
    complete: bool = True
    error: str | None = None
    inputs: DriveInputs | None = field(default=None, repr=False)
    reason: str | None = None
    time_reached: float | None = None
    trace_file: Path | None = None
    temporary_folder: Path | None = field(default=None, repr=False)
    weather: object = field(default=None, repr=False)  # the weather file read once (None: clear sky)
    trace_kept: bool = True  # False: RunOptions(keep_trace=False), figures only
    solution_plot: SolutionPlotData | None = field(default=None, repr=False)  # drawn from every solver step
    unwritten_trace: pd.DataFrame | None = field(default=None, repr=False)  # rows after trace_file's end

    def __post_init__(self) -> None:
        if not self.trace_kept:
            if self.held_trace is not None or self.trace_file is not None:
                raise ValueError("a RunResult without trace (trace_kept=False) has no held trace nor trace file")
            return
        if self.held_trace is None and self.trace_file is None:
            raise ValueError("a RunResult needs its trace in memory or in a trace file")
        if self.temporary_folder is not None:  # the run's own folder goes with the result
            weakref.finalize(self, shutil.rmtree, str(self.temporary_folder), True)

    @property
    def summary(self) -> dict:
        """The figures (``summary.json`` after the status; empty without a trace row)."""
        return self.figures.figures() if self.figures is not None else {}

    @property
    def status(self) -> RunStatus:
        return RunStatus(self.complete, self.error, self.reason, self.time_reached)

    def _require_trace(self) -> None:
        if not self.trace_kept:
            raise InputError(
                f"{self.scenario.name}: this run kept no trace (RunOptions(keep_trace=False)): "
                "only its summary and metadata"
            )

    def _streamed_file(self) -> Path:
        """The trace file of a run that holds no trace in memory (:meth:`__post_init__` checks it has one)."""
        if self.trace_file is None:
            raise RuntimeError(f"{self.scenario.name}: the run holds no trace in memory and has no trace file")
        return self.trace_file

    @property
    def trace(self) -> pd.DataFrame:
        """The trace: held in memory, or read from :attr:`trace_file` at each access."""
        self._require_trace()
        if self.held_trace is not None:
            return self.held_trace
        return self._with_unwritten(read_trace(self._streamed_file())[0])

    def _with_unwritten(self, frame: pd.DataFrame) -> pd.DataFrame:
        if self.unwritten_trace is None:
            return frame
        return pd.concat([frame, self.unwritten_trace[list(frame.columns)]], ignore_index=True)

    @property
    def trace_column_names(self) -> list[str]:
        self._require_trace()
        if self.held_trace is not None:
            return list(self.held_trace.columns)
        import pyarrow.parquet as pq

        return list(pq.read_schema(self._streamed_file()).names)

    @property
    def trace_rows(self) -> int:
        """The trace's number of rows (a file's from its footer, no row read)."""
        self._require_trace()
        if self.held_trace is not None:
            return len(self.held_trace)
        import pyarrow.parquet as pq

        unwritten = len(self.unwritten_trace) if self.unwritten_trace is not None else 0
        return pq.ParquetFile(self._streamed_file()).metadata.num_rows + unwritten

    def trace_columns(self, columns: list[str]) -> pd.DataFrame:
        """``time`` and those of ``columns`` the trace has, as a frame (read from the file when
        streamed: the other columns are never loaded)."""
        self._require_trace()
        if self.held_trace is not None:
            return self.held_trace[present_columns(self.held_trace, columns)]
        trace_file = self._streamed_file()
        return self._with_unwritten(read_trace(trace_file, present_columns(trace_file, columns))[0])

    def to_pandas(self, index: str | None = None) -> pd.DataFrame:
        """The trace as a DataFrame (a copy), indexed by row (``index=None``) or, with
        ``index="local_time"``, by each row's instant in the site's time zone: a time-zone-aware
        DatetimeIndex named ``local_time`` (the window's start plus ``time``, to the nanosecond; as pvlib's
        series are indexed), ``time`` [s from the start] kept as a column."""
        frame = self.trace.copy()
        if index is None:
            return frame
        if index != LOCAL_TIME:
            raise ValueError(f"to_pandas: index {index!r}; expected None or {LOCAL_TIME!r}")
        stamps = local_times(frame["time"].to_numpy(), self.metadata["window_start"], self.metadata["timezone"])
        return frame.set_axis(stamps.rename(LOCAL_TIME), axis="index")

    def plot(self, out_dir: str | Path) -> list[Path]:
        """Write the paper's Figs. 8–14 and the power on the tube for this run into ``out_dir``
        (:func:`~heliostep.plots.drawing.draw_run_figures`; drawn into a staging folder, swapped in and added
        to the folder's manifest, the folder's lock held meanwhile)."""
        self._require_trace()
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        with hold_folder(out_dir):
            return list(write_swapped(out_dir, self._draw, keep=manifest_files(out_dir)).values())

    def _draw(self, out_dir: Path) -> list[Path]:
        from heliostep.plots.drawing import draw_run_figures  # (matplotlib: imported only to draw)

        return draw_run_figures(self, out_dir)

    def trace_metadata(self) -> dict[str, str]:
        return trace_metadata(
            self.scenario.name,
            self.metadata,
            self.trace_column_names,
            self.complete,
            self.reason,
            self.time_reached,
            self.error,
        )

    def summary_record(self) -> dict:
        """What ``summary.json`` holds: completeness (and why not), then the figures."""
        return summary_record(self.figures, self.status, self.metadata.get("terminated"))

    def write(
        self,
        out_dir: str | Path,
        plots: bool = True,
        csv: bool = True,
        should_stop: Callable[[], bool] | None = None,
        before_figures: Callable[[], None] | None = None,
    ) -> dict[str, Path]:
        """Write trace (Parquet, and CSV unless ``csv=False``), summary.json, metadata.json and
        plots into ``out_dir`` (a run that kept no trace: summary.json and metadata.json). The
        trace's metadata, summary.json and metadata.json all say ``complete`` (and, when not,
        ``reason`` and the time reached). Returns name -> path.

        The folder's lock is held meanwhile (:func:`~heliostep.results.output.folder.hold_folder`:
        another run writing there is an InputError). The trace and records are written into a staging
        folder, then swapped in (:func:`~heliostep.results.output.run_files.write_run_records`): the earlier
        run's files (those its manifest lists) are removed and the new ones renamed into place, signals
        held back, so no interrupt leaves old and new files side by side; a file heliostep did not write
        is never removed or replaced. ``before_figures()``, when given, is called then (the command line
        reports the figures there). The figures are drawn last, and swapped in the same way, unless
        ``should_stop()`` has turned true.
        """
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        with hold_folder(out_dir):
            check_foreign(out_dir, run_file_names(plots, csv))
            written = write_run_records(out_dir, self, csv)
            if before_figures is not None:
                before_figures()
            if plots and self.trace_kept and self.trace_rows and not (should_stop and should_stop()):
                written.update(write_swapped(out_dir, self._draw, keep=written))
        return written

    def write_rescue(self, folder: Path) -> list[Path]:
        """Every computed row and the records into ``folder`` (no figures), each file under the
        process's file-size limit (:func:`heliostep.results.output.rescue.write_rescue`: the trace in parts if
        need be)."""
        return write_rescue(folder, self)


class RunFailed(RunFailure):
    """The simulation failed or was interrupted part-way; ``result`` holds the incomplete run
    (``result.reason`` says which)."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result

    @property
    def interrupted(self) -> bool:
        return self.result.reason == "interrupted"
