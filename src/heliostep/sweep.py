"""Sizing sweeps: many scenario runs on ``dask.distributed``, one Parquet row per case.

A *sweep* names a base scenario and the axes to vary; every combination of axis
values (``combine: product``, the default) or every position along the axes
(``combine: zip``) is one *case*: one :func:`heliostep.run.run_scenario` worth of work,
summarised by its figures (max tracking error, peak torque, ...). See ``docs/sweep.md``.

Sweep file::

    name: smoke                      # optional, default: the file's stem
    base: ../jan21-central.yaml      # relative to the sweep file
    combine: product                 # or zip
    axes:
      day_of_year: [21, 172]         # window.date in the base scenario's year; or "all"
      mirror: [0, 12]                # mirror.index (clears mirror.distance); or "all" (0 .. 12)
      sequencer.current: [5.5, 3.0]  # any dotted scenario key
    overrides: {output.interval: 0.5}  # applied to every case (optional)
    shared_primary: false            # true: add the field's shared primary drive (see heliostep.field)

Shorthand axes: ``day_of_year``, ``mirror``, ``motor`` (``fmus.motor``), ``mechanics``
(``fmus.mechanics``), ``current`` (``sequencer.current``), ``wind_moment``
(``wind.moment``). Numeric axes also take ``{start, stop, step}`` (stop included).

How a sweep runs
----------------
1. :func:`load_sweep` reads the file; :func:`expand_cases` builds and **validates every
   case's scenario** (base + overrides + axis values), so bad input raises
   :class:`~heliostep.errors.InputError` naming the sweep file and key before any case runs.
2. The FMUs are built once, in the client (:func:`heliostep.build.ensure_fmu`), and their
   bytes shipped to the workers as one small Dask task per FMU; each worker writes each
   FMU once into its local folder and the case's scenario points ``fmus.<instance>`` at
   that local copy.
3. Cases run on a local cluster (one single-threaded worker process per core, on
   127.0.0.1) or on an existing scheduler. Each finished case is written at once as a
   one-row Parquet *part* file beside the table (``results.parquet.parts/``); the parts
   are merged into ``results.parquet`` (atomically) every :data:`CONSOLIDATE_EVERY`
   seconds and at the end, so a stopped sweep loses nothing done.
4. A case's id is a hash of its fully resolved scenario; a rerun skips every case that
   already has a row with the same id and the same FMU contents (``ok`` rows, and
   ``failed`` rows unless ``retry_failed``). A case that fails is recorded with its error
   and never stops the sweep.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import datetime as dt
import hashlib
import itertools
import json
import logging
import math
import os
import socket
import sys
import tempfile
import threading
import time as clock
import traceback
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from heliostep.build import ensure_fmu
from heliostep.errors import HeliostepError, InputError
from heliostep.field import primary_sharing_error
from heliostep.fmi import read_fmu
from heliostep.run import RunFailed, run_scenario
from heliostep.scenario import (N_FIELD_MIRRORS, Scenario, load_scenario, read_yaml_file, set_dotted_key,
                                validate_scenario)

__all__ = [
    "CASE_COLUMNS",
    "CASE_STATUSES",
    "CENTRAL_MIRROR",
    "COMBINE_MODES",
    "CONSOLIDATE_EVERY",
    "FIGURE_COLUMNS",
    "ROLES",
    "RUN_COLUMNS",
    "SHORTHAND_AXES",
    "WIND_MARGIN",
    "FmuPayload",
    "SweepAxis",
    "SweepCase",
    "SweepOutcome",
    "SweepSpec",
    "default_results_path",
    "execute_cases",
    "expand_cases",
    "load_sweep",
    "read_results",
    "run_case",
    "run_sweep",
    "summary_figures",
    "sweep_from_scenario",
    "sweep_metadata",
]

logger = logging.getLogger(__name__)

#: How the axes combine into cases.
COMBINE_MODES = ("product", "zip")
#: Status of a case in the results table.
CASE_STATUSES = ("ok", "failed")
#: Shorthand axis name -> the dotted scenario key it sets (day_of_year and mirror are special).
SHORTHAND_AXES = {
    "day_of_year": "window.date",
    "mirror": "mirror.index",
    "motor": "fmus.motor",
    "mechanics": "fmus.mechanics",
    "current": "sequencer.current",
    "wind_moment": "wind.moment",
}
#: Table column of each shorthand axis (a column the table always has).
_SHORTHAND_COLUMNS = {
    "day_of_year": "day_of_year", "mirror": "mirror_index", "motor": "motor",
    "mechanics": "mechanics", "current": "current_A", "wind_moment": "wind_moment_Nm",
}
#: The paper's margin on the simulated peak torque for the wind: required torque = 2 x peak.
WIND_MARGIN = 2.0
#: Seconds between merges of the part files into the results table while a sweep runs.
CONSOLIDATE_EVERY = 30.0
#: Index of the central mirror of the field (distance 0), whose law the shared primary follows.
CENTRAL_MIRROR = N_FIELD_MIRRORS // 2
#: Roles of a case: one mirror's drive, or the field's shared primary drive.
ROLES = ("drive", "shared-primary")
#: Longest error text kept in the table [characters].
MAX_ERROR_CHARS = 4000

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
    "required_torque_Nm": "float64",
    "holding_torque_Nm": "float64",
    "primary_sharing_error_max_deg": "float64",
    "primary_sharing_error_signed_deg": "float64",
}
#: Columns describing a case (from its resolved scenario), with dtypes.
CASE_COLUMNS = {
    "case_id": "string", "case_index": "Int64", "role": "string",
    "date": "string", "day_of_year": "Int64", "mirror_index": "Int64",
    "mirror_distance_m": "float64", "mirror_axis": "string", "motor": "string",
    "mechanics": "string", "current_A": "float64", "wind_moment_Nm": "float64",
    "overrides": "string",
}
#: Columns about the execution of a case, with dtypes.
RUN_COLUMNS = {
    "status": "string", "error_type": "string", "error": "string", "wall_time_s": "float64",
    "finished_at": "string", "run_id": "string", "worker": "string", "fmu_sha256": "string",
}
_SWEEP_KEYS = ("name", "description", "base", "combine", "axes", "overrides", "shared_primary")
_METADATA_KEY = b"heliostep.sweep"


# --------------------------------------------------------------------------- data
@dataclasses.dataclass(frozen=True)
class SweepAxis:
    """One axis of a sweep.

    Attributes
    ----------
    name : str
        As written in the sweep: a shorthand of :data:`SHORTHAND_AXES` or a dotted key.
    values : tuple
        The expanded values ("all" and ranges resolved), in order.
    """

    name: str
    values: tuple

    @property
    def column(self) -> str:
        """The results-table column holding this axis's value."""
        return _SHORTHAND_COLUMNS.get(self.name, self.name)

    def overrides(self, value, year: int) -> tuple[tuple[str, Any], ...]:
        """The (dotted key, value) settings for one value of this axis.

        Parameters
        ----------
        value
            One of :attr:`values`.
        year : int
            Year of the base scenario's window (for ``day_of_year``).
        """
        if self.name == "day_of_year":
            return (("window.date", _date_of_day(year, value)),)
        if self.name == "mirror":
            return (("mirror.distance", None), ("mirror.index", value))
        return ((SHORTHAND_AXES.get(self.name, self.name), value),)


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep (see the module docstring); build it with :func:`load_sweep`.

    Attributes
    ----------
    name : str
    source : str
        The sweep file (or a description), named in error messages.
    base_data : dict
        The base scenario as plain data (its resolved form).
    base_source : str
        The base scenario's file, named in error messages.
    base_folder : Path
        Folder that relative FMU paths of the base scenario resolve against.
    axes : tuple of SweepAxis
    combine : {"product", "zip"}
    overrides : tuple of (str, object)
        (dotted key, value) applied to every case, before the axes.
    shared_primary : bool
        Add, per combination of the other axes, one case of the field's shared primary
        drive (the central mirror's primary axis); needs a ``mirror`` axis.
    description : str or None
    """

    name: str
    source: str
    base_data: dict
    base_source: str
    base_folder: Path
    axes: tuple[SweepAxis, ...]
    combine: str = "product"
    overrides: tuple[tuple[str, Any], ...] = ()
    shared_primary: bool = False
    description: str | None = None


@dataclasses.dataclass(frozen=True)
class SweepCase:
    """One case of a sweep: a validated scenario and its row's identity columns.

    Attributes
    ----------
    case_id : str
        16 hex digits of the SHA-256 of the resolved scenario: stable across reruns.
    index : int
        Position in the sweep's expansion.
    columns : dict
        Identity and parameter columns of the case's row (axis values, date, mirror, ...).
    scenario : dict
        The case's resolved scenario (JSON-able); ``fmus`` holds variant names or
        absolute paths.
    source : str
        Named in the case's error messages.
    folder : str
        The base scenario's folder.
    fmu_sha256 : dict
        FMU instance -> SHA-256 of the FMU file the case runs (set by :func:`execute_cases`).
    """

    case_id: str
    index: int
    columns: dict
    scenario: dict
    source: str
    folder: str
    fmu_sha256: dict = dataclasses.field(default_factory=dict)

    @property
    def label(self) -> str:
        """A short description: the case's override settings."""
        return self.columns.get("overrides") or "(base)"


@dataclasses.dataclass(frozen=True)
class FmuPayload:
    """An FMU file shipped to the workers: its name, content hash and bytes."""

    name: str
    sha256: str
    data: bytes = dataclasses.field(repr=False)


@dataclasses.dataclass
class SweepOutcome:
    """What :func:`run_sweep` / :func:`execute_cases` did.

    Attributes
    ----------
    table : pandas.DataFrame
        The results table (one row per case of the sweep), as written.
    results_path : Path
    executed : int
        Cases run by this call.
    skipped : int
        Cases skipped because the table already held them.
    failed : int
        Cases of the table whose status is "failed".
    """

    table: pd.DataFrame
    results_path: Path
    executed: int
    skipped: int
    failed: int


# --------------------------------------------------------------------------- loading
def load_sweep(path: str | Path) -> SweepSpec:
    """Read and check a sweep file (its cases are built by :func:`expand_cases`).

    Parameters
    ----------
    path : str or Path
        The sweep YAML.

    Returns
    -------
    SweepSpec

    Raises
    ------
    InputError
        Naming the sweep file and key: unreadable file, unknown key, missing base,
        an empty axis, a repeated value, zip axes of different lengths, an invalid
        ``day_of_year`` or ``mirror`` value, or an invalid base scenario.
    """
    path = Path(path)
    source = str(path)
    data = read_yaml_file(path, "sweep")
    if not isinstance(data, dict):
        raise InputError(f"{source}: the top level must be a mapping with keys {', '.join(_SWEEP_KEYS)}")
    unknown = [key for key in data if key not in _SWEEP_KEYS]
    if unknown:
        raise InputError(f"{source}: {unknown[0]}: unknown key; allowed keys: {', '.join(_SWEEP_KEYS)}")
    if not isinstance(data.get("base"), str) or not data["base"].strip():
        raise InputError(f"{source}: base: required: the path of the base scenario (relative to the sweep file)")
    base_path = Path(data["base"]).expanduser()
    if not base_path.is_absolute():
        base_path = path.absolute().parent / base_path
    try:
        base = load_scenario(base_path)
    except InputError as exc:
        raise InputError(f"{source}: base: {exc}") from None
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name.strip() or any(c in name for c in "/\\") or name.startswith("."):
        raise InputError(f"{source}: name: expected a non-empty name usable as a folder name "
                         f"(no '/', not starting with '.'), got {name!r}")
    return _make_spec(
        name=name.strip(), source=source, base=base, base_source=str(base_path),
        axes=data.get("axes"), combine=data.get("combine", "product"),
        overrides=data.get("overrides"), shared_primary=data.get("shared_primary", False),
        description=data.get("description"))


def sweep_from_scenario(scenario: Scenario, axes: Mapping[str, Any], *, combine: str = "product",
                        overrides: Mapping[str, Any] | None = None, shared_primary: bool = False,
                        name: str | None = None, source: str | None = None) -> SweepSpec:
    """A sweep over an in-memory scenario (the Python form of a sweep file).

    Parameters
    ----------
    scenario : Scenario
        The base scenario.
    axes : Mapping
        Axis name (shorthand or dotted key) -> values (a list, "all" or ``{start, stop, step}``).
    combine : {"product", "zip"}, default "product"
    overrides : Mapping, optional
        Dotted key -> value, applied to every case.
    shared_primary : bool, default False
        See :class:`SweepSpec`.
    name : str, optional
        Default: the scenario's name.
    source : str, optional
        Named in error messages; default ``"sweep of <scenario name>"``.

    Returns
    -------
    SweepSpec
    """
    label = source or f"sweep of {scenario.name}"
    return _make_spec(name=name or scenario.name, source=label, base=scenario,
                      base_source=f"scenario {scenario.name}", axes=axes, combine=combine,
                      overrides=overrides, shared_primary=shared_primary, description=None)


def _make_spec(*, name, source, base: Scenario, base_source, axes, combine, overrides,
               shared_primary, description) -> SweepSpec:
    if combine not in COMBINE_MODES:
        raise InputError(f"{source}: combine: expected one of {', '.join(COMBINE_MODES)}, got {combine!r}")
    if not isinstance(shared_primary, bool):
        raise InputError(f"{source}: shared_primary: expected true or false, got {shared_primary!r}")
    if description is not None and not isinstance(description, str):
        raise InputError(f"{source}: description: expected a string, got {description!r}")
    if overrides is None:
        overrides = {}
    if not isinstance(overrides, Mapping):
        raise InputError(f"{source}: overrides: expected a mapping of dotted scenario keys to values, "
                         f"e.g. {{output.interval: 0.5}}, got {overrides!r}")
    common = tuple((_check_key(key, f"{source}: overrides"), value) for key, value in overrides.items())
    base_data = base.resolved_dict()
    base_data["fmus"] = {instance: str(base.fmu_reference(instance)) for instance in base.fmus}
    spec = SweepSpec(name=name, source=source, base_data=base_data, base_source=base_source,
                     base_folder=base.folder, axes=(), combine=combine, overrides=common,
                     shared_primary=shared_primary, description=description)
    year = _validated(spec, (), f"{source}: overrides").window.date.year

    if not isinstance(axes, Mapping) or not axes:
        raise InputError(f"{source}: axes: expected a mapping of at least one axis (e.g. "
                         f"day_of_year: [21, 172]), got {axes!r}")
    parsed = tuple(SweepAxis(name=_check_key(axis_name, f"{source}: axes"),
                             values=_axis_values(axis_name, raw, year, f"{source}: axes.{axis_name}"))
                   for axis_name, raw in axes.items())
    owner = {}
    for axis in parsed:
        for key, _ in axis.overrides(axis.values[0], year):
            if key in owner and key != "mirror.distance":
                raise InputError(f"{source}: axes.{axis.name}: sets {key}, as axes.{owner[key]} does")
            owner.setdefault(key, axis.name)
    if combine == "zip":
        lengths = {axis.name: len(axis.values) for axis in parsed}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{axis_name} has {n}" for axis_name, n in lengths.items())
            raise InputError(f"{source}: axes: combine: zip needs axes of equal length; {listed} values")
    if shared_primary and "mirror" not in [axis.name for axis in parsed]:
        raise InputError(f"{source}: shared_primary: needs a 'mirror' axis (e.g. mirror: all)")
    return dataclasses.replace(spec, axes=parsed)


def _check_key(key, where: str) -> str:
    if not isinstance(key, str) or not all(part.strip() for part in key.split(".")) or key != key.strip():
        raise InputError(f"{where}: {key!r}: expected a shorthand ({', '.join(SHORTHAND_AXES)}) or a "
                         f"dotted scenario key such as 'sequencer.current'")
    return key


def _axis_hint(name: str) -> str:
    if name == "mirror.index":
        return " (to sweep the field's mirrors use the 'mirror' axis, which also clears mirror.distance)"
    if name == "window.date":
        return " (or use the 'day_of_year' axis)"
    return ""


def _axis_values(name: str, raw, year: int, where: str) -> tuple:
    """Expand one axis's values: a list, "all" (day_of_year, mirror) or {start, stop, step}."""
    if isinstance(raw, str) and raw.strip().lower() == "all":
        if name == "mirror":
            return tuple(range(N_FIELD_MIRRORS))
        if name == "day_of_year":
            return tuple(range(1, _days_in_year(year) + 1))
        raise InputError(f"{where}: 'all' is only for the day_of_year and mirror axes")
    if isinstance(raw, Mapping):
        values = _range_values(raw, where)
    elif isinstance(raw, (list, tuple)):
        values = tuple(raw)
    else:
        raise InputError(f"{where}: expected a list of values, 'all' (day_of_year, mirror) or "
                         f"{{start, stop, step}}, got {raw!r}")
    if not values:
        raise InputError(f"{where}: the axis is empty; give at least one value")
    seen = set()
    for value in values:
        if _show(value) in seen:
            raise InputError(f"{where}: the value {value!r} is repeated")
        seen.add(_show(value))
    if name == "day_of_year":
        days = _days_in_year(year)
        for value in values:
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= days:
                raise InputError(f"{where}: {value!r}: expected a day of year, an integer from 1 to {days} "
                                 f"(the base scenario's year is {year})")
    if name == "mirror":
        for value in values:
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < N_FIELD_MIRRORS:
                raise InputError(f"{where}: {value!r}: expected a mirror index, an integer from 0 to "
                                 f"{N_FIELD_MIRRORS - 1} ({CENTRAL_MIRROR} is the central mirror), or 'all'")
    return values


def _range_values(raw: Mapping, where: str) -> tuple:
    if set(raw) - {"start", "stop", "step"} or not {"start", "stop"} <= set(raw):
        raise InputError(f"{where}: a range is {{start, stop, step}} (step optional, default 1), got {dict(raw)!r}")
    start, stop, step = raw["start"], raw["stop"], raw.get("step", 1)
    for key, value in (("start", start), ("stop", stop), ("step", step)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"{where}.{key}: expected a number, got {value!r}")
    if step <= 0:
        raise InputError(f"{where}.step: expected a number > 0, got {step!r}")
    if stop < start:
        raise InputError(f"{where}: stop ({stop}) is before start ({start})")
    count = int(math.floor((stop - start) / step + 1e-9)) + 1
    if all(isinstance(v, int) for v in (start, stop, step)):
        return tuple(start + k * step for k in range(count))
    return tuple(float(np.round(start + k * step, 12)) for k in range(count))


def _days_in_year(year: int) -> int:
    return 366 if (year % 4 == 0 and year % 100 != 0) or year % 400 == 0 else 365


def _date_of_day(year: int, day_of_year: int) -> dt.date:
    return dt.date(year, 1, 1) + dt.timedelta(days=day_of_year - 1)


def _set_dotted(data: dict, key: str, value, where: str) -> None:
    set_dotted_key(data, key.split("."), copy.deepcopy(value), where)


def _scenario_data(spec: SweepSpec, settings: Iterable[tuple[str, Any]], where: str) -> dict:
    data = copy.deepcopy(spec.base_data)
    for key, value in (*spec.overrides, *settings):
        _set_dotted(data, key, value, where)
    return data


def _validated(spec: SweepSpec, settings: Sequence[tuple[str, Any]], where: str, hint: str = "") -> Scenario:
    """The base scenario with the sweep's and ``settings``' overrides, validated."""
    data = _scenario_data(spec, settings, where)
    shown = ", ".join(f"{key}={_show(value)}" for key, value in settings)
    try:
        return validate_scenario(data, source=f"{spec.base_source}{' with ' + shown if shown else ''}",
                                 folder=spec.base_folder)
    except InputError as exc:
        raise InputError(f"{where}: gives an invalid scenario{hint}:\n{exc}") from None


def _show(value) -> str:
    if isinstance(value, (dt.date, dt.time)):
        return value.isoformat()
    return json.dumps(value, default=str)


# --------------------------------------------------------------------------- cases
def expand_cases(spec: SweepSpec) -> list[SweepCase]:
    """All cases of a sweep, each with its scenario validated.

    Parameters
    ----------
    spec : SweepSpec

    Returns
    -------
    list of SweepCase
        In expansion order (``product``: the first axis varies slowest), then the shared
        primary cases when ``spec.shared_primary``.

    Raises
    ------
    InputError
        When a case's scenario is invalid (naming the sweep file and the case's
        settings), or when two cases are the same scenario.
    """
    year = _validated(spec, (), f"{spec.source}: overrides").window.date.year
    if spec.combine == "zip":
        combinations = list(zip(*(axis.values for axis in spec.axes)))
    else:
        combinations = list(itertools.product(*(axis.values for axis in spec.axes)))
    cases = []
    for values in combinations:
        cases.append(_make_case(spec, year, dict(zip(spec.axes, values)), len(cases), "drive"))
    if spec.shared_primary:
        others = [axis for axis in spec.axes if axis.name != "mirror"]
        seen = set()
        for values in combinations:
            chosen = {axis: value for axis, value in zip(spec.axes, values) if axis.name != "mirror"}
            key = json.dumps([_show(chosen[axis]) for axis in others])
            if key not in seen:
                seen.add(key)
                cases.append(_make_case(spec, year, chosen, len(cases), "shared-primary"))
    first_of = {}
    for case in cases:
        if case.case_id in first_of:
            other = first_of[case.case_id]
            raise InputError(f"{spec.source}: axes: cases {other.index} ({other.label}) and {case.index} "
                             f"({case.label}) are the same scenario")
        first_of[case.case_id] = case
    return cases


def _make_case(spec: SweepSpec, year: int, chosen: Mapping[SweepAxis, Any], index: int, role: str) -> SweepCase:
    """One validated case: the axis values ``chosen`` on the base, as a drive or the shared primary."""
    if role not in ROLES:
        raise ValueError(f"role must be one of {ROLES}, got {role!r}")
    settings = [setting for axis, value in chosen.items() for setting in axis.overrides(value, year)]
    if role == "shared-primary":
        settings += [("mirror.distance", None), ("mirror.index", CENTRAL_MIRROR), ("mirror.axis", "primary")]
    shown = ", ".join(f"{axis.name}={_show(value)}" for axis, value in chosen.items())
    if role == "shared-primary":
        shown += " (shared primary)"
    try:
        scenario = _validated(spec, settings, f"{spec.source}: case {index} ({shown})")
    except InputError:
        for axis, value in chosen.items():  # name the axis when its value alone is invalid
            _validated(spec, axis.overrides(value, year), f"{spec.source}: axes.{axis.name}: {_show(value)}",
                       hint=_axis_hint(axis.name))
        raise
    resolved = scenario.resolved_dict()
    resolved["fmus"] = {instance: str(scenario.fmu_reference(instance)) for instance in scenario.fmus}
    case_id = hashlib.sha256(json.dumps(resolved, sort_keys=True).encode()).hexdigest()[:16]
    mirror = scenario.mirror
    columns = {
        "case_id": case_id, "case_index": index, "role": role,
        **{axis.column: _table_value(value) for axis, value in chosen.items()},
        "date": scenario.window.date.isoformat(), "day_of_year": scenario.window.date.timetuple().tm_yday,
        "mirror_index": mirror.index, "mirror_distance_m": float(mirror.mirror_distance),
        "mirror_axis": mirror.axis, "motor": scenario.fmus.get("motor"),
        "mechanics": scenario.fmus.get("mechanics"), "current_A": scenario.sequencer.current,
        "wind_moment_Nm": scenario.wind.moment,
        "overrides": ", ".join(f"{key}={_show(value)}" for key, value in (*spec.overrides, *settings)),
    }
    return SweepCase(case_id=case_id, index=index, columns=columns, scenario=resolved,
                     source=f"{spec.source}: case {index} ({shown})", folder=str(spec.base_folder))


def _table_value(value):
    """An axis value as a table cell: scalars as they are, dates as ISO text, the rest as JSON."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return _show(value)


# --------------------------------------------------------------------------- one case (on a worker)
_LOCAL_FMUS: dict[str, Path] = {}
_LOCAL_FMUS_LOCK = threading.Lock()


def _local_fmu_folder() -> Path:
    try:
        from distributed import get_worker

        return Path(get_worker().local_directory) / "heliostep-fmus"
    except (ImportError, ValueError):  # not on a Dask worker
        return Path(tempfile.gettempdir()) / f"heliostep-fmus-{os.getpid()}"


def _local_fmu(payload: FmuPayload) -> Path:
    """The worker-local copy of a shipped FMU, written once per worker process."""
    with _LOCAL_FMUS_LOCK:
        path = _LOCAL_FMUS.get(payload.sha256)
        if path is not None and path.is_file():
            return path
        if hashlib.sha256(payload.data).hexdigest() != payload.sha256:
            raise RuntimeError(f"the shipped FMU {payload.name} is corrupt (SHA-256 mismatch)")
        folder = _local_fmu_folder() / payload.sha256[:16]
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / payload.name
        scratch = folder / f".{payload.name}.{os.getpid()}.{threading.get_ident()}.tmp"
        scratch.write_bytes(payload.data)
        os.replace(scratch, path)
        _LOCAL_FMUS[payload.sha256] = path
        return path


def _fmu_payload(payload: FmuPayload) -> FmuPayload:
    """The Dask task that carries an FMU's bytes (its data lives in the task, so it can be recomputed)."""
    return payload


def summary_figures(summary: Mapping) -> dict:
    """The table's figure columns from a run summary (``settling_time_s`` flattened).

    Parameters
    ----------
    summary : Mapping
        :attr:`heliostep.run.RunResult.summary`.

    Returns
    -------
    dict
        The summary keys of :data:`FIGURE_COLUMNS` (None when missing), with
        ``settling_time_s`` as ``settling_time_max_s``, ``settling_time_mean_s`` and
        ``settling_not_settled``, and ``required_torque_Nm`` = :data:`WIND_MARGIN` x peak torque [N.m].
    """
    figures = {name: summary.get(name) for name in FIGURE_COLUMNS
               if name not in ("settling_time_max_s", "settling_time_mean_s", "settling_not_settled",
                               "required_torque_Nm", "holding_torque_Nm", "primary_sharing_error_max_deg",
                               "primary_sharing_error_signed_deg")}
    settling = summary.get("settling_time_s") or {}
    figures["settling_time_max_s"] = settling.get("max")
    figures["settling_time_mean_s"] = settling.get("mean")
    figures["settling_not_settled"] = settling.get("not_settled")
    peak = summary.get("peak_torque_Nm")
    figures["required_torque_Nm"] = None if peak is None else WIND_MARGIN * peak
    return figures


def _holding_torque(scenario: Scenario, motor_fmu: Path | None) -> float | None:
    """k_e x I [N.m]: the motor's torque constant (parameter or FMU default) times the phase current."""
    k_e = scenario.parameters.get("motor", {}).get("k_e")
    if k_e is None and motor_fmu is not None:
        variable = read_fmu(motor_fmu).variables.get("k_e")
        k_e = None if variable is None else variable.start
    return None if k_e is None else float(k_e) * scenario.sequencer.current


def _error_text(exc: BaseException) -> str:
    text = f"{exc}" or repr(exc)
    if not isinstance(exc, HeliostepError):
        text += "\n" + "".join(traceback.format_exception(exc)[-6:])
    return text[:MAX_ERROR_CHARS]


def run_case(case: SweepCase, payloads: Mapping[str, FmuPayload], run_id: str = "") -> dict:
    """Run one case (on a Dask worker or in-process) and return its table row.

    Never raises for a failing case: an :class:`~heliostep.errors.InputError`, a
    :class:`~heliostep.run.RunFailed` or any other exception gives ``status`` "failed"
    with ``error_type`` and ``error``.

    Parameters
    ----------
    case : SweepCase
        With ``fmu_sha256`` set.
    payloads : Mapping
        SHA-256 -> :class:`FmuPayload` of (at least) the case's FMUs.
    run_id : str, default ""
        Id of the sweep invocation, stored in the row.

    Returns
    -------
    dict
        The case's columns, figures (:data:`FIGURE_COLUMNS`) and run columns
        (:data:`RUN_COLUMNS`; ``wall_time_s`` [s], ``finished_at`` UTC ISO time).
    """
    started = clock.perf_counter()
    row = {**case.columns, **dict.fromkeys(FIGURE_COLUMNS), "status": "ok", "error_type": None, "error": None}
    scenario = None
    try:
        data = copy.deepcopy(case.scenario)
        local = {instance: _local_fmu(payloads[sha]) for instance, sha in case.fmu_sha256.items()}
        data["fmus"] = {instance: str(path) for instance, path in local.items()}
        scenario = validate_scenario(data, source=case.source, folder=case.folder)
        result = run_scenario(scenario)
        row.update(summary_figures(result.summary))
        row["holding_torque_Nm"] = _holding_torque(scenario, local.get("motor"))
    except RunFailed as exc:
        row.update(status="failed", error_type=type(exc).__name__, error=_error_text(exc))
    except Exception as exc:  # noqa: BLE001 - a failing case is recorded, never fatal
        row.update(status="failed", error_type=type(exc).__name__, error=_error_text(exc))
    if scenario is not None:
        try:
            row.update(primary_sharing_error(scenario))
        except Exception as exc:  # noqa: BLE001
            logger.warning("primary sharing error of case %s: %s", case.case_id, exc)
    row.update(wall_time_s=clock.perf_counter() - started, finished_at=_now(), run_id=run_id,
               worker=f"{socket.gethostname()}:{os.getpid()}", fmu_sha256=_fmu_key(case.fmu_sha256))
    return row


def _now() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="microseconds")


