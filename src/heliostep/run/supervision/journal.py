"""The rows a supervised child computed and has not yet sent, in a file its supervisor maps: :class:`Journal`.

The child streams its rows to the supervisor in messages (:mod:`heliostep.run.supervision.child`); a
crash, ``exit()`` or kill of the child loses what a message did not yet carry unless the supervisor
can read it after the death. So the child keeps here, in memory both processes map:

- the trace rows and the solution rows (those its monitor took) since its last message, with the
  number of messages sent before them;
- its kernel's block of rows not yet handed over (:attr:`heliostep.cosim.kernel.Kernel.block_buffer`):
  the rows CVODE's steps recorded in C since the last hand-over, with their count.

Each count is written after its rows, so a death in the middle of a write leaves the rows before it.
After the death the supervisor takes (:meth:`Journal.unsent`) the journal's rows when it received every
message the child sent (a message sent but not yet noted here carried them already) and the kernel's:
every row the child computed.
"""

from __future__ import annotations

import mmap
import os
from pathlib import Path

import numpy as np

from heliostep.cosim.kernel import block_bytes, rows_not_handed_over

__all__ = ["SOLUTION_BYTES", "TRACE_ROWS", "Journal"]

#: The most trace rows the journal holds (the child sends its rows when it would hold more).
TRACE_ROWS = 1024
#: Bytes of solution rows (the monitor's: every solver step) the journal holds: room for more rows than
#: the child computes between its messages (whose totals take the rows' figures: sent more often, they cost).
SOLUTION_BYTES = 8 << 20

_HEADER = 64  # bytes: int64 messages sent, trace rows, solution rows, row width
_SENT, _TRACE, _SOLUTION, _WIDTH = range(4)


class Journal:
    """A journal in shared memory ``memory``: made by :meth:`in_memory` (a forked child inherits it) or mapped
    from the file ``path`` made by :meth:`create` (a child started by the fork server maps it by name)."""

    def __init__(self, path: str | Path | None = None, memory: mmap.mmap | None = None):
        if memory is None:
            descriptor = os.open(path, os.O_RDWR)  # type: ignore[arg-type]
            try:
                memory = mmap.mmap(descriptor, 0)
            finally:
                os.close(descriptor)
        self._map = memory
        self._view = memoryview(self._map)
        self.header = np.ndarray((4,), np.int64, self._view, 0)
        self.width = int(self.header[_WIDTH])
        block = block_bytes(self.width)
        self.kernel_block = self._view[_HEADER : _HEADER + block]
        start = _HEADER + block
        self._trace = np.ndarray((TRACE_ROWS, self.width), float, self._view, start)
        start += self._trace.nbytes
        self._solution = np.ndarray((_solution_rows(self.width), self.width), float, self._view, start)

    @classmethod
    def in_memory(cls, width: int) -> Journal:
        """A journal of rows ``width`` values wide in anonymous shared memory, which a child forked after it
        shares (no file: neither a full TMPDIR nor a file-size limit can take it away)."""
        memory = mmap.mmap(-1, _size(width), flags=mmap.MAP_SHARED | mmap.MAP_ANONYMOUS)
        memory[:32] = np.array([0, 0, 0, width], dtype=np.int64).tobytes()
        return cls(memory=memory)

    @staticmethod
    def create(path: str | Path, width: int) -> None:
        """Make the file of a journal of rows ``width`` values wide (zeros: nothing sent, no rows)."""
        size = _size(width)
        with open(path, "wb") as handle:
            handle.truncate(size)
            # its blocks allocated now: a full file system refuses here, not with SIGBUS while the child writes
            os.posix_fallocate(handle.fileno(), 0, size)
            handle.write(np.array([0, 0, 0, width], dtype=np.int64).tobytes())

    # ------------------------------------------------------------------ the child's side
    def keep_trace(self, rows: np.ndarray) -> bool:
        """Keep trace ``rows`` after those kept; False (nothing kept) when there is no room for them."""
        return self._keep(self._trace, _TRACE, rows)

    def keep_solution(self, rows: np.ndarray) -> bool:
        """Keep solution ``rows`` after those kept; False (nothing kept) when there is no room for them."""
        return self._keep(self._solution, _SOLUTION, rows)

    def _keep(self, region: np.ndarray, count: int, rows: np.ndarray) -> bool:
        held = int(self.header[count])
        if held + len(rows) > len(region):
            return False
        region[held : held + len(rows)] = rows
        self.header[count] = held + len(rows)  # after the rows: a death meanwhile leaves those before
        return True

    def sent(self) -> None:
        """One more message sent, carrying every row kept: none is kept now."""
        self.header[_SENT] += 1
        self.header[_TRACE] = self.header[_SOLUTION] = 0

    # ------------------------------------------------------------------ the supervisor's side
    def unsent(self, received: int) -> tuple[np.ndarray, np.ndarray]:
        """The solution rows and the trace rows the child computed and did not send (after its death),
        in time order, given the ``received`` messages: (solution rows, trace rows)."""
        solution, trace = np.zeros((0, self.width)), np.zeros((0, self.width))
        if received == int(self.header[_SENT]):  # else its last message carried them
            solution = self._solution[: int(self.header[_SOLUTION])].copy()
            trace = self._trace[: int(self.header[_TRACE])].copy()
        rows, kinds = rows_not_handed_over(self.kernel_block, self.width)
        return np.vstack([solution, rows]), np.vstack([trace, rows[kinds == 1]])

    def close(self) -> None:
        del self.header, self._trace, self._solution
        self.kernel_block.release()
        self._view.release()
        self._map.close()


def _size(width: int) -> int:
    """Bytes of a journal of rows ``width`` values wide."""
    return _HEADER + block_bytes(width) + 8 * width * (TRACE_ROWS + _solution_rows(width))


def _solution_rows(width: int) -> int:
    """The most solution rows of ``width`` values the journal holds."""
    return max(TRACE_ROWS, SOLUTION_BYTES // (8 * width))
