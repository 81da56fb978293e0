"""A run's results saved where they still fit, after its output folder could not take them (a full
disk, a file-size limit).

Details: docs/running.md, ``heliostep.results.output.rescue``.
"""

from __future__ import annotations

import itertools
import os
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

import pandas as pd

from heliostep.results.output.files import write_text_atomic
from heliostep.results.output.run_files import RunRecords, record_texts, trace_record
from heliostep.results.trace.files import iter_trace_blocks, write_trace

__all__ = ["file_size_limit", "rescue_folder", "write_rescue", "write_text_parts", "write_trace_parts"]

#: Room kept in each part for the Parquet footer and metadata besides the rows [bytes].
_FOOTER_ROOM = 64 * 1024


def file_size_limit() -> int | None:
    """The largest file this process may write [bytes] (``RLIMIT_FSIZE``'s soft limit; None: none)."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def rescue_folder(name: str) -> Path | None:
    """A new folder ``heliostep-NAME-rescue-*`` where a probe file can be written (None: nowhere)."""
    places = [tempfile.gettempdir(), "/dev/shm"]
    for place in dict.fromkeys(places):
        if not os.path.isdir(place):
            continue
        try:
            folder = Path(tempfile.mkdtemp(prefix=f"heliostep-{name}-rescue-", dir=place))
        except OSError:
            continue
        try:
            (folder / "probe").write_bytes(b"x" * 4096)
            (folder / "probe").unlink()
            return folder
        except OSError:
            for entry in folder.iterdir():
                entry.unlink(missing_ok=True)
            folder.rmdir()
    return None


def _rows_per_part(columns: int, limit: int | None) -> int | None:
    """Rows of ``columns`` float64 columns that fit in one file under ``limit`` (uncompressed, so
    with room to spare; None: no limit)."""
    if limit is None:
        return None
    return max(1, (limit // 2 - _FOOTER_ROOM) // (8 * columns + 16))


def write_trace_parts(
    folder: Path, blocks: Iterable[pd.DataFrame], metadata: Mapping[str, str], limit: int | None = None
) -> list[Path]:
    """Every row of ``blocks`` (a trace in time order) as Parquet trace files in ``folder``, each
    with ``metadata`` and at most ``limit`` bytes (default: :func:`file_size_limit`)."""
    limit = file_size_limit() if limit is None else limit
    parts: list[pd.DataFrame] = []
    written: list[Path] = []
    held, per_part = 0, None
    for block in blocks:
        if per_part is None:
            per_part = _rows_per_part(len(block.columns), limit)
        start = 0
        while start < len(block):
            take = len(block) - start if per_part is None else min(len(block) - start, per_part - held)
            parts.append(block.iloc[start : start + take])
            held, start = held + take, start + take
            if per_part is not None and held >= per_part:
                written.append(_write_part(folder, len(written), parts, metadata))
                parts, held = [], 0
    if parts or not written:
        written.append(_write_part(folder, len(written), parts, metadata))
    if len(written) == 1:
        written[0] = written[0].rename(folder / "trace.parquet")
    return written


def _write_part(folder: Path, index: int, frames: list[pd.DataFrame], metadata: Mapping[str, str]) -> Path:
    frame = pd.concat(frames, ignore_index=True) if len(frames) != 1 else frames[0].reset_index(drop=True)
    return write_trace(frame, folder / f"trace-part-{index:03d}.parquet", dict(metadata))


def write_text_parts(folder: Path, name: str, text: str, limit: int | None = None) -> list[Path]:
    """``text`` as ``folder/name``, or in pieces ``name.part-000``, ... of at most ``limit`` bytes."""
    limit = file_size_limit() if limit is None else limit
    data = text.encode("utf-8")
    if limit is None or len(data) < limit // 2:
        return [write_text_atomic(folder / name, text)]
    size, paths = max(1, limit // 2), []
    for index, start in enumerate(range(0, len(data), size)):
        path = folder / f"{name}.part-{index:03d}"
        path.write_bytes(data[start : start + size])
        paths.append(path)
    return paths


def write_rescue(folder: Path, run: RunRecords) -> list[Path]:
    """Every computed row of ``run`` and its records into ``folder`` (no figures), each file under the
    process's file-size limit (the trace in parts if need be)."""
    written = []
    if run.trace_kept:
        blocks: Iterable[pd.DataFrame]
        if run.held_trace is not None:
            held, step = run.held_trace, 65536
            blocks = (held.iloc[i : i + step] for i in range(0, max(len(held), 1), step))
        elif run.trace_file is not None:
            blocks = iter_trace_blocks(run.trace_file)
            if run.unwritten_trace is not None:
                blocks = itertools.chain(blocks, [run.unwritten_trace])
        else:
            raise RuntimeError("a run that holds no trace in memory has a trace file")
        written += write_trace_parts(folder, blocks, run.trace_metadata())
    for name, text in record_texts(run.figures, run.status, run.metadata, trace_record(run)).items():
        written += write_text_parts(folder, name, text)
    return written
