"""One case on a worker: the shipped FMUs written locally, the run, the case's table row."""

from __future__ import annotations

import copy
import dataclasses
import datetime as dt
import hashlib
import json
import logging
import math
import os
import socket
import tempfile
import threading
import time as clock
import traceback
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from heliostep.drive.inputs import DriveInputs, prepare_inputs, reference_times
from heliostep.errors import HeliostepError
from heliostep.run import RunOptions, run_scenario
from heliostep.run.load_budget import (
    load_budget,
    mechanics_values,
    start_values,
    step_limit_of_holding,
    wind_moment_at,
)
from heliostep.scenario import (
    Scenario,
    validate_scenario,
)
from heliostep.solar import sharing_errors, sharing_figures
from heliostep.sweep.spec import SweepCase
from heliostep.sweep.store import FIGURE_COLUMNS

logger = logging.getLogger(__name__)


#: Longest error text kept in the table [characters].
MAX_ERROR_CHARS = 4000


@dataclasses.dataclass(frozen=True)
class FmuPayload:
    """An FMU file shipped to the workers: its name, content hash and bytes."""

    name: str
    sha256: str
    data: bytes = dataclasses.field(repr=False)


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
        ``settling_not_settled`` (the load columns are :func:`load_figures`').
    """
    figures = {
        name: summary.get(name)
        for name in FIGURE_COLUMNS
        if name
        not in (
            "settling_time_max_s",
            "settling_time_mean_s",
            "settling_not_settled",
            "load_torque_Nm",
            "tracking_margin",
            "holding_torque_Nm",
            "primary_sharing_error_max_deg",
            "primary_sharing_error_signed_deg",
        )
    }
    settling = summary.get("settling_time_s") or {}
    figures["settling_time_max_s"] = settling.get("max")
    figures["settling_time_mean_s"] = settling.get("mean")
    figures["settling_not_settled"] = settling.get("not_settled")
    return figures


def load_figures(
    scenario: Scenario, local: Mapping[str, Path], held: float | None, inputs: DriveInputs | None = None
) -> dict:
    """``load_torque_Nm``: the load budget on the motor shaft at the case's worst instant
    (:func:`heliostep.run.load_budget.load_budget`: wind, friction, inertia [N.m]); ``tracking_margin``:
    the static step limit of the holding torque ``held`` (k_e x I [N.m],
    :func:`~heliostep.run.load_budget.step_limit_of_holding`) over that load (inf without a load).
    ``inputs``: the case's :func:`~heliostep.drive.inputs.prepare_inputs`, computed when not given."""
    mechanics = scenario.roles.instance_of("wind_moment") or "mechanics"
    values = mechanics_values(scenario, mechanics, local.get(mechanics))
    inputs = prepare_inputs(scenario) if inputs is None else inputs
    budget = load_budget(scenario, inputs, wind_moment_at(inputs), values, values["J_m"])
    sequencer = scenario.sequencer
    limit = None if held is None else step_limit_of_holding(held, sequencer.mode, sequencer.microsteps)
    margin = None if limit is None else (math.inf if budget.total_Nm <= 0 else limit / budget.total_Nm)
    return {"load_torque_Nm": budget.total_Nm, "tracking_margin": margin}


def _holding_torque(scenario: Scenario, motor: str | None, motor_fmu: Path | None) -> float | None:
    """k_e x I [N.m]: the torque constant of the ``motor`` instance (parameter or FMU default) times the current."""
    k_e = scenario.parameters.get(motor or "", {}).get("k_e")
    if k_e is None and motor_fmu is not None:
        default = start_values(motor_fmu).get("k_e")
        k_e = default if isinstance(default, float | int) else None
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
    row.update(method="full", fallback=None)
    scenario = None
    try:
        scenario, local = local_scenario(case, payloads)
        # supervised (a crashing or hanging FMU fails this case only, named), the child started by a fork server
        # (a Dask worker runs threads); the table needs the figures only
        options = RunOptions(keep_trace=False, supervise=True, light_first_order=False, start_method="forkserver")
        result = run_scenario(scenario, options)
        row.update(summary_figures(result.summary))
        motor = scenario.roles.instance_of("torque")
        row["holding_torque_Nm"] = _holding_torque(scenario, motor, local.get(motor) if motor else None)
    except Exception as exc:  # noqa: BLE001 - a failing case (RunFailed, InputError, ...) is recorded, never fatal
        row.update(status="failed", error_type=type(exc).__name__, error=_error_text(exc))
    else:
        try:  # the load columns (a case's own FMUs may lack a mechanics default): never the run's failure
            row.update(load_figures(scenario, local, row["holding_torque_Nm"]))
        except Exception as exc:  # noqa: BLE001
            logger.warning("load figures of case %s: %s", case.case_id, exc)
    if scenario is not None:
        try:
            row.update(primary_sharing_error(scenario))
        except Exception as exc:  # noqa: BLE001
            logger.warning("primary sharing error of case %s: %s", case.case_id, exc)
    row.update(run_columns(case, run_id, started))
    return row


def local_scenario(case: SweepCase, payloads: Mapping[str, FmuPayload]) -> tuple[Scenario, dict[str, Path]]:
    """The case's scenario on its FMUs written on this worker (from ``payloads``), and those FMUs' paths by
    instance."""
    data = copy.deepcopy(case.scenario)
    local = {instance: _local_fmu(payloads[sha]) for instance, sha in case.fmu_sha256.items()}
    dropped = {instance: None for instance, reference in data["fmus"].items() if reference is None}
    data["fmus"] = {**dropped, **{instance: str(path) for instance, path in local.items()}}
    return validate_scenario(data, source=case.source, folder=case.folder), local


def run_columns(case: SweepCase, run_id: str, started: float) -> dict:
    """A finished case's execution columns: its wall time since ``started`` (:func:`time.perf_counter`), the
    time, the sweep invocation, the worker, its FMUs."""
    return {
        "wall_time_s": clock.perf_counter() - started,
        "finished_at": _now(),
        "run_id": run_id,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
        "fmu_sha256": _fmu_key(case.fmu_sha256),
    }


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="microseconds")