def _fmu_key(fmu_sha256: Mapping[str, str]) -> str:
    return json.dumps(dict(sorted(fmu_sha256.items())))


def _lost_case_row(case: SweepCase, exc: BaseException, run_id: str) -> dict:
    """The row of a case whose task itself failed (e.g. its workers kept dying)."""
    return {**case.columns, **dict.fromkeys(FIGURE_COLUMNS), "status": "failed",
            "error_type": type(exc).__name__, "error": _error_text(exc), "wall_time_s": None,
            "finished_at": _now(), "run_id": run_id, "worker": None, "fmu_sha256": _fmu_key(case.fmu_sha256)}


# --------------------------------------------------------------------------- the table
def default_results_path(spec: SweepSpec) -> Path:
    """``out/<sweep name>/results.parquet`` (relative to the current directory)."""
    return Path("out") / spec.name / "results.parquet"


def _parts_dir(results_path: Path) -> Path:
    return results_path.with_name(results_path.name + ".parts")


def _normalize(table: pd.DataFrame) -> pd.DataFrame:
    """Fixed dtypes for the known columns; axis columns of mixed types become text."""
    known = {**CASE_COLUMNS, **FIGURE_COLUMNS, **RUN_COLUMNS}
    table = table.copy()
    for column, dtype in known.items():
        if column not in table:
            table[column] = pd.Series([None] * len(table), dtype=object)
        values = table[column]
        if dtype == "Int64":
            table[column] = pd.array([None if pd.isna(v) else int(v) for v in values], dtype="Int64")
        elif dtype == "float64":
            table[column] = pd.to_numeric(values.astype(object).where(values.notna(), np.nan),
                                          errors="coerce").astype("float64")
        else:
            table[column] = pd.array([None if _missing(v) else str(v) for v in values], dtype="string")
    for column in table.columns:
        if column in known or table[column].dtype != object:
            continue
        kinds = {type(v) for v in table[column] if not _missing(v)}
        if len(kinds) > 1 and not kinds <= {int, float}:
            table[column] = pd.array([None if _missing(v) else str(v) for v in table[column]], dtype="string")
    ordered = [c for c in CASE_COLUMNS if c in ("case_id", "case_index", "role")]
    ordered += [c for c in table.columns if c not in known]
    ordered += [c for c in CASE_COLUMNS if c not in ordered] + list(FIGURE_COLUMNS) + list(RUN_COLUMNS)
    return table[ordered]


