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
    column, in row groups; the metadata is the file's key-value metadata (UTF-8), which
    Parquet keeps in the footer, written last: a file cut short while being written has no
    footer and cannot be read, so it never claims to be complete. Keys that Arrow or pandas
    put there themselves (``pandas``, ``ARROW:*``) are not returned as metadata.
    :class:`TraceWriter` writes one row group at a time and its status keys (``complete``
    and so on) only when closing. When a row group cannot be written (disk full, a file-size
    limit) the file is closed at the last row group written: those rows stay readable, and
    the metadata given at closing says how the run ended.
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
import os
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import HeliostepError, InputError

TIME = "time"
SUFFIXES = (".parquet", ".csv")
_RESERVED_PARQUET_KEYS = ("pandas",)
# pandas < 3 parses floats exactly only when asked; pandas 3 always does (and warns on the option).
_EXACT_FLOATS = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
_RESERVED_PARQUET_PREFIX = "ARROW:"
#: Rows per Parquet row group (and per slice converted to Arrow at a time): with the 20 float64
#: columns of a run's trace 2.6 MB, the most of a streamed trace held at once.
ROW_GROUP_ROWS = 16_384

__all__ = ["TIME", "SUFFIXES", "TraceWriteError", "TraceWriter", "copy_trace_to_csv", "iter_trace_blocks", "read_trace", "read_trace_metadata",
           "write_trace", "check_time", "is_complete"]


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
        writer = TraceWriter(path, list(table.columns), keep_on_failure=False)  # a failure aborts it
        try:
            data = {c: table[c].to_numpy() for c in table.columns}
            # row groups of ROW_GROUP_ROWS: Arrow holds one group at a time, not a copy of the table
            for start in range(0, len(table), ROW_GROUP_ROWS):
                writer.write({c: v[start:start + ROW_GROUP_ROWS] for c, v in data.items()})
        except BaseException:
            writer.abort()
            raise
        writer.close(meta)
    else:
        with open(path, "w", encoding="utf-8", newline="") as fh:
            for key, value in meta.items():
                fh.write(f"# {key}: {value}\n")
            table.to_csv(fh, index=False, lineterminator="\n", na_rep="")
    return path


def _check_parquet_keys(meta: Mapping[str, str]) -> None:
    for key in meta:
        if key in _RESERVED_PARQUET_KEYS or key.startswith(_RESERVED_PARQUET_PREFIX):
            raise InputError(f"metadata key {key!r} is reserved in Parquet files")


class TraceWriteError(HeliostepError):
    """A row group of a trace could not be written (disk full, a file-size limit, an I/O error);
    the rows written before it can still be kept (:meth:`TraceWriter.close`)."""


class _ByteCounter(io.RawIOBase):
    """A write-only sink that counts the bytes written to it and, once :meth:`keep` is called,
    keeps those that follow."""

    def __init__(self):
        super().__init__()
        self.position = 0
        self.kept: bytearray | None = None

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        if self.kept is not None:
            self.kept += view
        self.position += len(view)
        return len(view)

    def tell(self) -> int:
        return self.position

    def keep(self) -> None:
        self.kept = bytearray()


#: How a trace's float64 columns are encoded in Parquet (pyarrow.parquet.ParquetWriter options).
TRACE_ENCODING = {"use_dictionary": False, "column_encoding": "BYTE_STREAM_SPLIT"}


