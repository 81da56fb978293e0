"""The results table: one Parquet part per finished case, merged atomically into ``results.parquet``."""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import uuid
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from heliostep.errors import InputError
from heliostep.results.trace.writer import arrow_path
from heliostep.sweep.certificate import CERTIFIED_FIGURES
from heliostep.sweep.spec import SweepCase, SweepSpec

logger = logging.getLogger(__name__)


#: Figure columns of the table and their dtypes ("Int64": nullable integer).
FIGURE_COLUMNS = {
    "max_tracking_error_deg": "float64",
    "rms_tracking_error_deg": "float64",
    "peak_torque_Nm": "float64",
    "peak_phase_current_A": "float64",
    "electrical_energy_J": "float64",
    "steps_commanded": "Int64",
    "steps_executed": "Int64",
    "missed_steps": "Int64",
    "steps_lost": "Int64",
    "settling_time_max_s": "float64",
    "settling_time_mean_s": "float64",
    "settling_not_settled": "Int64",
    "final_panel_angle_deg": "float64",
    "duration_s": "float64",
    "load_torque_Nm": "float64",
    "tracking_margin": "float64",
    "holding_torque_Nm": "float64",
    "primary_sharing_error_max_deg": "float64",
    "primary_sharing_error_signed_deg": "float64",
    # light on the tube (heliostep.results.light.on_tube) and the drive's trade-offs
    # (heliostep.results.figures.tradeoffs)
    "light_energy_J": "float64",
    "light_energy_ideal_J": "float64",
    "light_energy_reference_J": "float64",
    "light_lost_J": "float64",
    "light_lost_fraction": "float64",
    "light_lost_stepping_J": "float64",
    "light_lost_shared_primary_J": "float64",
    "mean_intercept": "float64",
    "max_transverse_miss_m": "float64",
    "drive_energy_per_day_J": "float64",
    "drive_energy_24h_J": "float64",
    "idle_holding_moment_Nm": "float64",
    "idle_holding_margin": "float64",
}


#: Columns describing a case (from its resolved scenario), with dtypes.
CASE_COLUMNS = {
    "case_id": "string",
    "case_index": "Int64",
    "role": "string",
    "date": "string",
    "day_of_year": "Int64",
    "mirror_index": "Int64",
    "mirror_distance_m": "float64",
    "mirror_axis": "string",
    "motor": "string",
    "mechanics": "string",
    "current_A": "float64",
    "wind_moment_Nm": "float64",
    "overrides": "string",
}


#: Columns about the execution of a case, with dtypes.
RUN_COLUMNS = {
    "status": "string",
    "error_type": "string",
    "error": "string",
    "wall_time_s": "float64",
    "finished_at": "string",
    "run_id": "string",
    "worker": "string",
    "fmu_sha256": "string",
    # how the figures came: "full" (co-simulated), "composed" (from the step family of the case's drive:
    # heliostep.run.step_family) or "certificate" (co-simulated, compared with its composition); "fallback":
    # why a case that could have been composed was co-simulated
    "method": "string",
    "fallback": "string",
    **{f"deviation_{name}": "float64" for name in CERTIFIED_FIGURES},  # a certificate row's (relative; counts: steps)
}


#: Every column the table types itself, with its dtype.
_KNOWN_COLUMNS = {**CASE_COLUMNS, **FIGURE_COLUMNS, **RUN_COLUMNS}

_METADATA_KEY = b"heliostep.sweep"


def default_results_path(spec: SweepSpec) -> Path:
    """``out/<sweep name>/results.parquet`` (relative to the current directory)."""
    return Path("out") / spec.name / "results.parquet"


def _parts_dir(results_path: Path) -> Path:
    return results_path.with_name(results_path.name + ".parts")


def _part_files(results_path: Path) -> list[Path]:
    """The part files not merged yet: one finished case's row each, in Arrow's IPC file format (``.arrow``: read
    far faster than a one-row Parquet file), or ``.parquet`` (a part an earlier heliostep wrote)."""
    parts = _parts_dir(results_path)
    return sorted(p for p in parts.glob("*") if p.suffix in (".arrow", ".parquet")) if parts.is_dir() else []


def _read_part(path: Path) -> pa.Table:
    if path.suffix == ".parquet":
        return pq.read_table(path)
    with pa.OSFile(arrow_path(path), "rb") as source:
        return pa.ipc.open_file(source).read_all()