def _missing(value) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA


def _write_atomically(table: pd.DataFrame, path: Path, metadata: Mapping | None = None) -> None:
    arrow = pa.Table.from_pandas(_normalize(table), preserve_index=False)
    if metadata:
        arrow = arrow.replace_schema_metadata({**(arrow.schema.metadata or {}),
                                               _METADATA_KEY: json.dumps(metadata).encode()})
    path.parent.mkdir(parents=True, exist_ok=True)
    scratch = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        pq.write_table(arrow, scratch)
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
    frames, metadata = [], {}
    if results_path.exists():
        table, metadata = _read_parquet(results_path)
        frames.append(table)
    parts = _parts_dir(results_path)
    part_files = sorted(parts.glob("*.parquet")) if parts.is_dir() else []
    for part in part_files:
        try:
            frames.append(_read_parquet(part)[0])
        except InputError:  # a part being written by a stopped run: its case reruns
            logger.warning("ignoring unreadable part file %s", part)
    if not frames:
        return _normalize(pd.DataFrame())
    combined = _normalize(pd.concat([f for f in frames if len(f)] or frames[:1], ignore_index=True))
    combined = combined.sort_values("finished_at", kind="stable").drop_duplicates("case_id", keep="last")
    combined = combined.sort_values("case_index", kind="stable").reset_index(drop=True)
    combined.attrs["sweep"] = metadata
    return combined


