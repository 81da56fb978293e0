"""The rules of the trace format that its reader and writer share (the format:
:mod:`heliostep.results.trace.files`): the time column, the suffixes, the metadata's form, the
Parquet row groups and the local time of a row (the window's start plus its time).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError

__all__ = [
    "ROW_GROUP_ROWS",
    "SUFFIXES",
    "RUN_METADATA_FILE",
    "TIME",
    "TRACE_METADATA_KEY",
    "check_parquet_keys",
    "check_time",
    "clean_metadata",
    "is_complete",
    "is_reserved_parquet_key",
    "iso_texts",
    "local_times",
    "trace_format",
]

TIME = "time"
#: The file beside a run's ``trace.csv`` that holds the rest of its metadata, under :data:`TRACE_METADATA_KEY`
#: (the CSV's header holds the units, its ``local_time`` column the window).
RUN_METADATA_FILE = "metadata.json"
TRACE_METADATA_KEY = "trace"
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


def local_times(time: np.ndarray, window_start: str, timezone: str, resolution: str = "ns") -> pd.DatetimeIndex:
    """The instants ``time`` [s from the window's start] as times of ``timezone`` (an IANA name), the
    start an ISO 8601 text (``2025-01-21T10:00:00+01:00``; without an offset: local to ``timezone``);
    each rounded to ``resolution`` (``"ns"`` or ``"us"``). :class:`InputError` for a start or zone
    pandas does not know."""
    per_second = {"ns": 10**9, "us": 10**6}[resolution]
    try:
        start = pd.Timestamp(window_start)
        start = start.tz_localize(timezone) if start.tzinfo is None else start.tz_convert(timezone)
    except (ValueError, TypeError, KeyError) as exc:
        raise InputError(f"window start {window_start!r} in time zone {timezone!r}: {exc}") from None
    ticks = np.round(np.asarray(time, dtype=np.float64) * per_second).astype(np.int64)
    return pd.DatetimeIndex(start + pd.to_timedelta(ticks, unit=resolution))


def iso_texts(stamps: pd.DatetimeIndex) -> np.ndarray:
    """Time-zone-aware ``stamps`` as ISO 8601 texts of their local time to the microsecond, with
    their offset from UTC (``2025-01-21T10:00:09.373829+01:00``)."""
    wall = stamps.tz_localize(None)
    texts = np.datetime_as_string(wall.to_numpy().astype("datetime64[us]"), unit="us")
    minutes = np.asarray((wall - stamps.tz_convert("UTC").tz_localize(None)) // pd.Timedelta(minutes=1))
    offsets, which = np.unique(minutes.astype(np.int64), return_inverse=True)
    names = np.array([f"{'-' if m < 0 else '+'}{abs(m) // 60:02d}:{abs(m) % 60:02d}" for m in offsets.tolist()])
    return np.char.add(texts, names[which]) if len(texts) else texts
