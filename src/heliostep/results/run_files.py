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
from heliostep.results.trace_io import copy_trace_to_csv, write_trace

__all__ = ["place_trace_file", "write_held_trace", "write_records", "write_trace_csv"]


def write_held_trace(out_dir: Path, trace: pd.DataFrame, metadata: Mapping[str, str], csv: bool) -> dict[str, Path]:
    """A trace held in memory as ``trace.parquet`` (and ``trace.csv``) with its ``metadata``."""
    written = {}
    for suffix in ("parquet", "csv") if csv else ("parquet",):
        path = out_dir / f"trace.{suffix}"
        with atomic_path(path) as tmp:
            write_trace(trace, tmp, dict(metadata))
        written[path.name] = path
    return written


def place_trace_file(source: Path, target: Path) -> Path:
    """The streamed trace ``source`` as ``target``: renamed when it is a temporary file of the same
    folder, else copied (under a temporary name, then renamed)."""
    source = Path(source)
    if source == target:
        return target
    if source.parent == target.parent and source.name.startswith(TMP_PREFIX):
        os.replace(source, target)
    else:
        with atomic_path(target) as tmp:
            shutil.copyfile(source, tmp)
    return target


def write_trace_csv(out_dir: Path, trace_file: Path, metadata: Mapping[str, str]) -> dict[str, Path]:
    """``trace.csv``: the copy of a trace file (read in batches) with ``metadata``."""
    with atomic_path(out_dir / "trace.csv") as tmp:
        copy_trace_to_csv(trace_file, tmp, dict(metadata))
    return {"trace.csv": out_dir / "trace.csv"}


def write_records(out_dir: Path, summary: RunSummary | None, status: RunStatus, metadata: Mapping) -> dict[str, Path]:
    """``metadata.json`` (the status, then ``metadata``) and ``summary.json`` (:func:`summary_record`)."""
    written = {}
    for name, content in (
        ("metadata.json", {**status_record(status), **metadata}),
        ("summary.json", summary_record(summary, status)),
    ):
        written[name] = write_text_atomic(out_dir / name, json.dumps(content, indent=2, default=str) + "\n")
    return written