def _consolidate(results_path: Path, metadata: Mapping, cases: Sequence[SweepCase] | None = None) -> pd.DataFrame:
    """Merge the part files into the table (atomically), then delete the merged parts.

    With ``cases``, the table keeps only the rows of these cases, with their identity
    and parameter columns (``case_index``, axis values, ...) as these cases give them.
    """
    parts = _parts_dir(results_path)
    merged_parts = sorted(parts.glob("*.parquet")) if parts.is_dir() else []
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
    _write_atomically(pd.DataFrame([row]), _parts_dir(results_path) / f"{row['case_id']}.parquet")


# --------------------------------------------------------------------------- the cluster
def _worker_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _probe_scheduler(address: str, timeout: float) -> None:
    """Fail at once (InputError) when a tcp:// scheduler address refuses connections."""
    from distributed.comm import parse_address
    from distributed.comm.addressing import parse_host_port
    from distributed.comm.registry import backends

    try:
        scheme, location = parse_address(address, strict=True)
        if scheme not in backends:
            raise ValueError(f"unknown scheme {scheme!r}; known: {', '.join(sorted(backends))}")
        host, port = parse_host_port(location) if scheme == "tcp" else (None, None)
    except ValueError as exc:
        raise InputError(f"scheduler {address!r}: expected an address such as tcp://HOST:8786 ({exc})") from None
    if scheme != "tcp":
        return
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise InputError(f"cannot reach the Dask scheduler at {address} ({exc.strerror or exc}); start one "
                         f"with 'dask scheduler' or leave out --scheduler to run on a local cluster") from None