def _parts_frame(part_files: Sequence[Path]) -> pd.DataFrame | None:
    """The rows of the readable part files in one frame (None: none), joined in Arrow; parts whose columns
    Arrow cannot unite (an axis' values of several types) joined in pandas, where :func:`_normalize` makes
    them text."""
    tables = []
    for part in part_files:
        try:
            tables.append(_read_part(part))
        except (OSError, pa.ArrowException):  # a part being written by a stopped run: its case reruns
            logger.warning("ignoring unreadable part file %s", part)
    if not tables:
        return None
    try:
        return pa.concat_tables(tables, promote_options="permissive").to_pandas()
    except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError):
        return pd.concat([table.to_pandas() for table in tables], ignore_index=True)


def _normalize(table: pd.DataFrame) -> pd.DataFrame:
    """Fixed dtypes for the known columns; axis columns of mixed types become text."""
    table = table.copy()
    for column, dtype in _KNOWN_COLUMNS.items():
        if column not in table:
            table[column] = pd.Series([None] * len(table), dtype=object)
        values = table[column]
        if dtype == "Int64":
            table[column] = pd.array([None if pd.isna(v) else int(v) for v in values], dtype="Int64")
        elif dtype == "float64":
            table[column] = pd.to_numeric(values.astype(object).where(values.notna(), np.nan), errors="coerce").astype(
                "float64"
            )
        else:
            table[column] = pd.array([None if _missing(v) else str(v) for v in values], dtype="string")
    for column in table.columns:
        if column in _KNOWN_COLUMNS or table[column].dtype != object:
            continue
        kinds = {type(v) for v in table[column] if not _missing(v)}
        if len(kinds) > 1 and not kinds <= {int, float}:
            table[column] = pd.array([None if _missing(v) else str(v) for v in table[column]], dtype="string")
    return table[_ordered(table.columns)]


def _ordered(columns) -> list[str]:
    """The table's column order: the case's identity, the axes' and other columns not known, then the known."""
    ordered = [c for c in CASE_COLUMNS if c in ("case_id", "case_index", "role")]
    ordered += [c for c in columns if c not in _KNOWN_COLUMNS]
    return ordered + [c for c in CASE_COLUMNS if c not in ordered] + list(FIGURE_COLUMNS) + list(RUN_COLUMNS)


@functools.cache
def _arrow_types() -> dict[str, pa.DataType]:
    """The Arrow type of each known column's dtype (:func:`_normalize`), as this pandas converts it."""
    sample = pd.DataFrame({dtype: pd.array([None], dtype=dtype) for dtype in ("Int64", "float64", "string")})
    return {field.name: field.type for field in pa.Schema.from_pandas(sample, preserve_index=False)}


def _as_float(value) -> float:
    """A value as :func:`_normalize` makes it in a float column (``pd.to_numeric(errors="coerce")``)."""
    if _missing(value):
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _row_table(row: Mapping) -> pa.Table:
    """One row with :func:`_normalize`'s types and order, built straight in Arrow: a part is written per
    finished case, as often as the workers finish them."""
    arrays, names, types = [], _ordered(row), _arrow_types()
    for name in names:
        value, dtype = row.get(name), _KNOWN_COLUMNS.get(name)
        if dtype == "Int64":
            arrays.append(pa.array([None if value is None or pd.isna(value) else int(value)], types[dtype]))
        elif dtype == "float64":
            arrays.append(pa.array([_as_float(value)], types[dtype], from_pandas=True))  # NaN: null
        elif dtype == "string":
            arrays.append(pa.array([None if _missing(value) else str(value)], types[dtype]))
        else:  # an axis' column: its value's own type, as pandas infers it for one row
            arrays.append(pa.array([value]))
    return pa.Table.from_arrays(arrays, names=names)


def _missing(value) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA


def _write_atomically(table: pd.DataFrame, path: Path, metadata: Mapping | None = None) -> None:
    arrow = pa.Table.from_pandas(_normalize(table), preserve_index=False)
    if metadata:
        arrow = arrow.replace_schema_metadata(
            {**(arrow.schema.metadata or {}), _METADATA_KEY: json.dumps(metadata).encode()}
        )
    _replace_atomically(path, lambda scratch: pq.write_table(arrow, scratch))


