"""Reading and writing simulation traces: Parquet and CSV, both round-tripping values, duplicate
time stamps and metadata; Modelica ``.mat`` files and OpenModelica's CSV read only.

Details: docs/compare.md, ``heliostep.results.trace.files``.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.input_files import MAX_ARCHIVE_BYTES, MAX_CSV_BYTES, check_input_file, read_input_text
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

# pandas < 3 parses floats exactly only when asked; pandas 3 always does (and warns on the option).
_EXACT_FLOATS = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}

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
    become ``"true"``/``"false"``, numbers their ``str``. Returns the path.
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
        with open(path, "wb") as fh:
            _write_csv_head(fh, meta, list(table.columns))
            _write_csv_rows(fh, [table[c].to_numpy() for c in table.columns])
    return path


def _write_csv_head(fh: BinaryIO, meta: Mapping[str, object], names: list[str]) -> None:
    """The metadata lines and the header line of a CSV trace (names quoted only where they must be)."""
    header = io.StringIO()
    csv.writer(header, lineterminator="\n").writerow(names)
    lines = "".join(f"# {key}: {value}\n" for key, value in meta.items()) + header.getvalue()
    fh.write(lines.encode("utf-8"))


def _write_csv_rows(fh: BinaryIO, columns: list[np.ndarray]) -> None:
    """Rows of float64 columns as CSV lines, by Arrow's CSV writer: each value in the shortest form that
    reads back to the same double (``0.1``, ``0``, ``-0``, ``1e-100``, ``inf``), NaN as an empty field
    (pandas' ``to_csv`` writes the same values, ``0.0`` for ``0``, many times slower)."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    arrays = [pa.array(values, type=pa.float64(), from_pandas=True) for values in columns]  # NaN: null, empty
    table = pa.Table.from_arrays(arrays, names=[f"c{i}" for i in range(len(columns))])  # (names: in the head)
    pa_csv.write_csv(table, fh, pa_csv.WriteOptions(include_header=False, quoting_style="none"))


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
    table in memory); the metadata is the Parquet file's unless ``metadata`` is given."""
    import pyarrow.parquet as pq

    parquet, csv_path = Path(parquet), Path(csv_path)
    meta = clean_metadata(read_trace_metadata(parquet) if metadata is None else metadata)
    source = pq.ParquetFile(parquet)
    names = list(source.schema_arrow.names)
    with open(csv_path, "wb") as fh:
        _write_csv_head(fh, meta, names)
        for batch in source.iter_batches(batch_size=batch_rows):
            _write_csv_rows(fh, [batch.column(i).to_numpy(zero_copy_only=False) for i in range(len(names))])
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
    meta, frame = _read_csv(path)
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


def _read_csv(path: Path) -> tuple[dict[str, str], pd.DataFrame]:
    text = read_input_text(path, "trace", MAX_CSV_BYTES, "utf-8-sig")  # a byte order mark (Excel) is dropped
    text = text.replace("\r\n", "\n").replace("\r", "\n")  # the universal newlines read_text gave
    meta: dict[str, str] = {}
    lines = text.splitlines(keepends=True)
    start = len(lines)
    for number, line in enumerate(lines):
        stripped = line.rstrip("\r\n")
        if not stripped.strip():
            continue
        if not stripped.startswith("#"):
            start = number
            break
        key, sep, rest = stripped[1:].partition(":")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"{path}: line {number + 1}: expected '# key: value', got {stripped!r}")
        if key in meta:
            raise InputError(f"{path}: line {number + 1}: metadata key {key!r} given twice")
        meta[key] = rest[1:] if rest.startswith(" ") else rest
    body = "".join(lines[start:])
    if not body.strip():
        raise InputError(f"{path}: no header line (expected a {TIME!r} column)")
    sep, decimal = _dialect(lines[start], lines[start + 1 : start + 50])
    try:
        names = [n.strip() for n in next(csv.reader(io.StringIO(lines[start]), delimiter=sep))]
    except csv.Error as exc:
        raise InputError(f"{path}: line {start + 1}: bad header: {exc}") from None
    trailing = len(names) > 1 and names[-1] == ""  # OpenModelica ends every line with the separator
    if trailing:
        names[-1] = "\x00trailing"
    dupes = sorted({c for c in names if names.count(c) > 1})
    if dupes:
        raise InputError(f"{path}: duplicate column(s) {', '.join(map(repr, dupes))}")
    try:
        frame = pd.read_csv(io.StringIO(body), header=0, names=names, sep=sep, decimal=decimal, **_EXACT_FLOATS)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        raise InputError(f"{path}: cannot read as CSV: {exc}") from None
    if trailing:
        if frame[names[-1]].notna().any():
            raise InputError(f"{path}: the header ends with an empty column name but its rows have values there")
        frame = frame.drop(columns=[names[-1]])
    return meta, frame


def _dialect(header: str, rows: list[str]) -> tuple[str, str]:
    """Separator and decimal mark: ``,`` and ``.``, or (Excel in many locales) ``;`` with ``,``
    or ``.`` decimals. ``;`` is taken when the header has a ``;`` and no ``,``."""
    if ";" in header and "," not in header:
        return ";", "," if any("," in row for row in rows) else "."
    return ",", "."