@contextlib.contextmanager
def _dask_client(client=None, scheduler: str | None = None, n_workers: int | None = None,
                 connect_timeout: float = 5.0) -> Iterator:
    """A Dask client: the one given, one connected to ``scheduler``, or one on a new local cluster."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler:
        _probe_scheduler(scheduler, connect_timeout)
        try:
            connected = Client(scheduler, timeout=connect_timeout)
        except ValueError as exc:
            raise InputError(f"scheduler {scheduler!r}: not a usable Dask address ({exc})") from None
        except Exception as exc:  # noqa: BLE001 - timeouts, refusals, a non-Dask server answering
            raise InputError(f"cannot connect to a Dask scheduler at {scheduler} within {connect_timeout:g} s "
                             f"({type(exc).__name__}: {str(exc)[:200]}); start one with 'dask scheduler' or "
                             f"leave out --scheduler to run on a local cluster") from None
        with connected:
            yield connected
        return
    workers = n_workers or _worker_count()
    if workers < 1:
        raise InputError(f"n_workers must be >= 1, got {workers}")
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=":0", silence_logs=logging.ERROR) as cluster, Client(cluster) as local:
        yield local


def _progress_bar(total: int, enabled: bool):
    from tqdm import tqdm

    quiet = not enabled or not sys.stderr.isatty() or bool(os.environ.get("CI"))
    return tqdm(total=total, desc="cases", unit="case", disable=quiet, file=sys.stderr, mininterval=0.5)


# --------------------------------------------------------------------------- running
def _ship_fmus(cases: Sequence[SweepCase]) -> tuple[list[SweepCase], dict[str, FmuPayload]]:
    """Build (or find) every FMU the cases use, once, and read their bytes."""
    paths: dict[str, Path] = {}
    for case in cases:
        for instance, reference in case.scenario["fmus"].items():
            if reference not in paths:
                try:
                    paths[reference] = Path(ensure_fmu(reference))
                except InputError as exc:
                    raise InputError(f"{case.source}: fmus.{instance}: {exc}") from None
    payloads, sha_of = {}, {}
    for reference, path in paths.items():
        data = path.read_bytes()
        sha = hashlib.sha256(data).hexdigest()
        payloads[sha] = FmuPayload(name=path.name, sha256=sha, data=data)
        sha_of[reference] = sha
    shipped = [dataclasses.replace(case, fmu_sha256={instance: sha_of[reference]
                                                     for instance, reference in case.scenario["fmus"].items()})
               for case in cases]
    return shipped, payloads


def execute_cases(cases: Sequence[SweepCase], results_path: str | Path, *, client=None,
                  scheduler: str | None = None, n_workers: int | None = None, connect_timeout: float = 5.0,
                  retry_failed: bool = False, progress: bool = False,
                  on_result: Callable[[dict], None] | None = None,
                  metadata: Mapping | None = None) -> SweepOutcome:
    """Run the cases not yet in the results table on Dask, writing each row as it finishes.

    Parameters
    ----------
    cases : sequence of SweepCase
        From :func:`expand_cases` (validated).
    results_path : str or Path
        The Parquet table; its part files go to ``<results_path>.parts/``.
    client : distributed.Client, optional
        Use this client (and its cluster) as it is.
    scheduler : str, optional
        Else connect to this scheduler (``tcp://HOST:PORT``); else start a local cluster.
    n_workers : int, optional
        Workers of the local cluster; default: the cores of this machine.
    connect_timeout : float, default 5  [s]
        How long to try reaching ``scheduler``.
    retry_failed : bool, default False
        Run again the cases whose row says "failed" (they are skipped otherwise).
    progress : bool, default False
        Show a progress bar (cases done / failed / remaining) when stderr is a terminal
        and ``CI`` is not set.
    on_result : callable, optional
        Called in the client with each finished case's row.
    metadata : Mapping, optional
        Stored in the table's Parquet metadata (``heliostep.sweep``).

    Returns
    -------
    SweepOutcome

    Raises
    ------
    InputError
        An FMU that cannot be built or found, or an unreachable scheduler (before any case runs).
    """
    results_path = Path(results_path)
    metadata = dict(metadata or {})
    cases, payloads = _ship_fmus(cases)
    if client is None and scheduler:
        _probe_scheduler(scheduler, connect_timeout)
    table = _consolidate(results_path, metadata) if results_path.exists() or _parts_dir(results_path).is_dir() \
        else _normalize(pd.DataFrame())
    done_statuses = {"ok"} if retry_failed else {"ok", "failed"}
    finished = {row.case_id: row for row in table.itertuples(index=False)
                if row.status in done_statuses}
    to_run = [case for case in cases
              if case.case_id not in finished or finished[case.case_id].fmu_sha256 != _fmu_key(case.fmu_sha256)]
    executed = 0
    run_id = uuid.uuid4().hex[:12]
    try:
        if to_run:
            executed = _run_on_dask(to_run, payloads, results_path, metadata, run_id, client=client,
                                    scheduler=scheduler, n_workers=n_workers, connect_timeout=connect_timeout,
                                    progress=progress, on_result=on_result)
    finally:
        if results_path.exists() or _parts_dir(results_path).is_dir():
            table = _consolidate(results_path, metadata, cases=cases)
    failed = int((table["status"] == "failed").sum())
    return SweepOutcome(table=table, results_path=results_path, executed=executed,
                        skipped=len(cases) - len(to_run), failed=failed)


def _run_on_dask(cases: Sequence[SweepCase], payloads: Mapping[str, FmuPayload], results_path: Path,
                 metadata: Mapping, run_id: str, *, client, scheduler, n_workers, connect_timeout,
                 progress, on_result) -> int:
    from distributed import as_completed

    with _dask_client(client, scheduler, n_workers, connect_timeout) as dask_client:
        shipped = {sha: dask_client.submit(_fmu_payload, payload, key=f"heliostep-fmu-{sha[:16]}-{run_id}",
                                           pure=False)
                   for sha, payload in payloads.items()
                   if any(sha in case.fmu_sha256.values() for case in cases)}
        futures = {}
        for case in cases:
            needed = {sha: shipped[sha] for sha in set(case.fmu_sha256.values())}
            future = dask_client.submit(run_case, case, needed, run_id, pure=False,
                                        key=f"heliostep-case-{case.case_id}-{run_id}")
            futures[future] = case
        done = failed = 0
        last_merge = clock.monotonic()
        with _progress_bar(len(cases), progress) as bar:
            for future in as_completed(futures):
                case = futures.pop(future)
                try:
                    row = future.result()
                except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: record, go on
                    row = _lost_case_row(case, exc, run_id)
                future.release()
                _write_part(row, results_path)
                done += 1
                failed += row["status"] == "failed"
                bar.set_postfix(done=done, failed=failed, remaining=len(cases) - done, refresh=False)
                bar.update(1)
                if on_result is not None:
                    on_result(row)
                if clock.monotonic() - last_merge > CONSOLIDATE_EVERY:
                    _consolidate(results_path, metadata)
                    last_merge = clock.monotonic()
        for future in shipped.values():
            future.release()
    return done


def run_sweep(sweep: SweepSpec | str | Path, results_path: str | Path | None = None, *, client=None,
              scheduler: str | None = None, n_workers: int | None = None, connect_timeout: float = 5.0,
              retry_failed: bool = False, progress: bool = False,
              on_result: Callable[[dict], None] | None = None) -> SweepOutcome:
    """Run a sweep: validate every case, then run the unfinished ones on Dask.

    Parameters
    ----------
    sweep : SweepSpec or str or Path
        A sweep, or the path of a sweep file.
    results_path : str or Path, optional
        Default :func:`default_results_path`.
    client, scheduler, n_workers, connect_timeout, retry_failed, progress, on_result
        See :func:`execute_cases`.

    Returns
    -------
    SweepOutcome

    Raises
    ------
    InputError
        Bad sweep or case scenario, unknown FMU, unreachable scheduler: before any case runs.
    """
    spec = sweep if isinstance(sweep, SweepSpec) else load_sweep(sweep)
    cases = expand_cases(spec)
    path = Path(results_path) if results_path is not None else default_results_path(spec)
    return execute_cases(cases, path, client=client, scheduler=scheduler, n_workers=n_workers,
                         connect_timeout=connect_timeout, retry_failed=retry_failed, progress=progress,
                         on_result=on_result, metadata=sweep_metadata(spec))


def sweep_metadata(spec: SweepSpec) -> dict:
    """What the table's Parquet metadata records about the sweep (name, source, axes, combine)."""
    return {"name": spec.name, "source": spec.source, "base": spec.base_source, "combine": spec.combine,
            "axes": {axis.name: axis.column for axis in spec.axes}, "shared_primary": spec.shared_primary,
            "overrides": {key: _show(value) for key, value in spec.overrides}}