def _replace_atomically(path: Path, write: Callable[[str], None]) -> None:
    """``write`` a scratch file beside ``path`` (given its absolute path), then rename it to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    scratch = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        write(arrow_path(scratch))
        os.replace(scratch, path)
    finally:
        scratch.unlink(missing_ok=True)


def _read_parquet(path: Path) -> tuple[pd.DataFrame, dict]:
    try:
        arrow = pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        raise InputError(f"{path}: not a readable results table: {exc}") from None
    raw = (arrow.schema.metadata or {}).get(_METADATA_KEY)
    return arrow.to_pandas(), (json.loads(raw) if raw else {})


def read_results(results_path: str | Path) -> pd.DataFrame:
    """The results of a sweep: the table plus any part files not merged yet.

    Parameters
    ----------
    results_path : str or Path
        The sweep's ``results.parquet``.

    Returns
    -------
    pandas.DataFrame
        One row per case (the latest when a case ran more than once), sorted by
        ``case_index``; ``attrs["sweep"]`` holds the sweep's metadata (name, axes
        columns, ...). Empty when nothing was written yet.
    """
    results_path = Path(results_path)
    frames: list[pd.DataFrame] = []
    metadata: dict = {}
    if results_path.exists():
        table, metadata = _read_parquet(results_path)
        frames.append(table)
    parts = _parts_frame(_part_files(results_path))
    if parts is not None:
        frames.append(parts)
    if not frames:
        return _normalize(pd.DataFrame())
    combined = _normalize(pd.concat([f for f in frames if len(f)] or frames[:1], ignore_index=True))
    combined = combined.sort_values("finished_at", kind="stable").drop_duplicates("case_id", keep="last")
    combined = combined.sort_values("case_index", kind="stable").reset_index(drop=True)
    combined.attrs["sweep"] = metadata
    return combined


def check_results_owner(results_path: str | Path, metadata: Mapping, replace: bool = False) -> None:
    """Refuse to run a sweep into a results table that holds another sweep's rows, unless ``replace``.

    A rerun drops the rows of cases no longer in the sweep; that is the sweep's own business when it is
    the same sweep (its file edited), never a silent loss of another sweep's finished cases.

    Parameters
    ----------
    results_path : str or Path
        The ``results.parquet`` the sweep would write.
    metadata : Mapping
        The new sweep's :func:`heliostep.sweep.sweep_metadata`.
    replace : bool, default False
        Let the new sweep drop the other sweep's rows.

    Raises
    ------
    InputError
        Naming the table, the sweep its rows belong to and the new one.
    """
    results_path = Path(results_path)
    if replace or not results_path.exists():
        return
    recorded = _recorded_metadata(results_path)
    if _same_sweep(recorded, metadata):
        return
    rows = len(read_results(results_path))
    if rows:
        raise InputError(
            f"{results_path}: holds {rows} finished case(s) of sweep {_sweep_label(recorded)}, "
            f"not of this sweep {_sweep_label(metadata)}; give another --out, or --replace to drop those rows"
        )


def _recorded_metadata(path: Path) -> dict:
    """The sweep's metadata of a results table, read from its footer only."""
    try:
        raw = (pq.read_schema(path).metadata or {}).get(_METADATA_KEY)
    except (OSError, pa.ArrowException) as exc:
        raise InputError(f"{path}: not a readable results table: {exc}") from None
    return json.loads(raw) if raw else {}


def _same_sweep(recorded: Mapping, new: Mapping) -> bool:
    """Same name and the same sweep file (its absolute path; the path as given for a table that has none)."""
    if recorded.get("name") != new.get("name"):
        return False
    if recorded.get("file") and new.get("file"):
        return recorded["file"] == new["file"]
    return recorded.get("source") == new.get("source")


def _sweep_label(metadata: Mapping) -> str:
    if not metadata:
        return "(unnamed: the table records no sweep)"
    return f"{metadata.get('name')!r} ({metadata.get('file') or metadata.get('source')})"


def _consolidate(results_path: Path, metadata: Mapping, cases: Sequence[SweepCase] | None = None) -> pd.DataFrame:
    """Merge the part files into the table (atomically), then delete the merged parts.

    With ``cases``, the table keeps only the rows of these cases, with their identity
    and parameter columns (``case_index``, axis values, ...) as these cases give them.
    """
    merged_parts = _part_files(results_path)
    table = read_results(results_path)
    if cases is not None:
        outcome_columns = ["case_id", *FIGURE_COLUMNS, *RUN_COLUMNS]
        identities = pd.DataFrame([case.columns for case in cases], columns=_column_union(cases))
        table = identities.merge(table[outcome_columns], on="case_id", how="inner", validate="one_to_one")
        table = _normalize(table).sort_values("case_index", kind="stable").reset_index(drop=True)
    _write_atomically(table, results_path, metadata)
    for part in merged_parts:
        part.unlink(missing_ok=True)
    table.attrs["sweep"] = dict(metadata)
    return table


def _column_union(cases: Sequence[SweepCase]) -> list[str]:
    return list(dict.fromkeys(column for case in cases for column in case.columns))


def _write_part(row: Mapping, results_path: Path) -> None:
    table = _row_table(row)

    def write(scratch: str) -> None:
        with pa.OSFile(scratch, "wb") as sink, pa.ipc.new_file(sink, table.schema) as writer:
            writer.write_table(table)

    _replace_atomically(_parts_dir(results_path) / f"{row['case_id']}.arrow", write)
