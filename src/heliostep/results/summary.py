"""A run's figures (``summary.json``) from its trace and its metadata alone.

:func:`summarize` needs nothing but the trace and the run's metadata (the ``roles`` that name
the columns, the ``drive`` record of the sequencer and the step schedule), so the figures of a
stored run can be recomputed from its files (:func:`summarize_files`).

Definitions:

- tracking error: the panel angle minus its reference; max of its magnitude and its RMS
  over time (trapezoidal, so the extra rows around steps do not weigh more) [deg];
- peak torque, peak phase current: max magnitude over the trace;
- electrical energy drawn: the integral of the motor's electrical power [J];
- steps commanded: the sequencer's steps in the window; a step is *missed* when, at the
  next step (or at the end of the window for the last one), the rotor is more than half a
  step increment away from the position that step commanded; steps executed = commanded −
  missed;
- steps lost: how many step increments the rotor ends behind the commanded position
  (negative: ahead); a slip under load loses whole electrical cycles (4 full steps);
- settling time of a step: from the step until the rotor stays within
  ``settling_band`` × the step increment of the commanded position (up to the next step);
  ``None`` when it never does.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from heliostep.drive.sequencer import Sequencer, StepSchedule
from heliostep.results.trace import drive_from_metadata
from heliostep.results.trace_io import read_trace

#: Band around the commanded position that counts as settled, in step increments.
SETTLING_BAND = 0.05


def _time_rms(values: np.ndarray, time: np.ndarray) -> float:
    span = time[-1] - time[0]
    if span <= 0:
        return float(np.sqrt(np.mean(values**2)))
    return float(np.sqrt(np.trapezoid(values**2, time) / span))


def _peak(trace: pd.DataFrame, *columns: str) -> float | None:
    present = [c for c in columns if c in trace]
    return float(np.abs(trace[present].to_numpy()).max()) if present and len(trace) else None


def step_outcomes(trace: pd.DataFrame, rotor_column: str, sequencer: Sequencer, schedule: StepSchedule,
                  settling_band: float = SETTLING_BAND):
    """Per commanded step: (time, commanded angle, missed, settling time or None)."""
    time = trace["time"].to_numpy()
    rotor = trace[rotor_column].to_numpy()
    increment = sequencer.increment
    end = time[-1]
    outcomes = []
    for k, (t_step, index) in enumerate(zip(schedule.times, schedule.indices)):
        if t_step > end:
            break  # the run stopped before this step
        t_next = schedule.times[k + 1] if k + 1 < len(schedule) else end
        commanded = float(sequencer.position(index))
        first = np.searchsorted(time, t_step, side="right") - 1  # the row just after the step
        last = np.searchsorted(time, t_next, side="left")  # the row just before the next one
        last = min(max(last, first), len(time) - 1)
        error = np.abs(rotor[first:last + 1] - commanded)
        missed = bool(error[-1] > increment / 2)
        outside = np.nonzero(error > settling_band * increment)[0]
        if len(outside) == 0:
            settling = 0.0
        elif outside[-1] == len(error) - 1:
            settling = None
        else:
            settling = float(time[first + outside[-1] + 1] - t_step)
        outcomes.append((float(t_step), commanded, missed, settling))
    return outcomes


def summarize(trace: pd.DataFrame, metadata: Mapping) -> dict:
    """The run's figures (see the module docstring) from its trace and metadata.

    ``metadata`` needs ``roles`` (role -> column) and ``drive`` (see
    :func:`heliostep.results.trace.drive_metadata`).
    """
    roles = metadata.get("roles", {})
    sequencer, schedule = drive_from_metadata(metadata["drive"])
    rotor_column, panel_column = roles.get("rotor_angle"), roles.get("panel_angle")
    time = trace["time"].to_numpy()
    summary: dict = {"duration_s": float(time[-1] - time[0]) if len(time) else 0.0, "rows": int(len(trace))}
    if "panel_angle_error" in trace and len(trace):
        error = np.degrees(trace["panel_angle_error"].to_numpy())
        summary["max_tracking_error_deg"] = float(np.abs(error).max())
        summary["rms_tracking_error_deg"] = _time_rms(error, time)
    summary["peak_torque_Nm"] = _peak(trace, *(c for c in [roles.get("torque")] if c))
    summary["peak_phase_current_A"] = _peak(trace, *(roles[r] for r in ("current_a", "current_b") if r in roles))
    power = roles.get("power")
    if power in trace and len(trace) > 1:
        summary["electrical_energy_J"] = float(np.trapezoid(trace[power].to_numpy(), time))
    commanded = int(np.sum(schedule.times <= (time[-1] if len(time) else -np.inf)))
    summary["steps_commanded"] = commanded
    if rotor_column in trace and len(trace):
        outcomes = step_outcomes(trace, rotor_column, sequencer, schedule)
        missed = sum(1 for o in outcomes if o[2])
        settling = [o[3] for o in outcomes]
        settled = [s for s in settling if s is not None]
        summary["missed_steps"] = missed
        summary["steps_executed"] = commanded - missed
        summary["settling_time_s"] = {
            "max": max(settled) if settled else None,
            "mean": float(np.mean(settled)) if settled else None,
            "not_settled": sum(1 for s in settling if s is None),
            "per_step": settling,
        }
        summary["missed_step_times_s"] = [o[0] for o in outcomes if o[2]]
        lag = trace["rotor_angle_cmd"].iloc[-1] - trace[rotor_column].iloc[-1]
        summary["steps_lost"] = int(np.round(lag / sequencer.increment))
    if panel_column in trace and len(trace):
        summary["final_panel_angle_deg"] = float(np.degrees(trace[panel_column].iloc[-1]))
    return summary


def summarize_files(out_dir: str | Path) -> dict:
    """Recompute a stored run's figures from its ``trace.parquet`` and ``metadata.json``."""
    out_dir = Path(out_dir)
    trace, _ = read_trace(out_dir / "trace.parquet")
    metadata = json.loads((out_dir / "metadata.json").read_text())
    return summarize(trace, metadata)
