"""A run's figures (``summary.json``) from its trace.

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

import numpy as np
import pandas as pd

from heliostep.inputs import DriveInputs
from heliostep.trace import PANEL_ANGLE, ROTOR_ANGLE

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


def step_outcomes(trace: pd.DataFrame, inputs: DriveInputs, settling_band: float = SETTLING_BAND):
    """Per commanded step: (time, commanded angle, missed, settling time or None)."""
    time = trace["time"].to_numpy()
    rotor = trace[ROTOR_ANGLE].to_numpy()
    schedule, sequencer = inputs.schedule, inputs.sequencer
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


def summarize(trace: pd.DataFrame, inputs: DriveInputs) -> dict:
    """The run's figures (see the module docstring)."""
    time = trace["time"].to_numpy()
    summary: dict = {"duration_s": float(time[-1] - time[0]) if len(time) else 0.0, "rows": int(len(trace))}
    if "panel_angle_error" in trace and len(trace):
        error = np.degrees(trace["panel_angle_error"].to_numpy())
        summary["max_tracking_error_deg"] = float(np.abs(error).max())
        summary["rms_tracking_error_deg"] = _time_rms(error, time)
    summary["peak_torque_Nm"] = _peak(trace, "motor.tau")
    summary["peak_phase_current_A"] = _peak(trace, "motor.i_a", "motor.i_b")
    if "motor.power" in trace and len(trace) > 1:
        summary["electrical_energy_J"] = float(np.trapezoid(trace["motor.power"].to_numpy(), time))
    commanded = int(np.sum(inputs.schedule.times <= (time[-1] if len(time) else -np.inf)))
    summary["steps_commanded"] = commanded
    if ROTOR_ANGLE in trace and len(trace):
        outcomes = step_outcomes(trace, inputs)
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
        lag = trace["rotor_angle_cmd"].iloc[-1] - trace[ROTOR_ANGLE].iloc[-1]
        summary["steps_lost"] = int(np.round(lag / inputs.sequencer.increment))
    if PANEL_ANGLE in trace and len(trace):
        summary["final_panel_angle_deg"] = float(np.degrees(trace[PANEL_ANGLE].iloc[-1]))
    return summary
