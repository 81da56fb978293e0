"""A run's trace streamed to Parquet as the master produces it (long windows: bounded memory).

The file has no footer until :meth:`TraceStream.close`, so it claims nothing before the run's outcome is known.

Details: docs/running.md, ``heliostep.results.trace.stream``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.results.figures.run_summary import RunStatus
from heliostep.results.trace.files import ROW_GROUP_ROWS, TraceWriteError, TraceWriter
from heliostep.results.trace.frame import TraceAssembler, master_block

__all__ = ["TraceStream"]


class TraceStream:
    """Row sink: the master's row blocks, assembled and written to ``path`` as Parquet row groups.

    ``master_columns`` are the master's trace columns (the layout of each block's rows).
    ``max_block_rows`` is the largest block received and ``max_held_rows`` the most assembled rows
    held before a row group was written (at most ``row_group_rows`` + one block). A
    :class:`~heliostep.results.trace.sinks.RowSink`.
    """

    trace_kept = True
    held_trace = None

    def __init__(
        self,
        path: str | Path,
        master_columns: list[str],
        assembler: TraceAssembler,
        row_group_rows: int = ROW_GROUP_ROWS,
        figures: Callable[[pd.DataFrame], None] | None = None,
    ):
        if row_group_rows < 1:
            raise ValueError(f"row_group_rows must be at least 1, not {row_group_rows}")
        self.path = Path(path)
        self.master_columns = list(master_columns)
        self.assembler = assembler
        self.columns = assembler.columns(self.master_columns)
        self.row_group_rows = row_group_rows
        self.figures = figures
        self._writer = TraceWriter(self.path, self.columns)
        self._held: list[pd.DataFrame] = []
        self._held_rows = 0
        self.rows = 0  # rows received
        self.row_groups = 0
        self.max_block_rows = 0
        self.max_held_rows = 0
        self.last_time: float | None = None
        self.closed = False
        self.failed: TraceWriteError | None = None  # a row group could not be written
        self.rows_not_written = 0  # rows received that the file does not hold (after a failed write)
        self._unwritten: list[pd.DataFrame] = []  # those rows, kept in memory

    def __call__(self, block: np.ndarray) -> None:
        block = master_block(block, self.master_columns, str(self.path))
        if not len(block):
            return
        frame = self.assembler(pd.DataFrame(block, columns=self.master_columns))
        if self.failed is not None:  # nothing more is written; the rows are kept in memory
            self._keep_unwritten([frame])
            self.rows += len(frame)
            self.last_time = float(block[-1, 0])
            return
        self.max_block_rows = max(self.max_block_rows, len(block))
        self._held.append(frame)
        self._held_rows += len(frame)
        self.rows += len(frame)
        self.last_time = float(block[-1, 0])
        self.max_held_rows = max(self.max_held_rows, self._held_rows)
        while self._held_rows >= self.row_group_rows:
            self._write(self.row_group_rows)

    def _write(self, rows: int) -> None:
        """Write the first ``rows`` held rows as one row group."""
        held = pd.concat(self._held, ignore_index=True) if len(self._held) > 1 else self._held[0]
        group, rest = held.iloc[:rows], held.iloc[rows:]
        try:
            self._writer.write({c: group[c].to_numpy() for c in self.columns})
        except TraceWriteError as exc:
            self.failed = exc
            self._keep_unwritten([held])
            self._held, self._held_rows = [], 0
            raise
        self.row_groups += 1
        if self.figures is not None:
            self.figures(group)
        self._held = [rest.reset_index(drop=True)] if len(rest) else []
        self._held_rows = len(rest)

    def _keep_unwritten(self, frames: list[pd.DataFrame]) -> None:
        """Rows the file will not hold: kept in memory, and on to the figures."""
        for frame in frames:
            if len(frame):
                self._unwritten.append(frame.reset_index(drop=True))
                self.rows_not_written += len(frame)
                if self.figures is not None:
                    self.figures(frame)

    @property
    def unwritten_trace(self) -> pd.DataFrame | None:
        """The rows computed after the file's last row (None: the file holds every row)."""
        if not self._unwritten:
            return None
        if len(self._unwritten) > 1:
            self._unwritten = [pd.concat(self._unwritten, ignore_index=True)]
        return self._unwritten[0]

    @property
    def written_rows(self) -> int:
        """Rows in the file (all those received unless a write failed)."""
        return self._writer.rows

    @property
    def written_time(self) -> float | None:
        """Time of the last row in the file (None: no row)."""
        return self._writer.last_time

    def flush(self) -> None:
        """Write the rows still held as a row group (:class:`TraceWriteError` if it cannot be)."""
        if self._held_rows and self.failed is None:
            self._write(self._held_rows)

    @property
    def trace_file(self) -> Path:
        return self.path

    def finish(self, status: RunStatus) -> RunStatus:
        """Write the rows still held; when a row group could not be written (now or before), the
        run failed there: the file keeps the rows up to :attr:`written_time`."""
        try:
            self.flush()  # the last rows: a write failing here fails the run as one during it
        except TraceWriteError:
            pass
        if self.failed is None:
            return status
        reached = self.last_time if self.last_time is not None else 0.0
        return RunStatus(
            False,
            f"the trace could not be written: {self.failed}; the file keeps the {self.written_rows} rows "
            f"up to t = {self.written_time or 0.0:.9g} s, the {self.rows_not_written} rows computed after "
            f"them (to t = {reached:.9g} s) are held in memory for the rescue",
            "failed",
            reached,
        )

    def close(self, metadata: Mapping[str, object]) -> Path:
        """Write the rows still held, then ``metadata`` and the footer: the file is complete
        (after a failed write: of the rows written before it; call :meth:`flush` first to know
        whether the last rows made it, so that ``metadata`` can say so)."""
        try:
            self.flush()
        except TraceWriteError:
            pass  # the file keeps the row groups written before; ``failed`` says why
        if self.failed is not None:  # the file says what it holds: the time of its own last row
            metadata = {
                **metadata,
                "time_reached": repr(float(self.written_time or 0.0)),
                "rows_computed_after_this_file": str(self.rows_not_written),
            }
        self._writer.close(metadata)
        self.closed = True
        return self.path

    def abort(self) -> None:
        """Remove the file, finished or not (the run it belongs to ended without a result)."""
        self._held, self._held_rows, self._unwritten = [], 0, []
        if not self.closed:
            self._writer.abort()
            self.closed = True
        self.path.unlink(missing_ok=True)
