"""A run's trace as the run figures read it: its columns, fetched on demand, and its clock (local time).

Details: ``heliostep.plots.run``.
"""

from __future__ import annotations

import zoneinfo
from collections.abc import Mapping
from pathlib import Path

import matplotlib.dates as mdates
import numpy as np
import pandas as pd

from heliostep.errors import InputError

__all__ = ["TraceClock", "TraceColumns", "step_times"]

#: A window longer than this [s] gets dates on its time axis.
_ONE_DAY = 86400.0


def step_times(trace: pd.DataFrame) -> np.ndarray:
    """Instants at which the sequencer steps: where ``step_index`` changes.

    Parameters
    ----------
    trace : pandas.DataFrame
        Columns ``time`` [s] and ``step_index``.

    Returns
    -------
    numpy.ndarray  [s]
        Time of the first row with the new index (empty without steps or without
        a ``step_index`` column).
    """
    if "step_index" not in trace or "time" not in trace:
        return np.empty(0)
    index = trace["step_index"].to_numpy(dtype=float)
    changed = np.flatnonzero(np.diff(index) != 0.0) + 1
    changed = changed[np.isfinite(index[changed]) & np.isfinite(index[changed - 1])]
    return trace["time"].to_numpy(dtype=float)[changed]


class TraceClock:
    """Maps the trace's time [s from the window start] to the x axis: local clock time."""

    def __init__(self, metadata: Mapping, time: np.ndarray):
        self.start = None
        self.tz = None
        start_text = metadata.get("window_start")
        timezone = metadata.get("timezone")
        if start_text is not None:
            try:
                start = pd.Timestamp(start_text)
            except (TypeError, ValueError) as exc:
                raise InputError(f"metadata window_start {start_text!r} is not a date/time: {exc}") from None
            try:
                tz = zoneinfo.ZoneInfo(timezone) if timezone else None
            except (zoneinfo.ZoneInfoNotFoundError, ValueError):
                raise InputError(f"metadata timezone {timezone!r} is not an IANA name") from None
            if start.tzinfo is None:
                start = start.tz_localize(tz or "UTC")
            self.start = start.tz_convert(tz) if tz is not None else start
            self.tz = self.start.tzinfo
        self.span = float(time[-1] - time[0]) if time.size else 0.0
        self._origin = None if self.start is None else mdates.date2num(self.start.to_pydatetime())

    def x(self, time: np.ndarray) -> np.ndarray:
        """x values (matplotlib dates, or seconds without a window start) of times [s]."""
        return time if self._origin is None else self._origin + time / 86400.0

    def format_axis(self, ax) -> None:
        """Ticks and label of a time axis."""
        if self._origin is None:
            ax.set_xlabel("time from the window start [s]")
            return
        locator = mdates.AutoDateLocator(tz=self.tz, minticks=4, maxticks=9)
        ax.xaxis.set_major_locator(locator)
        if self.span > _ONE_DAY:  # dates on the axis: each day's first tick names it
            ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator, tz=self.tz, show_offset=False))
            ax.set_xlabel(f"local date and time ({self.tz})")
            return
        pattern = "%H:%M:%S" if self.span <= 3600.0 else "%H:%M"
        ax.xaxis.set_major_formatter(mdates.DateFormatter(pattern, tz=self.tz))
        shown = "hh:mm:ss" if pattern == "%H:%M:%S" else "hh:mm"
        ax.set_xlabel(f"local time ({self.tz}) [{shown}]")

    def label(self, time: float) -> str:
        """A trace time as local clock time (or seconds)."""
        if self.start is None:
            return f"t = {time:.4f} s"
        return (self.start + pd.Timedelta(seconds=float(time))).strftime("%H:%M:%S.%f")[:-3]


class TraceColumns:
    """Columns of a trace as float arrays, fetched on demand; FMU columns found by role.

    The trace is a DataFrame or a Parquet trace file; from a file only the columns a figure
    draws are read, and :meth:`release` drops them once it is drawn (a long trace is never
    loaded whole).
    """

    def __init__(self, source: pd.DataFrame | Path, roles: Mapping[str, str]):
        self.roles = dict(roles)
        self._cache: dict[str, np.ndarray] = {}
        if isinstance(source, pd.DataFrame):
            self.frame, self.path = source, None
            self.columns = [str(c) for c in source.columns]
            self.time = source["time"].to_numpy(dtype=float)
        else:
            import pyarrow.parquet as pq

            self.frame, self.path = None, Path(source)
            try:
                self.columns = list(pq.read_schema(self.path).names)
            except Exception as exc:  # pyarrow raises several types for bad files
                raise InputError(f"{self.path}: cannot read as Parquet: {exc}") from None
            if "time" not in self.columns:
                raise InputError(f"{self.path}: trace has no 'time' column")
            self.time = self._read("time")

    def _read(self, column: str) -> np.ndarray:
        if self.frame is not None:
            return self.frame[column].to_numpy(dtype=float)
        import pyarrow.parquet as pq

        # ParquetFile.read takes the name as it is (read_table would split "motor.tau" at the dot)
        return pq.ParquetFile(self.path).read(columns=[column]).column(0).to_numpy().astype(float, copy=False)

    def release(self) -> None:
        """Forget the columns read from a file (a DataFrame's stay: they cost nothing)."""
        if self.path is not None:
            self._cache = {}

    def step_times(self) -> np.ndarray:
        if not self.has("step_index"):
            return np.empty(0)
        return step_times(pd.DataFrame({"time": self.time, "step_index": self["step_index"]}))

    def col(self, role: str) -> str:
        """The column of a role (a name no trace has when the role is absent)."""
        return self.roles.get(role, f"<no {role}>")

    def has(self, *columns: str) -> bool:
        return all(column in self.columns for column in columns)

    def __getitem__(self, column: str) -> np.ndarray:
        if column not in self._cache:
            self._cache[column] = self._read(column)
        return self._cache[column]

    def degrees(self, column: str) -> np.ndarray:
        return np.degrees(self[column])
