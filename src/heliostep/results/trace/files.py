"""Reading and writing simulation traces: Parquet, round-tripping values, duplicate time stamps and
metadata, and CSV, the same readable by anyone (:mod:`heliostep.results.trace.csv_text`: units in the
column names, angles in degrees, the local time; its other metadata in a run's ``metadata.json``);
Modelica ``.mat`` files and OpenModelica's CSV read only.

Details: docs/compare.md, ``heliostep.results.trace.files``.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.input_files import MAX_ARCHIVE_BYTES, MAX_CSV_BYTES, check_input_file
from heliostep.results.trace.csv_text import CsvLayout, read_csv_trace, write_csv_head, write_csv_rows
from heliostep.results.trace.format import (
    ROW_GROUP_ROWS,
    SUFFIXES,
    TIME,
    check_time,
    clean_metadata,
    is_complete,
    is_reserved_parquet_key,
    trace_format,
)
from heliostep.results.trace.modelica import MAT_SUFFIX, read_modelica_mat
from heliostep.results.trace.writer import TRACE_ENCODING, TraceWriteError, TraceWriter

__all__ = [
    "TIME",
    "SUFFIXES",
    "ROW_GROUP_ROWS",
    "TRACE_ENCODING",
    "TraceWriteError",
    "TraceWriter",
    "copy_trace_to_csv",
    "iter_trace_blocks",
    "read_trace",
    "read_trace_metadata",
    "write_trace",
    "check_time",
    "is_complete",
]


def _to_float_frame(df: pd.DataFrame, name: str) -> pd.DataFrame:
    """The table with float64 columns and ``time`` first; validates the time column."""
    columns = [str(c) for c in df.columns]
    if len(set(columns)) != len(columns):
        dupes = sorted({c for c in columns if columns.count(c) > 1})
        raise InputError(f"{name}: duplicate column(s) {', '.join(map(repr, dupes))}")
    if TIME not in columns:
        raise InputError(f"{name}: no {TIME!r} column (columns: {', '.join(map(repr, columns)) or 'none'})")
    data: dict[str, np.ndarray] = {}
    for label, column in zip(columns, df.columns):
        series = df[column]
        if len(series) == 0:
            values = np.empty(0, dtype=np.float64)
        elif pd.api.types.is_bool_dtype(series) or pd.api.types.is_numeric_dtype(series):
            try:
                values = series.to_numpy(dtype=np.float64, na_value=np.nan)
            except (TypeError, ValueError) as exc:
                raise InputError(f"{name}: column {label!r} is not numeric: {exc}") from None
        else:
            raise InputError(f"{name}: column {label!r} is not numeric (dtype {series.dtype})")
        data[label] = values
    check_time(data[TIME], name)
    order = [TIME] + [c for c in columns if c != TIME]
    return pd.DataFrame({c: data[c] for c in order})


def write_trace(df: pd.DataFrame, path: str | Path, metadata: Mapping[str, object] | None = None) -> Path:
    """Write *df* (a ``time`` column and signal columns) as a trace to *path*.

    The format follows the suffix (``.parquet`` or ``.csv``); ``time`` is written as
    the first column, every column as float64. *metadata* values that are ``bool``
    become ``"true"``/``"false"``, numbers their ``str``; a CSV keeps of them only the
    units (``unit.<column>``, in the header) and the window (``window_start`` and
    ``timezone``, its local time column). Returns the path.
    """
    path = Path(path)
    fmt = trace_format(path)
    meta = clean_metadata(metadata)
    table = _to_float_frame(df, str(path))
    if fmt == "parquet":
        writer = TraceWriter(path, list(table.columns), keep_on_failure=False)  # a failure aborts it
        try:
            data = {c: table[c].to_numpy() for c in table.columns}
            # row groups of ROW_GROUP_ROWS: Arrow holds one group at a time, not a copy of the table
            for start in range(0, len(table), ROW_GROUP_ROWS):
                writer.write({c: v[start : start + ROW_GROUP_ROWS] for c, v in data.items()})
        except BaseException:
            writer.abort()
            raise
        writer.close(meta)
    else:
        layout = CsvLayout.of(list(table.columns), meta)
        with open(path, "wb") as fh:
            write_csv_head(fh, layout)
            write_csv_rows(fh, layout, [table[c].to_numpy() for c in table.columns])
    return path


def read_trace_metadata(path: str | Path) -> dict[str, str]:
    """The metadata of a Parquet trace (from its footer), without reading its rows."""
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        raw = pq.ParquetFile(path).metadata.metadata or {}
    except Exception as exc:  # pyarrow raises several types for bad files
        raise InputError(f"{path}: cannot read as Parquet: {exc}") from None
    meta = {}
    for key, value in raw.items():
        k = key.decode("utf-8", "replace")
        if is_reserved_parquet_key(k):
            continue
        meta[k] = value.decode("utf-8", "replace")
    return meta


def copy_trace_to_csv(
    parquet: str | Path,
    csv_path: str | Path,
    metadata: Mapping[str, object] | None = None,
    batch_rows: int = ROW_GROUP_ROWS,
) -> Path:
    """Write the CSV form of a Parquet trace, ``batch_rows`` rows at a time (never the whole
    table in memory); its units and window are the Parquet file's metadata's unless ``metadata`` is given."""
    import pyarrow.parquet as pq

    parquet, csv_path = Path(parquet), Path(csv_path)
    meta = clean_metadata(read_trace_metadata(parquet) if metadata is None else metadata)
    source = pq.ParquetFile(parquet)
    layout = CsvLayout.of(list(source.schema_arrow.names), meta)
    with open(csv_path, "wb") as fh:
        write_csv_head(fh, layout)
        for batch in source.iter_batches(batch_size=batch_rows):
            write_csv_rows(
                fh, layout, [batch.column(i).to_numpy(zero_copy_only=False) for i in range(len(layout.names))]
            )
    return csv_path


def read_trace(path: str | Path, columns: list[str] | None = None) -> tuple[pd.DataFrame, dict[str, str]]:
    """Read a trace; returns ``(table, metadata)``. ``columns`` (Parquet only) reads just those
    (``time`` is always read), so a long trace need not be loaded whole.

    The table has float64 columns, ``time`` first. Raises
    :class:`~heliostep.errors.InputError` (naming the file, and the column where one
    is at fault) if the file is missing or unreadable, has no ``time`` column, a
    non-numeric column, or a time that is not finite and non-decreasing.
    """
    path = Path(path)
    if path.suffix.lower() == MAT_SUFFIX and columns is None:  # a Modelica tool's result file (read only)
        table, meta = read_modelica_mat(path)
        return _to_float_frame(table, str(path)), meta
    fmt = trace_format(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    check_input_file(path, "trace", MAX_ARCHIVE_BYTES if fmt == "parquet" else MAX_CSV_BYTES)
    if columns is not None:
        if fmt != "parquet":
            raise InputError(f"{path}: reading selected columns needs a Parquet trace")
        columns = [TIME] + [c for c in dict.fromkeys(columns) if c != TIME]
    if fmt == "parquet":
        return _read_parquet(path, columns), read_trace_metadata(path)
    frame, meta = read_csv_trace(path)
    return _to_float_frame(frame, str(path)), meta


def _open_parquet(path: Path, columns: list[str] | None):
    """The ParquetFile of a trace and the columns to read (``time`` first), checked: unique
    names, a ``time`` column, the wanted columns present and numeric."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        source = pq.ParquetFile(path)
        names = [str(n) for n in source.schema_arrow.names]
    except Exception as exc:  # pyarrow raises several types for bad files
        raise InputError(f"{path}: cannot read as Parquet: {exc}") from None
    if len(set(names)) != len(names):
        dupes = sorted({c for c in names if names.count(c) > 1})
        raise InputError(f"{path}: duplicate column(s) {', '.join(map(repr, dupes))}")
    if TIME not in names:
        raise InputError(f"{path}: no {TIME!r} column (columns: {', '.join(map(repr, names)) or 'none'})")
    wanted = names if columns is None else columns
    missing = [c for c in wanted if c not in names]
    if missing:
        raise InputError(f"{path}: no column(s) {', '.join(map(repr, missing))}")
    order = [TIME] + [c for c in wanted if c != TIME]
    for name in order:
        kind = source.schema_arrow.field(name).type
        if not (pa.types.is_floating(kind) or pa.types.is_integer(kind) or pa.types.is_boolean(kind)):
            raise InputError(f"{path}: column {name!r} is not numeric (type {kind})")
    return source, order


