"""The trace rows of a run: held for the trace, or handed to a sink in blocks as they come.

With a sink, :class:`RowBuffer` holds at most ``sink_rows`` rows (or one larger block stored at once)
and hands over whatever it holds after :attr:`RowBuffer.flush_interval` seconds of wall time too (a
supervised child's crash then loses only the last moments' rows).
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from heliostep.errors import InputError


class RowBuffer:
    """Trace rows of ``columns``: held (without a sink) or passed on to ``sink`` in blocks.

    ``max_buffered`` is the most rows held at once, ``total`` the rows stored so far (held or
    handed over).
    """

    #: [s] of wall time after which rows held are handed over at the next store (None: only by count).
    flush_interval: float | None = None

    def __init__(self, columns: Sequence[str], sink: Callable[[np.ndarray], None] | None = None, sink_rows: int = 4096):
        if sink is not None and sink_rows < 1:
            raise InputError(f"sink_rows must be at least 1, not {sink_rows}")
        self.columns = list(columns)
        self.sink, self.sink_rows = sink, sink_rows
        self.blocks: list[np.ndarray] = []  # blocks not yet handed to the sink (all of them without one)
        self.buffered = 0  # rows in self.blocks
        self.max_buffered = 0
        self.total = 0
        self._flushed = clock.monotonic()

    def store(self, rows: np.ndarray) -> None:
        """Every trace row goes through here: ``rows`` is a 2-D block (rows × ``columns``) in time
        order. Without a sink the rows are kept for :meth:`trace`; with one they are handed over
        in blocks of at most ``sink_rows`` once that many are held."""
        rows = np.asarray(rows, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != len(self.columns):
            raise ValueError(f"trace rows must be a 2-D block of {len(self.columns)} columns, got shape {rows.shape}")
        if self.sink is not None and self.buffered + len(rows) > self.sink_rows:
            self.flush()  # what is held goes first: held rows never exceed sink_rows or one block
        self.blocks.append(rows)
        self.buffered += len(rows)
        self.total += len(rows)
        self.max_buffered = max(self.max_buffered, self.buffered)
        if self.sink is not None and self.buffered >= self.sink_rows:
            self.flush()
        elif self.flush_interval is not None and clock.monotonic() - self._flushed >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        """Hand the held rows to the sink, in blocks of at most ``sink_rows``."""
        if self.sink is None or not self.buffered:
            return
        data = np.vstack(self.blocks)
        self.blocks, self.buffered = [], 0
        self._flushed = clock.monotonic()
        for start in range(0, len(data), self.sink_rows):
            self.sink(data[start : start + self.sink_rows])

    def trace(self) -> pd.DataFrame:
        """The rows held (all of them without a sink; none with one: they are flushed to it)."""
        self.flush()
        data = np.vstack(self.blocks) if self.blocks else np.zeros((0, len(self.columns)))
        return pd.DataFrame(data, columns=self.columns)
