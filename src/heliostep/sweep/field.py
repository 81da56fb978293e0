"""The 13-mirror field: one shared primary drive, one secondary drive per mirror.

Details: docs/sweep.md, ``heliostep.sweep.field``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.errors import InputError
from heliostep.scenario import Scenario, load_scenario
from heliostep.solar import DEFAULT_MIRROR_SPACING, N_FIELD_MIRRORS, field_distances, sharing_errors, sharing_figures
from heliostep.sweep.cluster import execute_cases
from heliostep.sweep.spec import SweepSpec, expand_cases, sweep_from_scenario, sweep_metadata
from heliostep.sweep.worker import window_sun_times

__all__ = ["FIELD_COLUMNS", "field_sharing_errors", "run_field"]

#: Columns of :func:`run_field`'s table shown first.
FIELD_COLUMNS = (
    "role",
    "mirror_index",
    "mirror_distance_m",
    "mirror_axis",
    "status",
    "max_tracking_error_deg",
    "primary_sharing_error_max_deg",
    "primary_sharing_error_signed_deg",
    "peak_torque_Nm",
    "load_torque_Nm",
    "tracking_margin",
    "holding_torque_Nm",
    "missed_steps",
    "mean_intercept",
    "light_energy_J",
    "light_energy_ideal_J",
    "light_lost_shared_primary_J",
    "light_lost_J",
)


def field_sharing_errors(scenario: Scenario, mirror_indices: Iterable[int] | None = None) -> pd.DataFrame:
    """Primary sharing error of each mirror of the field over the scenario's window (geometry only).

    Parameters
    ----------
    scenario : Scenario
    mirror_indices : iterable of int, optional
        Mirrors 0..12 (default all).

    Returns
    -------
    pandas.DataFrame
        Indexed by ``mirror_index``: ``mirror_distance_m`` [m],
        ``primary_sharing_error_max_deg`` and ``primary_sharing_error_signed_deg`` [deg]
        (see :func:`primary_sharing_error`).
    """
    indices = list(range(N_FIELD_MIRRORS) if mirror_indices is None else mirror_indices)
    for index in indices:
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < N_FIELD_MIRRORS:
            raise InputError(f"mirror index {index!r}: expected an integer from 0 to {N_FIELD_MIRRORS - 1}")
    spacing = scenario.mirror.spacing or DEFAULT_MIRROR_SPACING
    distances = field_distances(N_FIELD_MIRRORS, spacing)[indices]
    errors = sharing_errors(
        window_sun_times(scenario), scenario.site.to_site(), scenario.plant.to_plant(), scenario.window.date, distances
    )
    rows = [
        {"mirror_index": index, "mirror_distance_m": float(distance), **sharing_figures(errors[:, k])}
        for k, (index, distance) in enumerate(zip(indices, distances))
    ]
    return pd.DataFrame(rows).set_index("mirror_index")


def run_field(
    scenario: Scenario | str | Path,
    results_path: str | Path | None = None,
    *,
    mirror_indices: Iterable[int] | None = None,
    shared_primary: bool = True,
    overrides: Mapping[str, object] | None = None,
    client=None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    connect_timeout: float = 5.0,
    retry_failed: bool = False,
    progress: bool = False,
    on_result: Callable[[dict], None] | None = None,
) -> pd.DataFrame:
    """Simulate the whole field of the scenario: each mirror's secondary drive and the shared primary.

    One case per mirror (``mirror.index`` = 0 .. 12, secondary axis, its own motor) and,
    with ``shared_primary``, one case of the shared primary drive (the central mirror's
    primary law). Runs like a sweep (:func:`heliostep.sweep.execute_cases`): on Dask,
    written case by case to ``results_path``, finished cases skipped on a rerun.

    Parameters
    ----------
    scenario : Scenario or str or Path
        The base scenario (its ``mirror.distance``/``index`` and ``axis`` are replaced).
    results_path : str or Path, optional
        Default ``out/<scenario name>-field/results.parquet``.
    mirror_indices : iterable of int, optional
        Default all 13.
    shared_primary : bool, default True
        Also simulate the shared primary drive.
    overrides : Mapping, optional
        Dotted scenario key -> value, for every case.
    client, scheduler, n_workers, connect_timeout, retry_failed, progress, on_result
        See :func:`heliostep.sweep.execute_cases`.

    Returns
    -------
    pandas.DataFrame
        One row per case (the sweep table), :data:`FIELD_COLUMNS` first: the mirrors'
        secondary rows (``role`` "drive") with their ``max_tracking_error_deg`` and
        ``primary_sharing_error_max_deg`` [deg], then the shared primary (``role``
        "shared-primary").
    """
    spec = _field_sweep(scenario, mirror_indices, shared_primary, overrides)
    path = Path(results_path) if results_path is not None else Path("out") / spec.name / "results.parquet"
    outcome = execute_cases(
        expand_cases(spec),
        path,
        client=client,
        scheduler=scheduler,
        n_workers=n_workers,
        connect_timeout=connect_timeout,
        retry_failed=retry_failed,
        progress=progress,
        on_result=on_result,
        metadata=sweep_metadata(spec),
    )
    return _field_columns_first(outcome.table)


def _field_sweep(
    scenario: Scenario | str | Path,
    mirror_indices: Iterable[int] | None,
    shared_primary: bool,
    overrides: Mapping[str, object] | None,
) -> SweepSpec:
    """The sweep of :func:`run_field`: a ``mirror`` axis over *mirror_indices* on the secondary axis."""
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    indices = list(range(N_FIELD_MIRRORS) if mirror_indices is None else mirror_indices)
    return sweep_from_scenario(
        scenario,
        {"mirror": indices},
        overrides={"mirror.axis": "secondary", **(overrides or {})},
        shared_primary=shared_primary,
        name=f"{scenario.name}-field",
    )


def _field_columns_first(table: pd.DataFrame) -> pd.DataFrame:
    """*table* with :data:`FIELD_COLUMNS` first (those it has), its ``attrs`` kept."""
    first = [column for column in FIELD_COLUMNS if column in table]
    ordered = table[first + [column for column in table.columns if column not in first]]
    ordered.attrs = dict(table.attrs)
    return ordered
