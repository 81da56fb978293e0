"""The figures' definitions evaluated on rows held in a frame, all at once: the oracle that the
streaming figures (:class:`heliostep.results.figures.solution.SolutionRecorder`, the run's one pass) are
checked against. Written apart from them on purpose (the batch functions that were
``heliostep.results.figures.summary.figures``, ``step_outcomes`` and ``solution_figures``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from heliostep.results.figures.steps import SETTLING_BAND, judged_steps, lost_steps, step_outcome
from heliostep.results.trace.frame import drive_from_metadata


def _time_rms(values: np.ndarray, time: np.ndarray) -> float:
    """RMS over time of a signal taken as linear between rows."""
    span = time[-1] - time[0]
    if span <= 0:
        return float(np.sqrt(np.mean(values**2)))
    e0, e1, h = values[:-1], values[1:], np.diff(time)
    return float(np.sqrt(np.sum(h * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0) / span))


def _peak(trace: pd.DataFrame, *columns: str) -> float | None:
    present = [c for c in columns if c in trace]
    return float(np.abs(trace[present].to_numpy()).max()) if present and len(trace) else None


def step_outcomes(trace: pd.DataFrame, rotor_column: str, sequencer, schedule, settling_band: float = SETTLING_BAND):
    """Per commanded step: its :class:`~heliostep.results.figures.steps.StepOutcome`."""
    time = trace["time"].to_numpy()
    rotor = trace[rotor_column].to_numpy()
    end = time[-1]
    lag = float(sequencer.position(schedule.initial_index) - rotor[0])  # elastic lag held at the start
    outcomes = []
    previous = float(sequencer.position(schedule.initial_index))
    for k, (t_step, index) in enumerate(zip(schedule.times, schedule.indices)):
        if t_step > end:
            break  # the run stopped before this step
        t_next = schedule.times[k + 1] if k + 1 < len(schedule) else end
        commanded = float(sequencer.position(index))
        first = int(np.searchsorted(time, t_step, side="left"))  # the row at the step (before it)
        last = int(np.searchsorted(time, t_next, side="left"))  # the row at the next step (before it)
        last = min(max(last, first), len(time) - 1)
        outcomes.append(
            step_outcome(
                t_step,
                commanded,
                previous,
                time[first : last + 1],
                rotor[first : last + 1],
                lag,
                sequencer,
                settling_band,
            )
        )
        previous = commanded
    return outcomes


def figures(trace: pd.DataFrame, metadata: Mapping) -> dict:
    """The figures evaluated on the rows of an assembled ``trace`` (with ``rotor_angle_cmd`` and
    ``panel_angle_error``)."""
    roles = metadata.get("roles", {})
    sequencer, schedule = drive_from_metadata(metadata["drive"])
    rotor_column = roles.get("rotor_angle")
    time = trace["time"].to_numpy()
    result: dict = {}
    if "panel_angle_error" in trace and len(trace):
        error = np.degrees(trace["panel_angle_error"].to_numpy())
        result["max_tracking_error_deg"] = float(np.abs(error).max())
        result["rms_tracking_error_deg"] = _time_rms(error, time)
        # the error's integral over the rows (trapezoid), to the end and to each step's time reached: the
        # step's own row (the first at its time) counted, the rows after it not
        running = np.concatenate([[0.0], np.cumsum(np.diff(time) * (error[:-1] + error[1:]) / 2.0)])
        reached = [t for t in schedule.times if t <= time[-1]]
        result["error_integral_deg_s"] = float(running[-1])
        result["error_integral_at_steps_deg_s"] = [
            float(running[np.searchsorted(time, t, side="left")]) for t in reached
        ]
        # per interval (the rows from a step's time on, to the next step's), the first row of the largest
        # and of the least error: its time, error and panel angle
        interval = np.searchsorted(np.asarray(schedule.times, dtype=float), time, side="right")
        extremes, panel = [], trace[roles["panel_angle"]].to_numpy()
        for j in range(len(reached) + 1):
            rows = np.flatnonzero((interval == j) & ~np.isnan(error))
            if not len(rows):
                extremes.append([None] * 6)
                continue
            high, low = rows[np.argmax(error[rows])], rows[np.argmin(error[rows])]
            extremes.append([float(v) for k in (high, low) for v in (time[k], error[k], panel[k])])
        result["error_extremes_deg"] = extremes
        # the integral of e^2 over linear pieces, to the end and to each step's time reached
        e0, e1 = error[:-1], error[1:]
        squares = np.concatenate([[0.0], np.cumsum(np.diff(time) * (e0 * e0 + e0 * e1 + e1 * e1) / 3.0)])
        result["error_sq_integral_deg2_s"] = float(squares[-1])
        result["error_sq_integral_at_steps_deg2_s"] = [
            float(squares[np.searchsorted(time, t, side="left")]) for t in reached
        ]
    result["peak_torque_Nm"] = _peak(trace, *(c for c in [roles.get("torque")] if c))
    result["peak_phase_current_A"] = _peak(trace, *(roles[r] for r in ("current_a", "current_b") if r in roles))
    power = roles.get("power")
    if power in trace and len(trace) > 1:
        result["electrical_energy_J"] = float(np.trapezoid(trace[power].to_numpy(), time))
    if rotor_column in trace and len(trace):
        outcomes = step_outcomes(trace, rotor_column, sequencer, schedule)
        judged = judged_steps(outcomes, len(outcomes))
        result.update(
            missed_steps=judged.missed_steps,
            steps_executed=judged.steps_executed,
            settling_time_s=judged.settling_time_s.record(),
            missed_step_times_s=judged.missed_step_times_s,
        )
        behind = float(trace["rotor_angle_cmd"].iloc[-1] - trace[rotor_column].iloc[-1]) / sequencer.increment
        lag = float(trace["rotor_angle_cmd"].iloc[0] - trace[rotor_column].iloc[0]) / sequencer.increment
        result["steps_lost"], result["final_lag_steps"] = lost_steps(
            behind, lag, sequencer, schedule, float(time[0]), float(time[-1])
        )
        result["step_outcomes"] = [o.record() for o in outcomes]
    return result


def solution_figures(solution: pd.DataFrame, metadata: Mapping) -> dict:
    """The figures from the solution rows (assembled like a trace), as ``metadata['solution_figures']``."""
    result = figures(solution, metadata)
    result["solution_rows"] = int(len(solution))
    result["end_time_s"] = float(solution["time"].iloc[-1]) if len(solution) else 0.0
    return result


# The summary as it was computed after the simulation, before the one pass: the trace read back,
# its rows judged again by a second recorder and merged with the solution's figures by precedence
# (``TraceSummary``), and the summary at a cut recomputed from the rows up to the cut's step. The
# run's single-pass summary is checked against it (tests/run/test_run_one_pass.py).

_STEP_KEYS = (
    "missed_steps",
    "steps_executed",
    "settling_time_s",
    "missed_step_times_s",
    "steps_lost",
    "final_lag_steps",
)


def _old_step_fields(outcomes, commanded: int) -> dict:
    judged = judged_steps(outcomes, commanded)
    return {
        "missed_steps": judged.missed_steps,
        "steps_executed": judged.steps_executed,
        "settling_time_s": judged.settling_time_s.record(),
        "missed_step_times_s": judged.missed_step_times_s,
    }


def trace_summary_before(trace: pd.DataFrame, metadata: Mapping) -> dict:
    """``TraceSummary(...).summary()`` of the trace as one block, with the metadata's solution figures."""
    from heliostep.results.figures.solution import SolutionRecorder
    from heliostep.results.figures.steps import StepOutcome

    roles = metadata.get("roles", {})
    sequencer, schedule = drive_from_metadata(metadata["drive"])
    columns = list(trace.columns)
    recorder = SolutionRecorder(columns, roles, sequencer, schedule, None, block=1)
    rows = len(trace)
    if rows:
        recorder(trace[columns].to_numpy(dtype=float))
    time = trace["time"].to_numpy(dtype=float)
    summary: dict = {"duration_s": float(time[-1]) - float(time[0]) if rows else 0.0, "rows": rows}
    end = float(time[-1]) if rows else -np.inf
    commanded = int(np.sum(schedule.times <= end))
    grid = recorder.figures() if rows else {}
    for key in ("solution_rows", "end_time_s"):
        grid.pop(key, None)
    solution = metadata.get("solution_figures")
    chosen = dict(grid)
    if solution:
        chosen.update({k: v for k, v in solution.items() if k not in _STEP_KEYS and k != "step_outcomes" and k in grid})
        outcomes = [o for o in solution.get("step_outcomes", []) if o["time_s"] <= end]
        if len(outcomes) == commanded and "step_outcomes" in grid:
            chosen.update(_old_step_fields([StepOutcome.from_record(o) for o in outcomes], commanded))
            if solution.get("end_time_s") == float(end):
                chosen["steps_lost"] = solution["steps_lost"]
                chosen["final_lag_steps"] = solution["final_lag_steps"]
    chosen.pop("step_outcomes", None)
    summary.update({k: chosen.get(k) for k in ("max_tracking_error_deg", "rms_tracking_error_deg") if k in chosen})
    for key in ("peak_torque_Nm", "peak_phase_current_A", "electrical_energy_J"):
        if key in chosen:
            summary[key] = chosen[key]
    summary["steps_commanded"] = commanded
    for key in _STEP_KEYS:
        if key in chosen:
            summary[key] = chosen[key]
    summary["figures_from"] = "solution" if solution else "output rows"
    panel = roles.get("panel_angle")
    if panel in trace and rows:
        summary["final_panel_angle_deg"] = float(np.degrees(trace[panel].iloc[-1]))
    return summary


