"""What a run will take, estimated from its scenario alone before anything is computed.

:func:`check_budget` refuses a run over its memory or disk budget before its inputs are prepared.

Details: docs/running.md, ``heliostep.run.estimate``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from heliostep.drive.inputs import MAX_REFERENCE_SPACING, scenario_panel_angle, scenario_sequencer
from heliostep.errors import InputError
from heliostep.scenario import Scenario
from heliostep.solar import rotor_angle_from_panel

__all__ = ["REFERENCE_POINTS", "RunEstimate", "check_budget", "estimate_run"]

#: Instants of the reference the estimate evaluates (the run: one every 10 s, at least 600).
REFERENCE_POINTS = 2001
#: Columns of a trace, for the estimate (the shipped FMUs give 20; room for a vendor FMU's).
TRACE_COLUMNS = 24
#: Memory of the process besides the run's arrays [bytes]: Python, numpy, pandas, pvlib, the FMUs
#: (a 5-minute run of the shipped models peaks at 240 MB).
BASE_MEMORY = 300e6
#: Memory per output-grid time while the grid is built and used [bytes] (arange, concatenate,
#: unique, the master's copy).
GRID_BYTES_PER_ROW = 40.0
#: Memory per value of a trace held in memory [bytes] (the assembled blocks and their concatenation).
HELD_BYTES_PER_VALUE = 24.0
#: Memory per step [bytes] (schedule, currents, the step figures' rows).
STEP_BYTES = 400.0
#: Disk per trace value [bytes]: Parquet (uncompressed float64; zstd makes about half), CSV (measured 16.7).
PARQUET_BYTES_PER_VALUE = 8.0
CSV_BYTES_PER_VALUE = 20.0
#: Disk of ``metadata.json`` per step (the step schedule, the step outcomes, the error's integrals at the step and
#: its extremes for the light: measured 476 on ``jan21-day``, 2026-12-03) and of the figures [bytes].
METADATA_BYTES_PER_STEP = 520.0
FIGURE_BYTES = 1e6


@dataclass(frozen=True)
class RunEstimate:
    """A run's work, estimated (:func:`estimate_run`): counts and bytes (floats: they may be huge)."""

    duration_s: float
    steps: float
    events: float
    rows: float
    memory_bytes: float
    disk_bytes: float
    rows_regular: float  # of the regular grid
    rows_after_steps: float  # of the fine grids after the steps and the rows at the steps
    held: bool  # the trace held in memory (else streamed to its file)

    def record(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        return (
            f"{self.rows:.3g} trace rows, {self.steps:.3g} steps, {self.events:.3g} events, "
            f"{self.memory_bytes / 1e9:.3g} GB of memory, {self.disk_bytes / 1e9:.3g} GB of disk"
        )


def _finite(value: float) -> float:
    return float(value) if math.isfinite(value) else math.inf


def estimate_steps(scenario: Scenario, duration: float, start: pd.Timestamp) -> float:
    """The steps a run commands: the reference rotor angle's travel over the window (sampled at
    most :data:`REFERENCE_POINTS` times) divided by the sequencer's increment."""
    points = int(min(max(600, math.ceil(duration / MAX_REFERENCE_SPACING) + 1), REFERENCE_POINTS))
    times = np.linspace(0.0, duration, points)
    panel = scenario_panel_angle(scenario, start + pd.to_timedelta(times, unit="s"))
    transmission = scenario.transmission
    with np.errstate(all="ignore"):
        rotor = rotor_angle_from_panel(panel, panel[0], transmission.pinion_radius, transmission.lever_arm, 0.0)
        travel = float(np.sum(np.abs(np.diff(np.asarray(rotor, dtype=float)))))
        return _finite(travel / scenario_sequencer(scenario).increment)


def estimate_run(
    scenario: Scenario, held_max_duration: float, keep_trace: bool = True, csv: bool | None = None
) -> RunEstimate:
    """Steps, events, rows, memory [bytes] and disk [bytes] of ``scenario``'s run; a window up to
    ``held_max_duration`` [s] holds its trace in memory, a closed or hybrid loop's its rows whatever the
    window (until its steps are decided). ``csv``: a CSV copy written (None: for windows up to an hour, as
    ``heliostep run`` does)."""
    start, end = scenario.window_bounds()
    duration = (end - start).total_seconds()
    steps = estimate_steps(scenario, duration, start)
    out, sequencer = scenario.output, scenario.sequencer
    events = steps * (2.0 if sequencer.idle_current_fraction < 1.0 else 1.0)
    with np.errstate(all="ignore"):
        regular = _finite(duration / out.interval) + 1.0
        per_step = math.ceil(min(out.step_detail / out.step_interval, 1e300))
        fine_built = _finite(steps * per_step)  # before the duplicates go
        after_steps = min(fine_built, _finite(duration / out.step_interval)) + steps  # and the row at each step
    rows = regular + after_steps
    held = (keep_trace and duration <= held_max_duration) or scenario.tracking.mode != "open_loop"
    memory = BASE_MEMORY + (regular + fine_built) * GRID_BYTES_PER_ROW + steps * STEP_BYTES
    memory += rows * TRACE_COLUMNS * HELD_BYTES_PER_VALUE if held else 0.0
    disk = 0.0
    if keep_trace:
        csv = duration <= 3600.0 if csv is None else csv
        disk = rows * TRACE_COLUMNS * (PARQUET_BYTES_PER_VALUE + (CSV_BYTES_PER_VALUE if csv else 0.0))
        disk += steps * METADATA_BYTES_PER_STEP + FIGURE_BYTES
    return RunEstimate(duration, steps, events, rows, _finite(memory), _finite(disk), regular, after_steps, held)


#: Keys that enlarge a part of the estimate: (dotted key, larger when the value is smaller).
_STEP_KEYS = (
    ("sequencer.step_angle", True),
    ("sequencer.microsteps", False),
    ("transmission.pinion_radius", True),
    ("transmission.lever_arm", False),
)
_FINE_KEYS = (("output.step_interval", True), ("output.step_detail", False))
_REGULAR_KEYS = (("output.interval", True),)


def _enlargement(scenario: Scenario, key: str, smaller_is_larger: bool) -> tuple[float, float, float]:
    """How many times ``key`` enlarges the run against its default, its value and its default."""
    section_name, name = key.split(".")
    section = getattr(scenario, section_name)
    value, default = float(getattr(section, name)), float(type(section).model_fields[name].default)
    with np.errstate(all="ignore"):
        ratio = default / value if smaller_is_larger else value / default
    return _finite(ratio), value, default


def _culprit(scenario: Scenario, estimate: RunEstimate) -> str:
    """The key that makes the run large, with its value and default."""
    fine_part = estimate.rows_after_steps
    keys: tuple[tuple[str, bool], ...] = (
        _REGULAR_KEYS if estimate.rows_regular >= fine_part else _FINE_KEYS + _STEP_KEYS
    )
    candidates = [(*_enlargement(scenario, key, smaller), key) for key, smaller in keys]
    ratio, value, default, key = max(candidates, key=lambda candidate: candidate[0])
    if ratio > 1.0:
        return f"{key} = {value:g} (default {default:g})"
    window = scenario.window
    length = "window.duration" if window.duration is not None else "window.start / window.end"
    return f"{length} ({estimate.duration_s:g} s)"


def check_budget(scenario: Scenario, estimate: RunEstimate) -> None:
    """Refuse (InputError) a run whose estimated memory or disk is over ``scenario.budget``."""
    budget = scenario.budget
    for what, needed, allowed, key, option in (
        ("memory", estimate.memory_bytes, budget.memory_gb, "budget.memory_gb", "--max-memory"),
        ("disk", estimate.disk_bytes, budget.disk_gb, "budget.disk_gb", "--max-disk"),
    ):
        if needed > allowed * 1e9:
            raise InputError(
                f"{scenario.source}: {_culprit(scenario, estimate)} makes the run too large: an estimated "
                f"{estimate.describe()}; over the {what} budget of {allowed:g} GB "
                f"(raise it with {key} or heliostep run {option} if the machine has it)"
            )
