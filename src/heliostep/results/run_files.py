"""Writing a run's output folder: trace (Parquet, CSV), ``summary.json``, ``metadata.json``.

Every file is written under a temporary name in the folder and renamed into place
(:mod:`heliostep.results.outputs`); a streamed trace file is renamed (or copied) into place and
its CSV copy made from it in batches. The figures (plots) are drawn by the caller, last.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from heliostep.results.outputs import TMP_PREFIX, atomic_path, write_text_atomic
from heliostep.results.run_summary import RunStatus, RunSummary, status_record, summary_record
from heliostep.results.trace_io import TraceWriter, copy_trace_to_csv, iter_trace_blocks, write_trace

__all__ = [
    "FIGURE_FILES",
    "POWER_FILE",
    "RECORD_FILES",
    "TRACE_FILES",
    "place_trace_file",
    "record_texts",
    "write_held_trace",
    "write_joined_trace",
    "write_records",
    "write_trace_csv",
]

#: The trace files a run writes (Parquet always, CSV when asked), by the functions below.
TRACE_FILES = ("trace.parquet", "trace.csv")
#: The records a run writes (:func:`write_records`).
RECORD_FILES = ("metadata.json", "summary.json")
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
)
POWER_FILE = "power_on_tube.png"


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


def record_texts(summary: RunSummary | None, status: RunStatus, metadata: Mapping) -> dict[str, str]:
    """The text of ``metadata.json`` (the status, then ``metadata``) and ``summary.json`` (:func:`summary_record`)."""
    contents = ({**status_record(status), **metadata}, summary_record(summary, status, metadata.get("terminated")))
    return {name: json.dumps(content, indent=2, default=str) + "\n" for name, content in zip(RECORD_FILES, contents)}


def write_records(out_dir: Path, summary: RunSummary | None, status: RunStatus, metadata: Mapping) -> dict[str, Path]:
    """``metadata.json`` and ``summary.json`` (:func:`record_texts`), each renamed into place."""
    texts = record_texts(summary, status, metadata)
    return {name: write_text_atomic(out_dir / name, text) for name, text in texts.items()}


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
