"""The CSV encoding of a trace (the format: :mod:`heliostep.results.trace.files`): one header row, then one
line per row, readable as it is by a spreadsheet, ``pandas.read_csv`` and the ``csv`` module.

Every column's name says its unit (``time [s]``, ``motor.tau [N.m]``); angles are in degrees
(``mechanics.theta_p [deg]``, ``mechanics.omega [deg/s]``), which the reader turns back into radians.
A trace with a window (metadata ``window_start`` and ``timezone``) has a ``local_time`` column after the
time: each row's instant as ISO 8601 local time with its UTC offset. The rest of a run's metadata is in the
``metadata.json`` beside its ``trace.csv`` (:data:`~heliostep.results.trace.format.RUN_METADATA_FILE`).
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.input_files import MAX_CSV_BYTES, MAX_YAML_BYTES, read_input_text
from heliostep.results.trace.format import (
    RUN_METADATA_FILE,
    TIME,
    TRACE_METADATA_KEY,
    iso_texts,
    local_times,
)

__all__ = ["LOCAL_TIME", "CsvLayout", "read_csv_trace", "write_csv_head", "write_csv_rows"]

#: The column of a CSV trace with a window: each row's local time (ISO 8601, with its offset from UTC).
LOCAL_TIME = "local_time"
#: The unit of the time column.
TIME_UNIT = "s"
# pandas < 3 parses floats exactly only when asked; pandas 3 always does (and warns on the option).
_EXACT_FLOATS = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
_NAME_AND_UNIT = re.compile(r"(?P<name>.*\S) \[(?P<unit>[^\[\]]*)\]")


def _swap_angle(unit: str, old: str, new: str) -> str | None:
    """``unit`` with the angle ``old`` (``rad``, ``rad/s``, ...) as ``new``; None when it is no angle."""
    return new + unit[len(old) :] if unit == old or unit.startswith(old + "/") else None


@dataclass(frozen=True)
class CsvLayout:
    """How a trace's columns are written: ``names`` (``time`` first), their ``header`` texts (with the
    :data:`LOCAL_TIME` column after the time when there is a ``window``) and which are in degrees."""

    names: list[str]
    header: list[str]
    degrees: list[bool]
    window: tuple[str, str] | None

    @classmethod
    def of(cls, names: list[str], metadata: Mapping[str, str]) -> CsvLayout:
        """The layout of a trace with columns ``names`` (``time`` first) and ``metadata`` (its
        ``unit.<column>`` keys name the units; ``window_start`` and ``timezone`` the window)."""
        header, degrees = [], []
        for name in names:
            unit = TIME_UNIT if name == TIME else metadata.get(f"unit.{name}", "")
            shown = _swap_angle(unit, "rad", "deg")
            degrees.append(shown is not None)
            header.append(f"{name} [{shown or unit}]" if unit else name)
        start, zone = metadata.get("window_start"), metadata.get("timezone")
        window = (start, zone) if start and zone else None
        if window is not None:
            header.insert(1, LOCAL_TIME)
        return cls(list(names), header, degrees, window)


def write_csv_head(fh: BinaryIO, layout: CsvLayout) -> None:
    """The header line of a CSV trace (names quoted only where they must be)."""
    header = io.StringIO()
    csv.writer(header, lineterminator="\n").writerow(layout.header)
    fh.write(header.getvalue().encode("utf-8"))


def write_csv_rows(fh: BinaryIO, layout: CsvLayout, columns: list[np.ndarray]) -> None:
    """Rows of float64 ``columns`` (in ``layout.names``' order) as CSV lines, by Arrow's CSV writer: each
    value in the shortest form that reads back to the same double (``0.1``, ``0``, ``-0``, ``1e-100``,
    ``inf``; an angle's in degrees), NaN as an empty field, the local time after the time."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    values = [np.degrees(v) if deg else v for v, deg in zip(columns, layout.degrees)]
    arrays = [pa.array(v, type=pa.float64(), from_pandas=True) for v in values]  # NaN: null, empty
    if layout.window is not None:
        stamps = local_times(columns[0], *layout.window, resolution="us")
        arrays.insert(1, pa.array(iso_texts(stamps), type=pa.string()))
    table = pa.Table.from_arrays(arrays, names=[f"c{i}" for i in range(len(arrays))])  # (names: in the head)
    pa_csv.write_csv(table, fh, pa_csv.WriteOptions(include_header=False, quoting_style="none"))


def read_csv_trace(path: Path) -> tuple[pd.DataFrame, dict[str, str]]:
    """The columns of a CSV trace (``time`` and signals, by their names without the unit; angles back in
    radians; no :data:`LOCAL_TIME`) and its metadata: the units of the header, and for a run's ``trace.csv``
    the rest from the ``metadata.json`` beside it. The column types are checked by the caller."""
    text = read_input_text(path, "trace", MAX_CSV_BYTES, "utf-8-sig")  # a byte order mark (Excel) is dropped
    lines = text.replace("\r\n", "\n").replace("\r", "\n").splitlines(keepends=True)
    start = next((number for number, line in enumerate(lines) if line.strip()), None)
    if start is None:
        raise InputError(f"{path}: no header line (expected a {TIME!r} column)")
    sep, decimal = _dialect(lines[start], lines[start + 1 : start + 50])
    try:
        names = [n.strip() for n in next(csv.reader(io.StringIO(lines[start]), delimiter=sep))]
    except csv.Error as exc:
        raise InputError(f"{path}: line {start + 1}: bad header: {exc}") from None
    trailing = len(names) > 1 and names[-1] == ""  # OpenModelica ends every line with the separator
    if trailing:
        names[-1] = "\x00trailing"
    _refuse_duplicates(path, names)
    body = io.StringIO("".join(lines[start:]))
    wanted = [n for n in names if n != LOCAL_TIME]
    try:
        frame = pd.read_csv(body, header=0, names=names, usecols=wanted, sep=sep, decimal=decimal, **_EXACT_FLOATS)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        raise InputError(f"{path}: cannot read as CSV: {exc}") from None
    if trailing:
        if frame[names[-1]].notna().any():
            raise InputError(f"{path}: the header ends with an empty column name but its rows have values there")
        frame = frame.drop(columns=[names[-1]])
    frame, meta = _in_radians(path, frame[[n for n in wanted if n in frame.columns]])
    return frame, {**meta, **_run_metadata(path)}


def _refuse_duplicates(path: Path, names: list[str]) -> None:
    dupes = sorted({c for c in names if names.count(c) > 1})
    if dupes:
        raise InputError(f"{path}: duplicate column(s) {', '.join(map(repr, dupes))}")


def _in_radians(path: Path, frame: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, str]]:
    """``frame`` with each column named without its unit (the unit into the metadata), degrees as radians."""
    data, meta = {}, {}
    for header in frame.columns:
        found = _NAME_AND_UNIT.fullmatch(header)
        name, unit = (found["name"], found["unit"]) if found else (header, None)
        if name == TIME and unit not in (None, TIME_UNIT):
            raise InputError(f"{path}: column {header!r}: the time is in seconds ({TIME} [{TIME_UNIT}])")
        series = frame[header]
        radians = None if unit is None else _swap_angle(unit, "deg", "rad")
        if radians is not None and pd.api.types.is_numeric_dtype(series):
            series, unit = np.radians(series.astype(np.float64)), radians
        data[name] = series
        if unit is not None:
            meta[f"unit.{name}"] = unit
    _refuse_duplicates(path, [(m["name"] if (m := _NAME_AND_UNIT.fullmatch(h)) else h) for h in frame.columns])
    return pd.DataFrame(data), meta


def _run_metadata(path: Path) -> dict[str, str]:
    """The trace metadata a run keeps in the ``metadata.json`` beside its ``trace.csv`` (none for another CSV)."""
    record = path.with_name(RUN_METADATA_FILE)
    if path.name != "trace.csv" or not record.is_file():
        return {}
    try:
        entry = json.loads(read_input_text(record, "run metadata", MAX_YAML_BYTES)).get(TRACE_METADATA_KEY, {})
    except (ValueError, AttributeError) as exc:
        raise InputError(f"{record}: cannot read as the run's metadata (JSON): {exc}") from None
    if not isinstance(entry, dict):
        raise InputError(f"{record}: {TRACE_METADATA_KEY!r} is not a table of the trace's metadata")
    return {str(key): str(value) for key, value in entry.items()}


def _dialect(header: str, rows: list[str]) -> tuple[str, str]:
    """Separator and decimal mark: ``,`` and ``.``, or (Excel in many locales) ``;`` with ``,``
    or ``.`` decimals. ``;`` is taken when the header has a ``;`` and no ``,``."""
    if ";" in header and "," not in header:
        return ";", "," if any("," in row for row in rows) else "."
    return ",", "."