def _row_group(source, path: Path, group: int, order: list[str]):
    """One row group's columns as float64 arrays (nulls: NaN)."""
    import pyarrow as pa

    try:  # ParquetFile takes the names as they are (read_table would split "motor.tau" at the dot)
        table = source.read_row_group(group, columns=order, use_threads=False)
    except Exception as exc:
        raise InputError(f"{path}: cannot read row group {group}: {exc}") from None
    return [table.column(j).cast(pa.float64()).to_numpy(zero_copy_only=False) for j in range(len(order))]


def _read_parquet(path: Path, columns: list[str] | None) -> pd.DataFrame:
    """The float64 table of a Parquet trace, ``time`` first, read one row group at a time into
    one array (the table in memory once, plus one row group in Arrow form)."""
    import pyarrow as pa

    source, order = _open_parquet(path, columns)
    data = np.empty((source.metadata.num_rows, len(order)), dtype=np.float64, order="F")
    start = 0
    for group in range(source.num_row_groups):  # one row group at a time: Arrow holds no more
        arrays = _row_group(source, path, group, order)
        stop = start + len(arrays[0])
        for j, values in enumerate(arrays):
            data[start:stop, j] = values
        start = stop
        del arrays
    pa.default_memory_pool().release_unused()  # Arrow's pool would keep the decoded groups' memory
    check_time(data[:, 0], str(path))
    return pd.DataFrame(data, columns=order, copy=False)


def iter_trace_blocks(path: str | Path, columns: list[str] | None = None) -> Iterator[pd.DataFrame]:
    """A Parquet trace one row group at a time, as float64 frames (``time`` first, then
    ``columns`` or every column): the rows :func:`read_trace` gives, in order, never more than
    one row group in memory. The time is checked across the groups as a whole."""
    path = Path(path)
    if trace_format(path) != "parquet":
        raise InputError(f"{path}: reading a trace by row groups needs a Parquet trace")
    if not path.exists():
        raise InputError(f"{path}: no such file")
    check_input_file(path, "trace", MAX_ARCHIVE_BYTES)
    if columns is not None:
        columns = [TIME] + [c for c in dict.fromkeys(columns) if c != TIME]
    source, order = _open_parquet(path, columns)
    previous = None
    for group in range(source.num_row_groups):
        arrays = _row_group(source, path, group, order)
        time = arrays[0]
        if not len(time):
            continue
        check_time(time if previous is None else np.concatenate([[previous], time]), str(path))
        previous = float(time[-1])
        yield pd.DataFrame(dict(zip(order, arrays)), columns=order, copy=False)
