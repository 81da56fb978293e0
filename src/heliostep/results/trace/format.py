"""The rules of the trace format that its reader and writer share (the format:
:mod:`heliostep.results.trace.files`): the time column, the suffixes, the metadata's form and the
Parquet row groups.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from heliostep.errors import InputError

__all__ = [
    "ROW_GROUP_ROWS",
    "SUFFIXES",
    "TIME",
    "check_parquet_keys",
    "check_time",
    "clean_metadata",
    "is_complete",
    "is_reserved_parquet_key",
    "trace_format",
]

TIME = "time"
SUFFIXES = (".parquet", ".csv")
_RESERVED_PARQUET_KEYS = ("pandas",)
_RESERVED_PARQUET_PREFIX = "ARROW:"
#: Rows per Parquet row group (and per slice converted to Arrow at a time): with the 20 float64
#: columns of a run's trace 2.6 MB, the most of a streamed trace held at once.
ROW_GROUP_ROWS = 16_384


def trace_format(path: Path) -> str:
    """The encoding of a trace file by its suffix: ``"parquet"`` or ``"csv"``."""
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(
            f"{path}: unknown trace format {suffix or '(no suffix)'!r}; expected one of {', '.join(SUFFIXES)}"
        )
    return suffix[1:]


def clean_metadata(metadata: Mapping[str, object] | None) -> dict[str, str]:
    """*metadata* as the trace format's ``dict[str, str]`` (bools as ``"true"``/``"false"``, numbers
    as their ``str``); :class:`InputError` for a key or value the format cannot hold."""
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


def is_reserved_parquet_key(key: str) -> bool:
    """A Parquet key-value metadata key that Arrow or pandas put there themselves (not a trace's)."""
    return key in _RESERVED_PARQUET_KEYS or key.startswith(_RESERVED_PARQUET_PREFIX)


def check_parquet_keys(meta: Mapping[str, str]) -> None:
    """Raise :class:`InputError` for a key that Arrow or pandas keep for themselves in Parquet."""
    for key in meta:
        if is_reserved_parquet_key(key):
            raise InputError(f"metadata key {key!r} is reserved in Parquet files")


def is_complete(metadata: Mapping[str, str]) -> bool:
    """False only when the metadata says ``complete: false`` (case-insensitive)."""
    value = metadata.get("complete")
    return not (isinstance(value, str) and value.strip().lower() == "false")
