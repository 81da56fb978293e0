"""A Parquet trace written while it is produced, one row group at a time (:class:`TraceWriter`);
the trace format: :mod:`heliostep.results.trace.files`."""

from __future__ import annotations

import io
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from heliostep.errors import InputError, RunFailure
from heliostep.results.trace.format import TIME, check_parquet_keys, check_time, clean_metadata, trace_format

__all__ = ["PARQUET_OPTIONS", "TRACE_ENCODING", "TraceWriteError", "TraceWriter", "arrow_path"]


def arrow_path(path: str | Path) -> str:
    """``path`` as pyarrow is to write it: absolute, so that pyarrow's own expansion of a leading ``~`` never
    sends a file elsewhere than where heliostep made its folder (``~`` means $HOME only where --out is read)."""
    return os.fspath(Path(path).absolute())


class TraceWriteError(RunFailure):
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

    def keep(self) -> bytearray:
        """Keep the bytes written from now on (in the returned buffer, also :attr:`kept`)."""
        self.kept = bytearray()
        return self.kept


#: How a trace's float64 columns are encoded in Parquet (pyarrow.parquet.ParquetWriter options).
TRACE_ENCODING = {"use_dictionary": False, "column_encoding": "BYTE_STREAM_SPLIT"}
#: Every option a trace's ParquetWriter is given: its encoding, zstd, and no serialized Arrow schema
#: (see :class:`TraceWriter`).
PARQUET_OPTIONS = {"compression": "zstd", "store_schema": False, **TRACE_ENCODING}


class TraceWriter:
    """A Parquet trace written as it is produced: :meth:`write` appends one row group of float64
    columns, :meth:`close` writes the metadata (all of it, ``complete`` included) and the footer.

    Until :meth:`close` the file has no footer: a reader sees no table and no metadata, so a file
    cut short (killed process, full disk) never claims to be complete. Write to a temporary name
    and rename into place afterwards (:func:`heliostep.results.output.files.atomic_path`).

    A row group that cannot be written raises :class:`TraceWriteError` (``failed`` then holds
    the cause) and writes nothing more; :meth:`close` then keeps the row groups written before
    it: the file is cut back to their end and given the footer a second writer produced from the
    same row groups (Parquet bytes are a function of the rows and the settings; the two files'
    sizes are compared after every row group). With
    ``keep_on_failure=False`` there is no second writer (half the encoding work) and a failed
    file cannot be closed, only aborted. ``rows`` counts the rows written, ``last_time`` the
    time of the last one.
    """

    def __init__(self, path: str | Path, columns: list[str], keep_on_failure: bool = True):
        import pyarrow as pa
        import pyarrow.parquet as pq

        self.path = Path(path)
        if trace_format(self.path) != "parquet":
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
        # written faster and take less space (benchmarks/bench_trace_io.py)
        self._writer = pq.ParquetWriter(arrow_path(self.path), self._schema, **PARQUET_OPTIONS)
        # the same row groups written nowhere: its footer is the one for the groups written so far
        self._shadow_sink = _ByteCounter()
        self._shadow = pq.ParquetWriter(self._shadow_sink, self._schema, **PARQUET_OPTIONS) if keep_on_failure else None
        self._pa = pa

    @property
    def last_time(self) -> float | None:
        return float(self._last_time) if self.rows else None

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
        check_time(np.concatenate([[self._last_time], time]) if np.isfinite(self._last_time) else time, str(self.path))
        table = pa.Table.from_arrays([pa.array(a, type=pa.float64()) for a in arrays], schema=self._schema)
        try:
            self._writer.write_table(table)
        except OSError as exc:
            self.failed = exc
            raise TraceWriteError(
                f"{self.path}: could not write rows {self.rows + 1}-{self.rows + len(time)} "
                f"(t = {time[0]:.9g} to {time[-1]:.9g} s): {exc}"
            ) from exc
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
        meta = clean_metadata(metadata)
        check_parquet_keys(meta)
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
            raise OSError(
                f"{self.path}: the trace could not be closed after a failed write ({self.failed}): "
                f"its row groups cannot be recovered"
            )
        end = self._shadow_sink.position
        kept = self._shadow_sink.keep()
        if self.rows == 0:
            self._shadow.write_table(self._schema.empty_table())
        if meta:
            self._shadow.add_key_value_metadata(meta)
        self._shadow.close()
        footer, self._shadow = bytes(kept), None
        try:
            os.truncate(self.path, end)  # frees what the failed row group took
            with open(self.path, "r+b") as fh:
                fh.seek(end)
                fh.write(footer)
                fh.truncate()
        except OSError as exc:
            raise OSError(
                f"{self.path}: after a failed write ({self.failed}) not even the footer of the "
                f"{self.rows} rows written could be written: {exc}"
            ) from exc
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
