"""glibc's heap thresholds back to their dynamic defaults where ``MALLOC_TRIM_THRESHOLD_`` fixed them.

Dask's nanny starts every worker with ``MALLOC_TRIM_THRESHOLD_=65536`` (its config
``distributed.nanny.pre-spawn-environ``, to hand freed memory back to the OS). Setting that variable
also turns off glibc's dynamic mmap threshold (mallopt(3): setting M_TRIM_THRESHOLD, M_MMAP_THRESHOLD,
M_TOP_PAD or M_MMAP_MAX disables it), so the threshold stays at 128 KiB: every numpy array of 128 KiB or
more (16 384 float64) is then its own mmap, returned at once, and its pages are faulted in, zeroed,
each time. A sweep case's figures work on blocks of 16 384 rows, so a Dask worker ran them several
times slower than a plain process (``benchmarks/bench_sweep.py --full-day``). :func:`restore_dynamic_heap`
sets the two thresholds to where glibc's own dynamic rule takes them at most (64-bit: the mmap threshold
32 MiB, the trim threshold twice it): arrays up to 32 MiB come from the heap and are reused, and a worker
keeps at most 64 MiB of freed heap. It only acts where the variable is set and the C library has ``mallopt``.
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["MMAP_THRESHOLD", "TRIM_THRESHOLD", "restore_dynamic_heap"]

#: glibc's DEFAULT_MMAP_THRESHOLD_MAX on 64-bit systems: the most its dynamic rule raises the threshold to [B].
MMAP_THRESHOLD = 32 << 20
#: Twice the mmap threshold, as glibc's dynamic rule sets the trim threshold [B].
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # <malloc.h>
_restored = False  # set once per process (a forked child inherits the heap's settings)


def restore_dynamic_heap() -> bool:
    """Raise glibc's mmap and trim thresholds (:data:`MMAP_THRESHOLD`, :data:`TRIM_THRESHOLD`) when
    ``MALLOC_TRIM_THRESHOLD_`` is set in this process's environment; True if they are set (once per
    process: every later call only says so)."""
    global _restored
    if _restored or "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return _restored
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the C library the interpreter runs on
    except (OSError, AttributeError):  # not glibc (musl, macOS): nothing to undo
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    _restored = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return _restored
