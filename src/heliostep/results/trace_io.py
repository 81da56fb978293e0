"""Reading and writing simulation traces.

Trace format
============

A *trace* is a table of samples of a simulation run:

* The first column is ``time`` in seconds: float, finite and non-decreasing. A
  discontinuity at an instant is written as consecutive rows with the same time,
  the value just before the instant first, the value just after it last (event
  iterations may put further rows in between).
* Every other column is one signal, a float column named like ``motor.tau`` or
  ``panel_angle_error``. Column names are unique. Signals may hold NaN (for
  example after a solver failure); :func:`read_trace` keeps them, consumers such
  as :mod:`heliostep.results.compare` decide what to do with them.
* *Metadata* is a flat ``dict[str, str]``. Conventional keys:

  ``complete``
      ``"true"`` or ``"false"``; a run that failed mid-way writes ``"false"``.
  ``unit.<column>``
      unit of a column, e.g. ``unit.motor.tau: N.m``.

  Keys are non-empty, contain no ``:`` and no line break, and have no leading or
  trailing blanks; values contain no line break.

Two encodings, chosen by the file suffix:

``.parquet``
    An Apache Parquet file (written with pyarrow) with one float64 column per table
    column; the metadata is the key-value metadata of the Arrow schema (UTF-8).
    Keys that Arrow or pandas put there themselves (``pandas``, ``ARROW:*``) are not
    returned as metadata.
``.csv``
    UTF-8 text. The metadata comes first, one ``# key: value`` line per entry, then
    the header line (``time,motor.tau,...``) and one line per row, comma-separated,
    floats in shortest round-trip form, missing values as empty fields (:func:`read_trace`
    also accepts a UTF-8 byte order mark and, as Excel writes in many locales, ``;`` as the
    separator with ``,`` or ``.`` as the decimal mark)::

        # complete: true
        # unit.motor.tau: N.m
        time,motor.tau
        0.0,0.0
        1.0,0.5
        1.0,2.0

Both encodings round-trip values (bit for bit), column order, duplicate time stamps
and metadata.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError

TIME = "time"
SUFFIXES = (".parquet", ".csv")
_RESERVED_PARQUET_KEYS = ("pandas",)
# pandas < 3 parses floats exactly only when asked; pandas 3 always does (and warns on the option).
_EXACT_FLOATS = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
_RESERVED_PARQUET_PREFIX = "ARROW:"
#: Rows per Parquet row group (and per slice converted to Arrow at a time).
ROW_GROUP_ROWS = 262_144

__all__ = ["TIME", "SUFFIXES", "read_trace", "write_trace", "check_time", "is_complete"]


def _format(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(
            f"{path}: unknown trace format {suffix or '(no suffix)'!r}; "
            f"expected one of {', '.join(SUFFIXES)}"
        )
    return suffix[1:]


def _clean_metadata(metadata: Mapping[str, object] | None) -> dict[str, str]:
    out: dict[str, str] = {}
    for key, value in (metadata or {}).items():
        if not isinstance(key, str) or not key or key != key.strip():
            raise InputError(f"metadata key {key!r}: must be a non-empty string without surrounding blanks")
        if ":" in key or "\n" in key or "\r" in key:
            raise InputError(f"metadata key {key!r}: must not contain ':' or a line break")
        if isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, str):
            text = value
        elif isinstance(value, (int, float, np.integer, np.floating)):
            text = str(value)
        else:
            raise InputError(f"metadata {key!r}: value must be a string, not {type(value).__name__}")
        if "\n" in text or "\r" in text:
            raise InputError(f"metadata {key!r}: value must not contain a line break")
        out[key] = text
    return out


def check_time(time: np.ndarray, name: str) -> None:
    """Raise :class:`InputError` unless *time* is finite and non-decreasing.

    *name* (a file name or a label) is used in the message.
    """
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{name}: column {TIME!r} has a non-finite value ({float(time[i])}) in data row {i + 1}")
    drops = np.flatnonzero(np.diff(time) < 0)
    if drops.size:
        i = int(drops[0]) + 1
        raise InputError(
            f"{name}: column {TIME!r} decreases in data row {i + 1} "
            f"({float(time[i])!r} after {float(time[i - 1])!r}); time must be non-decreasing"
        )


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
    fmt = _format(path)
    meta = _clean_metadata(metadata)
    table = _to_float_frame(df, str(path))
    if fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        for key in meta:
            if key in _RESERVED_PARQUET_KEYS or key.startswith(_RESERVED_PARQUET_PREFIX):
                raise InputError(f"metadata key {key!r} is reserved in Parquet files")
        schema = pa.schema([pa.field(c, pa.float64()) for c in table.columns],
                           metadata={k.encode(): v.encode() for k, v in meta.items()})
        columns = [table[c].to_numpy() for c in table.columns]
        # row groups of ROW_GROUP_ROWS: Arrow holds one group at a time, not a copy of the table
        with pq.ParquetWriter(path, schema, compression="zstd") as writer:
            for start in range(0, max(len(table), 1), ROW_GROUP_ROWS):
                chunk = [pa.array(c[start:start + ROW_GROUP_ROWS], type=pa.float64()) for c in columns]
                writer.write_table(pa.Table.from_arrays(chunk, schema=schema))
    else:
        with open(path, "w", encoding="utf-8", newline="") as fh:
            for key, value in meta.items():
                fh.write(f"# {key}: {value}\n")
            table.to_csv(fh, index=False, lineterminator="\n", na_rep="")
    return path


def read_trace(path: str | Path) -> tuple[pd.DataFrame, dict[str, str]]:
    """Read a trace; returns ``(table, metadata)``.

    The table has float64 columns, ``time`` first. Raises
    :class:`~heliostep.errors.InputError` (naming the file, and the column where one
    is at fault) if the file is missing or unreadable, has no ``time`` column, a
    non-numeric column, or a time that is not finite and non-decreasing.
    """
    path = Path(path)
    fmt = _format(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if fmt == "parquet":
        import pyarrow.parquet as pq

        try:
            arrow = pq.read_table(path)
        except Exception as exc:  # pyarrow raises several types for bad files
            raise InputError(f"{path}: cannot read as Parquet: {exc}") from None
        raw = arrow.schema.metadata or {}
        meta = {}
        for key, value in raw.items():
            k = key.decode("utf-8", "replace")
            if k in _RESERVED_PARQUET_KEYS or k.startswith(_RESERVED_PARQUET_PREFIX):
                continue
            meta[k] = value.decode("utf-8", "replace")
        columns = arrow.column_names
        try:
            data = {c: arrow.column(i).to_numpy(zero_copy_only=False) for i, c in enumerate(columns)}
        except Exception as exc:
            raise InputError(f"{path}: cannot read as Parquet: {exc}") from None
        if len(set(columns)) != len(columns):
            dupes = sorted({c for c in columns if columns.count(c) > 1})
            raise InputError(f"{path}: duplicate column(s) {', '.join(map(repr, dupes))}")
        frame = pd.DataFrame(data)
        return _to_float_frame(frame, str(path)), meta
    meta, frame = _read_csv(path)
    return _to_float_frame(frame, str(path)), meta


def _read_csv(path: Path) -> tuple[dict[str, str], pd.DataFrame]:
    try:
        text = path.read_text(encoding="utf-8-sig")  # a leading byte order mark (Excel) is dropped
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read as CSV: {exc}") from None
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
    sep, decimal = _dialect(lines[start], lines[start + 1:start + 50])
    try:
        names = [n.strip() for n in next(csv.reader(io.StringIO(lines[start]), delimiter=sep))]
    except csv.Error as exc:
        raise InputError(f"{path}: line {start + 1}: bad header: {exc}") from None
    dupes = sorted({c for c in names if names.count(c) > 1})
    if dupes:
        raise InputError(f"{path}: duplicate column(s) {', '.join(map(repr, dupes))}")
    try:
        frame = pd.read_csv(io.StringIO(body), header=0, names=names, sep=sep, decimal=decimal,
                            **_EXACT_FLOATS)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        raise InputError(f"{path}: cannot read as CSV: {exc}") from None
    return meta, frame


def _dialect(header: str, rows: list[str]) -> tuple[str, str]:
    """Separator and decimal mark: ``,`` and ``.``, or (Excel in many locales) ``;`` with ``,``
    or ``.`` decimals. ``;`` is taken when the header has a ``;`` and no ``,``."""
    if ";" in header and "," not in header:
        return ";", "," if any("," in row for row in rows) else "."
    return ",", "."


def is_complete(metadata: Mapping[str, str]) -> bool:
    """False only when the metadata says ``complete: false`` (case-insensitive)."""
    value = metadata.get("complete")
    return not (isinstance(value, str) and value.strip().lower() == "false")
