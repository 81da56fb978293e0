"""The outcome of a run: :class:`RunResult` (trace, figures, metadata; written by
:meth:`RunResult.write`) and :class:`RunFailed`."""

from __future__ import annotations

import itertools
import os
import pickle
import shutil
import weakref
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from heliostep.drive.inputs import DriveInputs
from heliostep.errors import InputError, RunFailure
from heliostep.results.outputs import TMP_PREFIX
from heliostep.results.rescue import write_text_parts, write_trace_parts
from heliostep.results.run_figures import present_columns
from heliostep.results.run_files import (
    FIGURE_FILES,
    POWER_FILE,
    RECORD_FILES,
    TRACE_FILES,
    place_trace_file,
    record_texts,
    write_held_trace,
    write_joined_trace,
    write_records,
    write_trace_csv,
)
from heliostep.results.run_folder import check_foreign, hold_folder, manifest_files, staging_folder, swap_in
from heliostep.results.run_summary import RunMetadata, RunStatus, RunSummary, summary_record
from heliostep.results.solution import SolutionPlotData
from heliostep.results.trace import trace_metadata
from heliostep.results.trace_io import iter_trace_blocks, read_trace
from heliostep.run.drawing import CHILD_FIGURES, OWN_FIGURES, FigureJob, draw_figure_names, draw_figures
from heliostep.run.forked import Helper, can_fork, in_parallel
from heliostep.scenario import Scenario

