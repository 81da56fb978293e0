"""pvlib's sun grids kept by content, so that a run seen before does not import pvlib at all.

The values are pvlib's own, stored bit for bit under a hash of every input; the cache never fails a run.

Details: docs/geometry.md, ``heliostep.solar.sun_cache``.
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
import zipfile
from collections.abc import Callable, Sequence
from importlib import metadata as package_metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from heliostep.paths import fmus_dir

__all__ = ["CACHE_FORMAT", "MAX_ENTRIES", "MAX_ENTRY_BYTES", "cache_folder", "cache_key", "cached_frame"]

#: Bumped whenever what an entry holds, or how a key is made, changes.
CACHE_FORMAT = 1

#: The column types an entry holds (instants as int64 nanoseconds).
_KEPT_DTYPES = (np.dtype(np.float64), np.dtype(np.int64))

#: Entries kept; beyond, the least recently used are removed.
MAX_ENTRIES = 256

#: The largest grid kept [bytes of float64 values] (a 5-minute window's grids take 20-150 kB).
MAX_ENTRY_BYTES = 2 << 20


def cache_folder() -> Path:
    """The folder of the entries: ``sun-grids`` in the FMU cache."""
    return fmus_dir() / "sun-grids"


@functools.lru_cache(maxsize=1)
def _pvlib_version() -> str:
    try:
        return package_metadata.version("pvlib")
    except package_metadata.PackageNotFoundError:  # (pvlib is a dependency: then the import fails anyway)
        return "unknown"


def _part(value) -> bytes:
    """One input's bytes in the key: floats exactly (hex), arrays by dtype, shape and bits."""
    if isinstance(value, float | np.floating):
        return float(value).hex().encode()
    if isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
        return f"{array.dtype.str}{array.shape}".encode() + array.tobytes()
    return repr(value).encode()


def cache_key(kind: str, times: pd.DatetimeIndex, parameters: Sequence) -> str:
    """The SHA-256 (hex) of everything a grid's values depend on (see the module's docstring)."""
    digest = hashlib.sha256()
    # the index's dtype names its unit (pandas 3 makes microsecond grids too) and its timezone
    for part in (kind, CACHE_FORMAT, _pvlib_version(), str(times.dtype), np.asarray(times.asi8), *parameters):
        chunk = _part(part)
        digest.update(len(chunk).to_bytes(8, "little"))  # length-prefixed: no two inputs join alike
        digest.update(chunk)
    return digest.hexdigest()


def cached_frame(
    kind: str,
    times: pd.DatetimeIndex,
    parameters: Sequence,
    compute: Callable[[], pd.DataFrame],
) -> pd.DataFrame:
    """``compute()`` (a frame of float64 or int64 columns indexed by ``times``), or the same values read
    back from the entry of (``kind``, ``times``, ``parameters``) when there is one.

    ``parameters`` must hold every other input the values depend on (floats, strings, arrays).
    The frame given back is indexed by ``times`` itself, its columns in ``compute()``'s order.
    """
    path = cache_folder() / f"{cache_key(kind, times, parameters)}.npz"
    found = _read(path, len(times))
    if found is not None:
        return pd.DataFrame(found, index=times)  # (the columns' arrays as read: no copy, no conversion)
    frame = compute()
    columns = {str(name): frame[name].to_numpy() for name in frame.columns}
    if all(values.dtype in _KEPT_DTYPES for values in columns.values()) and list(columns) == list(frame.columns):
        if sum(values.nbytes for values in columns.values()) <= MAX_ENTRY_BYTES:
            _write(path, columns)
    return frame


def _read(path: Path, rows: int) -> dict[str, np.ndarray] | None:
    """The entry's columns in their order, or None (none, damaged, or not of ``rows`` rows)."""
    try:
        with np.load(path, allow_pickle=False) as entry:
            order = [str(name) for name in entry["__columns__"]]
            columns = {name: entry[name] for name in order}
        os.utime(path)  # used: the last to be removed
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):  # none, or not whole: a miss
        return None
    if not all(values.dtype in _KEPT_DTYPES and values.shape == (rows,) for values in columns.values()):
        return None
    return columns


def _write(path: Path, columns: dict[str, np.ndarray]) -> None:
    """The entry written atomically (never an error: a cache that cannot be written is only slower),
    then the oldest entries beyond :data:`MAX_ENTRIES` removed."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=".tmp-", suffix=".npz", dir=path.parent)
        try:
            with os.fdopen(handle, "wb") as file:
                arrays: dict[str, Any] = {"__columns__": np.array(list(columns)), **columns}
                np.savez(file, **arrays)
            os.replace(temporary, path)
        finally:
            Path(temporary).unlink(missing_ok=True)
        _trim(path.parent)
    except OSError:
        return


def _trim(folder: Path) -> None:
    entries = []
    for entry in folder.glob("*.npz"):
        if entry.name.startswith("."):  # another process's entry being written
            continue
        try:
            entries.append((entry.stat().st_mtime, entry))
        except OSError:  # removed meanwhile by another process
            continue
    for _, entry in sorted(entries)[: max(0, len(entries) - MAX_ENTRIES)]:
        entry.unlink(missing_ok=True)