def _fmu_key(fmu_sha256: Mapping[str, str]) -> str:
    return json.dumps(dict(sorted(fmu_sha256.items())))


def _lost_case_row(case: SweepCase, exc: BaseException, run_id: str) -> dict:
    """The row of a case whose task itself failed (e.g. its workers kept dying)."""
    return {
        **case.columns,
        **dict.fromkeys(FIGURE_COLUMNS),
        "status": "failed",
        "error_type": type(exc).__name__,
        "error": _error_text(exc),
        "wall_time_s": None,
        "finished_at": _now(),
        "run_id": run_id,
        "worker": None,
        "fmu_sha256": _fmu_key(case.fmu_sha256),
        "method": "full",
    }


def primary_sharing_error(scenario: Scenario) -> dict:
    """Primary-angle error of the scenario's mirror when its primary follows the central mirror's law.

    The shared motor turns every primary by the central mirror's angle; each mirror is
    mounted with the offset that makes it exact at solar noon of the window's date
    (:func:`heliostep.solar.sharing_errors`). Evaluated over the scenario's window on the grid
    where the simulation evaluates the sun, while the sun is above the horizon.

    Returns
    -------
    dict
        ``primary_sharing_error_max_deg``: max |error| [deg];
        ``primary_sharing_error_signed_deg``: that error with its sign (positive tilts the
        normal toward +x) [deg]. None when the sun stays down.
    """
    errors = sharing_errors(
        window_sun_times(scenario),
        scenario.site.to_site(),
        scenario.plant.to_plant(),
        scenario.window.date,
        [scenario.mirror.mirror_distance],
    )
    return sharing_figures(errors[:, 0])


def window_sun_times(scenario: Scenario) -> pd.DatetimeIndex:
    """The instants of the window at which a run evaluates the sun (:func:`heliostep.drive.inputs.reference_times`)."""
    start, end = scenario.window_bounds()
    return start + pd.to_timedelta(reference_times((end - start).total_seconds()), unit="s")