__all__ = ["CHILD_FIGURES", "OWN_FIGURES", "RunFailed", "RunResult", "run_file_names"]


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

    ``figures`` is the run's :class:`~heliostep.results.run_summary.RunSummary` (None without a
    trace row) and ``summary`` the same as a dict (``summary.json`` after the status). The
    summary of an interrupted run does not judge the step in progress at the cut: when the
    last step before the cut looks missed or unsettled there, the step figures (steps commanded,
    executed, missed, lost, settling) are those up to that step, and ``step_in_progress_at_cut_s``
    gives its time.

    ``unwritten_trace`` holds the rows computed after the last row of ``trace_file`` that could
    not be written to it (a full disk, a file-size limit; the run then failed there): :attr:`trace`
    and :meth:`write` give them after the file's rows, :meth:`write_rescue` saves them all.

    ``solution_plot`` is what the plots draw from every solver step (the rows around the peak
    |torque|, the per-bin envelopes; :class:`~heliostep.results.solution.SolutionPlotData`), not in
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
    trace_kept: bool = True  # False: run_scenario(..., keep_trace=False), figures only
    solution_plot: SolutionPlotData | None = field(default=None, repr=False)  # drawn from every solver step
    unwritten_trace: pd.DataFrame | None = field(default=None, repr=False)  # rows after trace_file's end
    #: the figures' light at every row of a held trace (``heliostep.results.light_rows.PLOT_COLUMNS``): what the power
    #: on the tube is drawn from; None: computed again from the trace when drawn
    light_rows: dict | None = field(default=None, repr=False)

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
                f"{self.scenario.name}: this run kept no trace (run_scenario(..., keep_trace=False)): "
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

    def to_pandas(self) -> pd.DataFrame:
        """The trace as a DataFrame (a copy)."""
        return self.trace.copy()

    def plot(self, out_dir: str | Path) -> list[Path]:
        """Write the paper's Figs. 8–14 and the power on the tube for this run into ``out_dir``
        (drawn into a staging folder, swapped in and added to the folder's manifest, the
        folder's lock held meanwhile)."""
        self._require_trace()
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        with hold_folder(out_dir):
            staging = staging_folder(out_dir)
            try:
                drawn = [path.name for path in self._draw(staging)]
                return list(swap_in(out_dir, staging, drawn, keep=manifest_files(out_dir)).values())
            finally:
                shutil.rmtree(staging, ignore_errors=True)

    def _draw(self, out_dir: Path) -> list[Path]:
        """The figures drawn into ``out_dir`` (each renamed into place there), on two cores
        (:func:`~heliostep.run.drawing.draw_figures`)."""
        return draw_figures(self._figure_job(), out_dir)

    def _figure_job(self) -> FigureJob:
        """What the figures are drawn from (a streamed trace: its file, read by column)."""
        panel_angle = self.metadata.get("roles", {}).get("panel_angle", "")
        return FigureJob(
            source=self.held_trace if self.held_trace is not None else self._streamed_file(),
            trace_metadata=self.trace_metadata(),
            solution_plot=self.solution_plot,
            light=self.trace_columns(["panel_angle_ref", panel_angle]),
            light_rows=self.light_rows,
            metadata=self.metadata,
            scenario=self.scenario,
            weather=self.weather,
            summary=self.summary,
        )

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
        drawer: Helper | None = None,
    ) -> dict[str, Path]:
        """Write trace (Parquet, and CSV unless ``csv=False``), summary.json, metadata.json and
        plots into ``out_dir`` (a run that kept no trace: summary.json and metadata.json). The
        trace's metadata, summary.json and metadata.json all say ``complete`` (and, when not,
        ``reason`` and the time reached).

        The folder's lock is held meanwhile (:func:`~heliostep.results.run_folder.hold_folder`:
        another run writing there is an InputError). Every file is written first into a staging
        folder inside ``out_dir``, then swapped in (:func:`~heliostep.results.run_folder.swap_in`):
        the earlier run's files (those its manifest lists) are removed and the new ones renamed
        into place, signals held back, so no interrupt leaves old and new files side by side; a
        file heliostep did not write is never removed or replaced. When ``should_stop()`` turns
        true the figures (drawn last) are skipped. ``before_figures()``, when given, is called once the
        trace and records are in place, before the figures are swapped in (the command line reports
        the figures there: a reader has them a second before the plots).

        A trace held in memory is drawn while the records are written, where a child can be forked
        (:func:`~heliostep.run.forked.can_fork`): the child imports the plotting modules and draws
        (on two cores, :meth:`_draw`) while this process writes; its PNGs are swapped in after the
        records, as they are when drawn after them. A streamed trace (a file this process moves
        while writing) is drawn after the records are in place. ``drawer``, when given (the command
        line's, :func:`~heliostep.run.drawing.start_drawer`: forked before the simulation, the plotting
        modules imported meanwhile), draws them instead of a child forked here (where it has ended, they are
        drawn as without it); it is not closed here.
        """
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        if drawer is not None and not drawer.alive():  # ended (killed, crashed): the figures drawn as without one
            drawer = None
        with hold_folder(out_dir):
            check_foreign(out_dir, run_file_names(plots, csv))
            drawing = plots and self.trace_kept and self.trace_rows and not (should_stop and should_stop())
            if drawing and self.held_trace is not None and (drawer is not None or can_fork()):
                return self._write_while_drawing(out_dir, csv, should_stop, before_figures, drawer)
            written = self._write_records(out_dir, csv, before_figures)
            if drawing and not (should_stop and should_stop()):
                staging = staging_folder(out_dir)  # then the figures, added to them
                try:
                    if drawer is not None and _submitted(drawer, self._figure_job(), staging):
                        drawn = drawer.result()
                    else:
                        drawn = [path.name for path in self._draw(staging)]
                    written.update(swap_in(out_dir, staging, drawn, keep=written))
                finally:
                    shutil.rmtree(staging, ignore_errors=True)
        return written

    def _write_records(self, out_dir: Path, csv: bool, before_figures: Callable[[], None] | None) -> dict[str, Path]:
        """The trace and records swapped into ``out_dir`` (the earlier run's files, figures too, out),
        then ``before_figures()``: name -> path."""
        staging, source = staging_folder(out_dir), self.trace_file
        try:
            written = swap_in(out_dir, staging, self._write_staged(staging, csv))
        finally:  # (also when a signal held back during the swap is raised as it ends)
            self._trace_file_after_swap(out_dir, staging, source)
            shutil.rmtree(staging, ignore_errors=True)
        if before_figures is not None:
            before_figures()
        return written

    def _write_while_drawing(
        self, out_dir: Path, csv: bool, should_stop: Callable[[], bool] | None, before_figures, drawer: Helper | None
    ) -> dict[str, Path]:
        """:meth:`write` with the figures drawn into a staging folder by a forked child (or by
        ``drawer``) while this process writes the records; the child (the drawer) killed, no figure,
        when the writing fails or a stop is asked for meanwhile."""
        staging = staging_folder(out_dir)

        def records() -> dict[str, Path]:
            written = self._write_records(out_dir, csv, before_figures)
            if should_stop and should_stop():
                raise _FiguresSkipped(written)
            return written

        try:
            try:
                if drawer is not None and _submitted(drawer, self._figure_job(), staging):
                    try:
                        written = records()
                    except BaseException:
                        drawer.close()
                        raise
                    drawn = drawer.result()
                else:
                    drawn, written = in_parallel(lambda: [path.name for path in self._draw(staging)], records)
            except _FiguresSkipped as skipped:  # (the child killed and reaped)
                return skipped.written
            return {**written, **swap_in(out_dir, staging, drawn, keep=written)}
        finally:
            shutil.rmtree(staging, ignore_errors=True)

    def _trace_file_after_swap(self, out_dir: Path, staging: Path, source: Path | None) -> None:
        """Where the trace file is once the swap has ended: in ``out_dir`` when the one moved
        into ``staging`` was swapped in; moved back to ``source`` (kept) when it was not."""
        if self.trace_file is None or self.trace_file.parent != staging:
            return
        if self.trace_file.exists():  # not swapped in: the stream goes back where it was
            if source is not None:
                os.replace(self.trace_file, source)
                self.trace_file = source
            return
        self.trace_file = out_dir / self.trace_file.name
        if source is not None and source.parent == out_dir and source.name.startswith(TMP_PREFIX):
            source.unlink(missing_ok=True)  # a stream cut short, now joined with its rest

    def _write_staged(self, staging: Path, csv: bool) -> list[str]:
        """The run's trace and records written into ``staging``: their names, in the order written."""
        written: dict[str, Path] = {}
        if not self.trace_kept:  # figures only: summary.json and metadata.json
            pass
        elif self.held_trace is not None:
            written.update(write_held_trace(staging, self.held_trace, self.trace_metadata(), csv))
        elif self.unwritten_trace is not None:  # streamed, cut short by storage: the file's rows and the rest
            written.update(
                write_joined_trace(staging, self._streamed_file(), self.unwritten_trace, self.trace_metadata(), csv)
            )
            self.trace_file, self.unwritten_trace = written["trace.parquet"], None
        else:  # streamed: the finished file is renamed (or copied) into place, the CSV made from it
            source, metadata = self._streamed_file(), self.trace_metadata()
            written["trace.parquet"] = place_trace_file(source, staging / "trace.parquet")
            if not source.exists():  # moved, not copied: the result's trace is the placed one
                self.trace_file = written["trace.parquet"]
            if csv:
                written.update(write_trace_csv(staging, written["trace.parquet"], metadata))
        written.update(write_records(staging, self.figures, self.status, self.metadata))
        return list(written)

    def write_rescue(self, folder: Path) -> list[Path]:
        """Every computed row and the records into ``folder`` (no figures), each file under the
        process's file-size limit (:mod:`heliostep.results.rescue`: the trace in parts if need be)."""
        written = []
        if self.trace_kept:
            blocks: Iterable[pd.DataFrame]
            if self.held_trace is not None:
                held, step = self.held_trace, 65536
                blocks = (held.iloc[i : i + step] for i in range(0, max(len(held), 1), step))
            else:
                blocks = iter_trace_blocks(self._streamed_file())
                if self.unwritten_trace is not None:
                    blocks = itertools.chain(blocks, [self.unwritten_trace])
            written += write_trace_parts(folder, blocks, self.trace_metadata())
        for name, text in record_texts(self.figures, self.status, self.metadata).items():
            written += write_text_parts(folder, name, text)
        return written


