"""A run's trace: the master's rows plus the reference, the commanded position and the error.

Columns (SI units, angles in radians; see :data:`UNITS`): ``time`` [s from the window
start], the master inputs ``i_a_ref``, ``i_b_ref`` (and ``m_ext``), every FMU output as
``instance.variable``, and the derived ``panel_angle_ref``, ``rotor_angle_ref``,
``step_index``, ``rotor_angle_cmd`` and ``panel_angle_error`` (actual − reference panel
angle). At a step two rows share the time: just before and just after it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from heliostep.inputs import DriveInputs

#: Units of the columns heliostep itself adds to a trace.
UNITS = {
    "time": "s", "i_a_ref": "A", "i_b_ref": "A", "m_ext": "N.m", "panel_angle_ref": "rad",
    "rotor_angle_ref": "rad", "step_index": "1", "rotor_angle_cmd": "rad", "panel_angle_error": "rad",
}

PANEL_ANGLE = "mechanics.theta_p"
ROTOR_ANGLE = "mechanics.theta"


def step_indices(times: np.ndarray, inputs: DriveInputs) -> np.ndarray:
    """Commanded step index on each row: at a repeated time the first row is before the step."""
    times = np.asarray(times, dtype=float)
    first_of_time = np.concatenate([[True], times[1:] != times[:-1]])
    before = inputs.schedule.index_at(times, side="left")
    after = inputs.schedule.index_at(times, side="right")
    return np.where(first_of_time, before, after)


def assemble_trace(master_trace: pd.DataFrame, inputs: DriveInputs) -> pd.DataFrame:
    """Add the reference, the commanded position and the tracking error to the master's trace."""
    trace = master_trace.copy()
    time = trace["time"].to_numpy()
    trace["panel_angle_ref"] = inputs.panel_reference()(time)
    trace["rotor_angle_ref"] = inputs.rotor_reference()(time)
    index = step_indices(time, inputs)
    trace["step_index"] = index.astype(float)
    trace["rotor_angle_cmd"] = inputs.sequencer.position(index)
    if PANEL_ANGLE in trace:
        trace["panel_angle_error"] = trace[PANEL_ANGLE] - trace["panel_angle_ref"]
    return trace