class TraceWriter:
    """A Parquet trace written as it is produced: :meth:`write` appends one row group of float64
    columns, :meth:`close` writes the metadata (all of it, ``complete`` included) and the footer.

    Until :meth:`close` the file has no footer: a reader sees no table and no metadata, so a file
    cut short (killed process, full disk) never claims to be complete. Write to a temporary name
    and rename into place afterwards (:func:`heliostep.results.outputs.atomic_path`).

    A row group that cannot be written raises :class:`TraceWriteError` (``failed`` then holds
    the cause) and writes nothing more; :meth:`close` then keeps the row groups written before
    it: the file is cut back to their end and given the footer a second writer produced from the
    same row groups (Parquet bytes are a function of the rows and the settings; the two files'
    sizes are compared after every row group, ``recoverable`` says they agree). With
    ``keep_on_failure=False`` there is no second writer (half the encoding work) and a failed
    file cannot be closed, only aborted. ``rows`` counts the rows written, ``last_time`` the
    time of the last one.
    """

    def __init__(self, path: str | Path, columns: list[str], keep_on_failure: bool = True):
        import pyarrow as pa
        import pyarrow.parquet as pq

        self.path = Path(path)
        if _format(self.path) != "parquet":
            raise InputError(f"{self.path}: TraceWriter writes Parquet (.parquet) files")
        if not columns or columns[0] != TIME or len(set(columns)) != len(columns):
            raise InputError(f"{self.path}: trace columns must be unique and start with {TIME!r}: {columns}")
        self.columns = list(columns)
        self.rows = 0
        self.failed: OSError | None = None
        self._last_time = -np.inf
        self._schema = pa.schema([pa.field(c, pa.float64()) for c in self.columns])
        # no serialized Arrow schema (all columns are float64): readers then take the schema's
        # metadata from the footer's key-value metadata, which close() writes. Encoding: each
        # float64 split into its 8 byte planes (BYTE_STREAM_SPLIT), then zstd; against Parquet's
        # default dictionary encoding, which the continuous columns overflow, the row groups are
        # written 3-4x faster and take 40 % less space (benchmarks/bench_trace_io.py)
        options = {"compression": "zstd", "store_schema": False, **TRACE_ENCODING}
        self._writer = pq.ParquetWriter(self.path, self._schema, **options)
        # the same row groups written nowhere: its footer is the one for the groups written so far
        self._shadow_sink = _ByteCounter()
        self._shadow = pq.ParquetWriter(self._shadow_sink, self._schema, **options) if keep_on_failure else None
        self._pa = pa

    @property
    def last_time(self) -> float | None:
        return float(self._last_time) if self.rows else None

    @property
    def recoverable(self) -> bool:
        """The file so far is the second writer's bytes: it can be closed at its last row group."""
        return self._shadow is not None

    def write(self, columns: Mapping[str, np.ndarray]) -> None:
        """Append rows as one row group; ``columns`` maps every column name to its values."""
        pa = self._pa
        if self.failed is not None:
            raise TraceWriteError(f"{self.path}: no more rows after a failed write ({self.failed})")
        missing = [c for c in self.columns if c not in columns]
        if missing:
            raise InputError(f"{self.path}: rows without column(s) {', '.join(missing)}")
        arrays = [np.asarray(columns[c], dtype=np.float64) for c in self.columns]
        if not len(arrays[0]):
            return
        time = arrays[0]
        check_time(np.concatenate([[self._last_time], time]) if np.isfinite(self._last_time) else time,
                   str(self.path))
        table = pa.Table.from_arrays([pa.array(a, type=pa.float64()) for a in arrays], schema=self._schema)
        try:
            self._writer.write_table(table)
        except OSError as exc:
            self.failed = exc
            raise TraceWriteError(f"{self.path}: could not write rows {self.rows + 1}-{self.rows + len(time)} "
                                  f"(t = {time[0]:.9g} to {time[-1]:.9g} s): {exc}") from exc
        if self._shadow is not None:
            self._shadow.write_table(table)
            if self._shadow_sink.position != os.path.getsize(self.path):  # not the same bytes: no recovery
                self._shadow = None
        self._last_time = float(time[-1])
        self.rows += len(time)

    def close(self, metadata: Mapping[str, object] | None = None) -> Path:
        """Write ``metadata`` and the footer; the file is then a complete Parquet trace (after a
        failed write: of the rows written before it). Raises OSError when not even that can
        be written (the file then has no footer)."""
        meta = _clean_metadata(metadata)
        _check_parquet_keys(meta)
        if self.failed is not None:
            return self._close_at_last_row_group(meta)
        if self.rows == 0:  # a table with no rows still has its columns
            self._writer.write_table(self._schema.empty_table())
        if meta:
            self._writer.add_key_value_metadata(meta)
        self._writer.close()
        self._close_shadow()
        return self.path

    def _close_at_last_row_group(self, meta: dict[str, str]) -> Path:
        """After a failed write: cut the file back to its last whole row group and append the
        footer the second writer gives for the row groups up to there."""
        try:
            self._writer.close()
        except Exception:  # noqa: BLE001 - its bytes past the last row group are cut off below
            pass
        if self._shadow is None:
            raise OSError(f"{self.path}: the trace could not be closed after a failed write ({self.failed}): "
                          f"its row groups cannot be recovered")
        end = self._shadow_sink.position
        self._shadow_sink.keep()
        if self.rows == 0:
            self._shadow.write_table(self._schema.empty_table())
        if meta:
            self._shadow.add_key_value_metadata(meta)
        self._shadow.close()
        footer, self._shadow = bytes(self._shadow_sink.kept), None
        try:
            os.truncate(self.path, end)  # frees what the failed row group took
            with open(self.path, "r+b") as fh:
                fh.seek(end)
                fh.write(footer)
                fh.truncate()
        except OSError as exc:
            raise OSError(f"{self.path}: after a failed write ({self.failed}) not even the footer of the "
                          f"{self.rows} rows written could be written: {exc}") from exc
        return self.path

    def _close_shadow(self) -> None:
        if self._shadow is not None:
            try:
                self._shadow.close()
            except Exception:  # noqa: BLE001 - it writes nowhere
                pass
            self._shadow = None

    def abort(self) -> None:
        """Close the file without metadata and remove it."""
        try:
            self._writer.close()
        except Exception:  # noqa: BLE001 - the file is removed anyway
            pass
        self._close_shadow()
        self.path.unlink(missing_ok=True)


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
        if k in _RESERVED_PARQUET_KEYS or k.startswith(_RESERVED_PARQUET_PREFIX):
            continue
        meta[k] = value.decode("utf-8", "replace")
    return meta


def copy_trace_to_csv(parquet: str | Path, csv_path: str | Path, metadata: Mapping[str, object] | None = None,
                      batch_rows: int = ROW_GROUP_ROWS) -> Path:
    """Write the CSV form of a Parquet trace, ``batch_rows`` rows at a time (never the whole
    table in memory); the metadata is the Parquet file's unless ``metadata`` is given."""
    import pyarrow.parquet as pq

    parquet, csv_path = Path(parquet), Path(csv_path)
    meta = _clean_metadata(read_trace_metadata(parquet) if metadata is None else metadata)
    source = pq.ParquetFile(parquet)
    with open(csv_path, "w", encoding="utf-8", newline="") as fh:
        for key, value in meta.items():
            fh.write(f"# {key}: {value}\n")
        header = True
        for batch in source.iter_batches(batch_size=batch_rows):
            frame = pd.DataFrame({name: batch.column(i).to_numpy(zero_copy_only=False)
                                  for i, name in enumerate(batch.schema.names)})
            frame.to_csv(fh, index=False, header=header, lineterminator="\n", na_rep="")
            header = False
        if header:  # no rows: the header line alone
            pd.DataFrame(columns=source.schema_arrow.names).to_csv(fh, index=False, lineterminator="\n")
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
    fmt = _format(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
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
    if _format(path) != "parquet":
        raise InputError(f"{path}: reading a trace by row groups needs a Parquet trace")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
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