def summary_at_cut_before(trace: pd.DataFrame, metadata: Mapping, summary: dict) -> dict:
    """The summary of an interrupted run as it was corrected after the simulation (trace re-read)."""
    drive = metadata.get("drive") or {}
    times = np.asarray(drive.get("step_times", []), dtype=float)
    if not len(trace):
        return summary
    end = float(trace["time"].iloc[-1])
    before = times[times <= end]
    if not len(before):
        return summary
    last_step = float(before[-1])
    missed_last = last_step in set(summary.get("missed_step_times_s") or [])
    per_step = (summary.get("settling_time_s") or {}).get("per_step") or []
    unsettled_last = bool(per_step) and per_step[-1] is None
    lost = summary.get("steps_lost")
    if not (missed_last or unsettled_last or (lost not in (None, 0))):
        return summary
    keep = times < last_step
    drive_before = {
        **drive,
        "step_times": [float(t) for t in times[keep]],
        "step_indices": [int(k) for k in np.asarray(drive["step_indices"])[keep]],
    }
    time = trace["time"].to_numpy()
    i = int(np.searchsorted(time, last_step, side="left"))
    head = trace.iloc[: i + 1] if i < len(time) and time[i] == last_step else trace.iloc[:i]
    fixed = dict(summary)
    keys = ("steps_commanded", *_STEP_KEYS)
    if len(head):
        partial = trace_summary_before(head.reset_index(drop=True), {**metadata, "drive": drive_before})
        for key in keys:
            if key in partial:
                fixed[key] = partial[key]
    else:
        for key in keys:
            fixed.pop(key, None)
    fixed["step_in_progress_at_cut_s"] = last_step
    return fixed
