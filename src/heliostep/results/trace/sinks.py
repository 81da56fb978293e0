"""Where a run's rows go while simulating: the :class:`RowSink` protocol and the held trace.

Each sink assembles the master's rows, keeps them its own way (in memory, streamed to Parquet, or
not at all) and hands them to the run's figures in the same pass.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd

from heliostep.results.figures.run_summary import RunStatus
from heliostep.results.trace.frame import TraceAssembler, master_block

__all__ = ["HeldTrace", "KeptRows", "RowSink"]


class RowSink(Protocol):
    """A run's row sink: the master's row blocks in, the trace kept (or not) and the figures fed."""

    rows: int  # rows received
    last_time: float | None  # [s] time of the last row received
    columns: list[str]  # the assembled trace's columns
    trace_kept: bool  # False: the run keeps no trace (figures only)

    def __call__(self, block: np.ndarray) -> None:
        """Take a block of the master's rows (rows x the master's columns)."""

    def finish(self, status: RunStatus) -> RunStatus:
        """The rows still held go out; the run's status, failed if they could not be kept."""

    def close(self, metadata: Mapping[str, str]) -> Path | None:
        """The run has ended (``metadata``: the trace's, saying how): the trace is final; the
        trace file, if streamed."""

    def abort(self) -> None:
        """The run ended without a result: whatever was kept goes."""

    @property
    def held_trace(self) -> pd.DataFrame | None:
        """The trace in memory, if held."""

    @property
    def trace_file(self) -> Path | None:
        """The trace file, if streamed (final once closed)."""


class HeldTrace:
    """Row sink of a run whose trace is held in memory: the blocks assembled as they come, fed to
    ``figures`` and kept; :attr:`held_trace` is their concatenation (the same rows as assembling
    the master's whole trace at once)."""

    trace_kept = True
    trace_file = None

    def __init__(
        self,
        master_columns: list[str],
        assembler: TraceAssembler,
        figures: Callable[[pd.DataFrame], None] | None = None,
    ) -> None:
        self.master_columns = list(master_columns)
        self.assembler = assembler
        self.columns = assembler.columns(self.master_columns)
        self.figures = figures
        self._blocks: list[pd.DataFrame] = []
        self._trace: pd.DataFrame | None = None
        self.rows = 0
        self.last_time: float | None = None

    def __call__(self, block: np.ndarray) -> None:
        block = master_block(block, self.master_columns, "the trace held in memory")
        if not len(block):
            return
        frame = self.assembler(pd.DataFrame(block, columns=self.master_columns))
        if self.figures is not None:
            self.figures(frame)
        self._blocks.append(frame)
        self.rows += len(frame)
        self.last_time = float(block[-1, 0])

    def finish(self, status: RunStatus) -> RunStatus:
        return status

    def close(self, metadata: Mapping[str, str]) -> None:
        if self._blocks:
            self._trace = pd.concat(self._blocks, ignore_index=True) if len(self._blocks) > 1 else self._blocks[0]
        else:
            self._trace = self.assembler(
                pd.DataFrame(np.zeros((0, len(self.master_columns))), columns=self.master_columns)
            )
        self._blocks = []

    def abort(self) -> None:
        self._blocks, self._trace = [], None

    @property
    def held_trace(self) -> pd.DataFrame | None:
        return self._trace


class KeptRows:
    """The master's rows kept as they come, to be handed to the run's sink once what they are assembled
    with is known (a controller's steps, decided while simulating): :meth:`replay`."""

    def __init__(self, master_columns: list[str]) -> None:
        self.master_columns = list(master_columns)
        self._blocks: list[np.ndarray] = []
        self.rows = 0
        self.last_time: float | None = None

    def __call__(self, block: np.ndarray) -> None:
        block = master_block(block, self.master_columns, "the rows kept")
        if len(block):
            self._blocks.append(block.copy())
            self.rows += len(block)
            self.last_time = float(block[-1, 0])

    def frame(self, columns: list[str]) -> pd.DataFrame:
        """The rows kept so far, of ``columns``."""
        index = [self.master_columns.index(c) for c in columns]
        data = np.concatenate(self._blocks) if self._blocks else np.zeros((0, len(self.master_columns)))
        return pd.DataFrame(data[:, index], columns=columns)

    def replay(self, sink: Callable[[np.ndarray], None], columns: list[str], rows: int = 4096) -> None:
        """The rows kept, of ``columns``, to ``sink`` in blocks of at most ``rows``; none kept after."""
        index = [self.master_columns.index(c) for c in columns]
        blocks, self._blocks = self._blocks, []
        for block in blocks:
            for start in range(0, len(block), rows):
                sink(np.ascontiguousarray(block[start : start + rows, index]))

    def abort(self) -> None:
        self._blocks = []