def _submitted(drawer: Helper, job: FigureJob, staging: Path) -> bool:
    """Whether ``job`` was sent to ``drawer`` (to draw into ``staging``), pickled into a file in the staging
    folder; a part of it that does not pickle (a user's object in the metadata, say) is no error: the drawer
    is closed and the figures are drawn as without one (False)."""
    spool = staging / (TMP_PREFIX + "figure-job.pickle")
    try:
        drawer.submit(draw_figure_names, (job, staging), spool)
    except (pickle.PicklingError, TypeError, AttributeError):
        drawer.close()
        spool.unlink(missing_ok=True)
        return False
    return True


class _FiguresSkipped(Exception):
    """A stop asked for while the records were written: the figures being drawn are dropped."""

    def __init__(self, written: dict[str, Path]):
        super().__init__("figures skipped")
        self.written = written


def run_file_names(plots: bool = True, csv: bool = True) -> list[str]:
    """The names a run's :meth:`RunResult.write` may give its files (a folder holding one of them
    that heliostep did not write is refused): those of the writers of traces, records and figures
    (named in :mod:`heliostep.results.run_files`: no matplotlib imported before the figures are drawn)."""
    names = [*TRACE_FILES[: 2 if csv else 1], *RECORD_FILES]
    return names + ([*FIGURE_FILES, POWER_FILE] if plots else [])


class RunFailed(RunFailure):
    """The simulation failed or was interrupted part-way; ``result`` holds the incomplete run
    (``result.reason`` says which)."""

    def __init__(self, message: str, result: RunResult):
        super().__init__(message)
        self.result = result

    @property
    def interrupted(self) -> bool:
        return self.result.reason == "interrupted"
