"""One day case of a sizing co-simulated in full: its figures for the sheet.

Details: docs/sizing.md, ``heliostep.sizing.case``.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from heliostep.run import RunFailed, RunOptions, run_scenario
from heliostep.sizing.plan import case_scenario
from heliostep.sweep.certificate import CERTIFIED_FIGURES
from heliostep.sweep.worker import FmuPayload, _local_fmu

__all__ = ["CASE_FIGURES", "CERTIFIED_CASE_FIGURES", "run_sizing_case"]

#: A day case's figures in the sheet's records.
CASE_FIGURES = (
    "max_tracking_error_deg",
    "steps_commanded",
    "missed_steps",
    "steps_lost",
    "electrical_energy_J",
    "drive_energy_per_day_J",
    "drive_power_mean_W",
    "peak_torque_Nm",
    "peak_phase_current_A",
    "light_energy_ideal_J",
    "light_energy_J",
    "light_lost_J",
    "light_lost_stowed_J",
    "stowed_time_s",
)
#: The figures of a sweep's certificate that a day case carries: those a sizing's certificate compares.
CERTIFIED_CASE_FIGURES = tuple(name for name in CERTIFIED_FIGURES if name in CASE_FIGURES)


def run_sizing_case(
    raw: dict,
    overrides: Sequence[str],
    source: str,
    folder: str,
    should_stop: Callable[[], bool] | None = None,
    fmu_paths: Mapping[str, Path] | None = None,
    shipped: Mapping[str, FmuPayload] | None = None,
) -> dict:
    """One case (on a Dask worker or here): its figures, or why it failed; ``"interrupted": True``
    when ``should_stop`` stopped it (not a finished case). ``fmu_paths``: the FMUs resolved once;
    ``shipped``: their bytes, sent to a worker that may have neither the models nor the cache."""
    scenario = case_scenario(raw, overrides, source, Path(folder))
    if shipped is not None:
        fmu_paths = {instance: _local_fmu(payload) for instance, payload in shipped.items()}
    started = clock.perf_counter()
    try:
        result = run_scenario(scenario, RunOptions(keep_trace=False, should_stop=should_stop, fmu_paths=fmu_paths))
    except RunFailed as failed:
        if failed.result.reason == "interrupted":
            return {"interrupted": True}
        return {"complete": False, "error": str(failed)[:500], "wall_time_s": clock.perf_counter() - started}
    figures = dict(result.summary or {})
    record = {key: figures.get(key) for key in CASE_FIGURES}
    record.update(complete=True, wall_time_s=clock.perf_counter() - started, method="full")
    return record
