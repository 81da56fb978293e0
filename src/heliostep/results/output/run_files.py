"""Writing a run's output folder: trace (Parquet, CSV), ``summary.json``, ``metadata.json``.

:func:`write_run_records` writes a run's trace and records into a staging folder and swaps them into
the output folder (:mod:`heliostep.results.output.folder`); each file is written under a temporary name
and renamed into place (:mod:`heliostep.results.output.files`), a streamed trace file is renamed (or
copied) into place and its CSV copy made from it in batches. The figures are drawn by the caller, last.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Protocol

import pandas as pd

from heliostep.results.figures.run_summary import RunMetadata, RunStatus, RunSummary, status_record, summary_record
from heliostep.results.output.files import TMP_PREFIX, atomic_path, write_text_atomic
from heliostep.results.output.folder import staging_folder, swap_in, write_swapped
from heliostep.results.trace.files import TraceWriter, copy_trace_to_csv, iter_trace_blocks, write_trace
from heliostep.results.trace.format import RUN_METADATA_FILE, TRACE_METADATA_KEY

__all__ = [
    "FIGURE_FILES",
    "POWER_FILE",
    "RECORD_FILES",
    "TRACE_FILES",
    "RunRecords",
    "place_trace_file",
    "record_texts",
    "run_file_names",
    "trace_record",
    "write_held_trace",
    "write_joined_trace",
    "write_records",
    "write_run_records",
    "write_stopped_records",
    "write_trace_csv",
]

#: The trace files a run writes (Parquet always, CSV when asked), by the functions below.
TRACE_FILES = ("trace.parquet", "trace.csv")
#: The records a run writes (:func:`write_records`).
RECORD_FILES = (RUN_METADATA_FILE, "summary.json")
#: The figures a run draws, in the order drawn: the paper's Figs. 8-14 (:mod:`heliostep.plots.run`), then the
#: power on the tube (:mod:`heliostep.plots.light`). Named here, so that a run knows its files (and a
#: ``--no-plots`` run checks its folder) without importing matplotlib.
FIGURE_FILES = (
    "fig08_panel_angle_ref.png",
    "fig09_rotor_angle_ref.png",
    "fig10_phase_currents.png",
    "fig11_torque.png",
    "fig12_rotor_angle.png",
    "fig13_panel_tracking.png",
    "fig14_torque_zoom.png",
    "tracking_loop.png",  # a closed or hybrid loop's
)
POWER_FILE = "power_on_tube.png"


class RunRecords(Protocol):
    """What a run's output files are written from (:class:`heliostep.run.RunResult`): its trace, held in memory
    or in a Parquet file (with the rows that could not be written to it), its figures, status and metadata."""

    held_trace: pd.DataFrame | None
    trace_file: Path | None
    unwritten_trace: pd.DataFrame | None
    trace_kept: bool
    figures: RunSummary | None
    metadata: RunMetadata

    @property
    def status(self) -> RunStatus: ...

    def trace_metadata(self) -> dict[str, str]: ...


def run_file_names(plots: bool = True, csv: bool = True) -> list[str]:
    """The names a run may give its files (a folder holding one of them that heliostep did not write is
    refused): its traces, records and, with ``plots``, figures."""
    names = [*TRACE_FILES[: 2 if csv else 1], *RECORD_FILES]
    return names + ([*FIGURE_FILES, POWER_FILE] if plots else [])


def write_run_records(out_dir: Path, run: RunRecords, csv: bool) -> dict[str, Path]:
    """The run's trace (Parquet, and CSV with ``csv``) and records swapped into ``out_dir``
    (:func:`~heliostep.results.output.folder.swap_in`: the earlier run's files, figures too, out): name -> path.

    A streamed trace file is moved into the folder rather than copied where it can be: ``run.trace_file`` is
    then the placed file (joined with ``run.unwritten_trace``, which is then None); when the swap does
    not happen, the file goes back where it was."""
    staging, source = staging_folder(out_dir), run.trace_file
    try:
        return swap_in(out_dir, staging, _write_staged(staging, run, csv))
    finally:  # (also when a signal held back during the swap is raised as it ends)
        _trace_file_after_swap(run, out_dir, staging, source)
        shutil.rmtree(staging, ignore_errors=True)


def _write_staged(staging: Path, run: RunRecords, csv: bool) -> list[str]:
    """The run's trace and records written into ``staging``: their names, in the order written."""
    written: dict[str, Path] = {}
    if not run.trace_kept:  # figures only: summary.json and metadata.json
        pass
    elif run.held_trace is not None:
        written.update(write_held_trace(staging, run.held_trace, run.trace_metadata(), csv))
    elif run.trace_file is None:
        raise RuntimeError("a run that holds no trace in memory has a trace file")
    elif run.unwritten_trace is not None:  # streamed, cut short by storage: the file's rows and the rest
        written.update(write_joined_trace(staging, run.trace_file, run.unwritten_trace, run.trace_metadata(), csv))
        run.trace_file, run.unwritten_trace = written["trace.parquet"], None
    else:  # streamed: the finished file is renamed (or copied) into place, the CSV made from it
        source, metadata = run.trace_file, run.trace_metadata()
        written["trace.parquet"] = place_trace_file(source, staging / "trace.parquet")
        if not source.exists():  # moved, not copied: the run's trace is the placed one
            run.trace_file = written["trace.parquet"]
        if csv:
            written.update(write_trace_csv(staging, written["trace.parquet"], metadata))
    written.update(write_records(staging, run.figures, run.status, run.metadata, trace_record(run)))
    return list(written)


def trace_record(run: RunRecords) -> dict[str, str] | None:
    """The trace's metadata as ``metadata.json`` holds it (what a Parquet trace's footer holds and a
    CSV trace cannot: :mod:`heliostep.results.trace.csv_text`); None for a run that kept no trace."""
    return run.trace_metadata() if run.trace_kept else None


def _trace_file_after_swap(run: RunRecords, out_dir: Path, staging: Path, source: Path | None) -> None:
    """Where the trace file is once the swap has ended: in ``out_dir`` when the one moved into ``staging``
    was swapped in; moved back to ``source`` (kept) when it was not."""
    if run.trace_file is None or run.trace_file.parent != staging:
        return
    if run.trace_file.exists():  # not swapped in: the stream goes back where it was
        if source is not None:
            os.replace(run.trace_file, source)
            run.trace_file = source
        return
    run.trace_file = out_dir / run.trace_file.name
    if source is not None and source.parent == out_dir and source.name.startswith(TMP_PREFIX):
        source.unlink(missing_ok=True)  # a stream cut short, now joined with its rest


def write_held_trace(out_dir: Path, trace: pd.DataFrame, metadata: Mapping[str, str], csv: bool) -> dict[str, Path]:
    """A trace held in memory as ``trace.parquet`` (and ``trace.csv``) with its ``metadata``."""
    written = {}
    for name in TRACE_FILES if csv else TRACE_FILES[:1]:
        path = out_dir / name
        with atomic_path(path) as tmp:
            write_trace(trace, tmp, dict(metadata))
        written[path.name] = path
    return written


def place_trace_file(source: Path, target: Path) -> Path:
    """The streamed trace ``source`` as ``target``: renamed when it is a temporary file of the same
    folder or of the folder holding ``target``'s (a staging folder), else copied (under a
    temporary name, then renamed)."""
    source = Path(source)
    if source == target:
        return target
    if source.parent in (target.parent, target.parent.parent) and source.name.startswith(TMP_PREFIX):
        os.replace(source, target)
    else:
        with atomic_path(target) as tmp:
            shutil.copyfile(source, tmp)
    return target


def write_trace_csv(out_dir: Path, trace_file: Path, metadata: Mapping[str, str]) -> dict[str, Path]:
    """``trace.csv``: the copy of a trace file (read in batches) with ``metadata``."""
    path = out_dir / TRACE_FILES[1]
    with atomic_path(path) as tmp:
        copy_trace_to_csv(trace_file, tmp, dict(metadata))
    return {path.name: path}


def record_texts(
    summary: RunSummary | None, status: RunStatus, metadata: Mapping, trace: Mapping[str, str] | None = None
) -> dict[str, str]:
    """The text of ``metadata.json`` (the status, then ``metadata``, then the ``trace``'s metadata under
    :data:`~heliostep.results.trace.format.TRACE_METADATA_KEY`) and ``summary.json`` (:func:`summary_record`;
    an incomplete run's also says the stage it reached, ``metadata``'s ``stage``, else ``simulating``)."""
    summary_content = summary_record(summary, status, metadata.get("terminated"))
    if not status.complete:
        summary_content = {**summary_content, "stage": metadata.get("stage", "simulating")}
    traced = {TRACE_METADATA_KEY: dict(trace)} if trace is not None else {}
    contents = ({**status_record(status), **metadata, **traced}, summary_content)
    return {name: json.dumps(content, indent=2, default=str) + "\n" for name, content in zip(RECORD_FILES, contents)}


def write_records(
    out_dir: Path,
    summary: RunSummary | None,
    status: RunStatus,
    metadata: Mapping,
    trace: Mapping[str, str] | None = None,
) -> dict[str, Path]:
    """``metadata.json`` and ``summary.json`` (:func:`record_texts`), each renamed into place."""
    texts = record_texts(summary, status, metadata, trace)
    return {name: write_text_atomic(out_dir / name, text) for name, text in texts.items()}


def write_stopped_records(out_dir: Path, error: str, stage: str) -> dict[str, Path]:
    """``summary.json`` and ``metadata.json`` of a run stopped before it computed anything (``complete: false``,
    reason interrupted, ``stage`` the one it reached), swapped into ``out_dir`` (the earlier run's files out): a
    script finds a summary after any stop."""

    def write(staging: Path) -> list[Path]:
        status = RunStatus(False, error, "interrupted", None)
        return list(write_records(staging, None, status, {"stage": stage}).values())

    return write_swapped(out_dir, write)


def write_joined_trace(
    out_dir: Path, trace_file: Path, rest: pd.DataFrame, metadata: Mapping[str, str], csv: bool
) -> dict[str, Path]:
    """``trace.parquet`` (and ``trace.csv``): the rows of ``trace_file`` (read a row group at a
    time), then ``rest`` (rows that could not be written to it), with ``metadata``."""
    path = out_dir / TRACE_FILES[0]
    columns = list(rest.columns)
    with atomic_path(path) as tmp:
        writer = TraceWriter(tmp, columns, keep_on_failure=False)
        try:
            for block in (*iter_trace_blocks(trace_file, columns), rest):
                writer.write({c: block[c].to_numpy() for c in columns})
        except BaseException:
            writer.abort()
            raise
        writer.close(dict(metadata))
    written = {path.name: path}
    if csv:
        written.update(write_trace_csv(out_dir, path, metadata))
    return written
