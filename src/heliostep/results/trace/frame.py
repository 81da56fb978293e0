"""A run's trace: the master's rows plus the reference, the commanded position and the error.

Columns (SI units, angles in radians; see :data:`UNITS`): ``time`` [s from the window
start], the master inputs ``i_a_ref``, ``i_b_ref`` (and ``m_ext``), every FMU output as
``instance.variable``, and the derived ``panel_angle_ref``, ``rotor_angle_ref``,
``step_index``, ``rotor_angle_cmd`` and ``panel_angle_error`` (actual − reference panel
angle). At a step two rows share the time: just before and just after it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from heliostep.drive.inputs import DriveInputs
from heliostep.drive.sequencer import Sequencer, StepSchedule

#: Units of the columns heliostep itself adds to a trace.
UNITS = {
    "time": "s",
    "i_a_ref": "A",
    "i_b_ref": "A",
    "m_ext": "N.m",
    "panel_angle_ref": "rad",
    "rotor_angle_ref": "rad",
    "step_index": "1",
    "rotor_angle_cmd": "rad",
    "panel_angle_error": "rad",
}


def trace_metadata(
    scenario: str,
    metadata: Mapping[str, Any],
    columns: list[str],
    complete: bool,
    reason: str | None,
    time_reached: float | None,
    error: str | None,
) -> dict[str, str]:
    """A run's trace file metadata: ``complete`` (and, when not, ``reason`` and ``time_reached``),
    the scenario's name, the window (from the run's ``metadata``), the error, and the unit and
    role of each of ``columns``."""
    present = set(columns)
    units = {f"unit.{c}": u for c, u in metadata.get("units", {}).items() if c in present}
    roles = {f"role.{r}": c for r, c in metadata.get("roles", {}).items() if c in present}
    extra = {}
    if not complete:
        extra["reason"] = reason or "failed"
        if time_reached is not None:
            extra["time_reached"] = repr(float(time_reached))
    return {
        "complete": str(complete).lower(),
        **extra,
        "scenario": scenario,
        "window_start": metadata["window_start"],
        "timezone": metadata["timezone"],
        **({"error": error} if error else {}),
        **units,
        **roles,
    }


def figure_columns(roles: dict[str, str]) -> list[str]:
    """The trace columns the run's figures are computed from (summary, light): the derived
    columns and every role's column. A streamed trace is read back with only these."""
    return [
        "time",
        "panel_angle_ref",
        "rotor_angle_ref",
        "step_index",
        "rotor_angle_cmd",
        "panel_angle_error",
        *roles.values(),
    ]


def drive_metadata(inputs: DriveInputs) -> dict:
    """What the results need of the drive, as plain JSON data for a run's metadata."""
    sequencer, schedule = inputs.sequencer, inputs.schedule
    return {
        "mode": sequencer.mode,
        "current": sequencer.current,
        "step_angle": sequencer.step_angle,
        "microsteps": sequencer.microsteps,
        "idle_current_fraction": sequencer.idle_current_fraction,
        "idle_delay": sequencer.idle_delay,
        "initial_index": int(schedule.initial_index),
        "step_times": [float(t) for t in schedule.times],
        "step_indices": [int(k) for k in schedule.indices],
        **_wind_metadata(inputs),
    }


def _wind_metadata(inputs: DriveInputs) -> dict:
    """The wind's figures known before simulating: the worst holding instant, the stow moves."""
    if inputs.wind_signal is None:
        return {}
    transmission = inputs.implied_parameters
    worst = inputs.wind_signal.worst_holding_instant(transmission["pinion_radius"], transmission["lever_arm"])
    return {
        "wind": worst,
        "stow_moves": [move.record() for move in inputs.stow_moves],
        "stowed_spans_s": [[float(a), float(b)] for a, b in inputs.stowed_spans],
    }


def drive_from_metadata(drive: dict) -> tuple[Sequencer, StepSchedule]:
    """The sequencer and the step schedule back from :func:`drive_metadata`'s data."""
    defaults = Sequencer()  # a record written before microstepping and idle reduction existed
    sequencer = Sequencer(
        mode=drive["mode"],
        current=float(drive["current"]),
        step_angle=float(drive["step_angle"]),
        microsteps=int(drive.get("microsteps", defaults.microsteps)),
        idle_current_fraction=float(drive.get("idle_current_fraction", defaults.idle_current_fraction)),
        idle_delay=float(drive.get("idle_delay", defaults.idle_delay)),
    )
    schedule = StepSchedule(
        times=np.asarray(drive["step_times"], dtype=float),
        indices=np.asarray(drive["step_indices"], dtype=int),
        initial_index=int(drive["initial_index"]),
    )
    return sequencer, schedule


def step_indices(times: np.ndarray, schedule: StepSchedule, previous_time: float | None = None) -> np.ndarray:
    """Commanded step index on each row: at a repeated time the first row is before the step.

    ``previous_time`` is the time of the row before ``times[0]`` (when the rows are a block of a
    longer trace), so a block that starts at the repeated time of a step is indexed as the whole.
    """
    times = np.asarray(times, dtype=float)
    first = [True] if previous_time is None or not len(times) else [bool(times[0] != previous_time)]
    first_of_time = np.concatenate([first, times[1:] != times[:-1]])[: len(times)]
    before = schedule.index_at(times, side="left")
    after = schedule.index_at(times, side="right")
    return np.where(first_of_time, before, after)


def master_block(block, master_columns: list[str], where: str = "") -> np.ndarray:
    """A block of the master's trace rows as a float 2-D array (rows x ``master_columns``), or
    ValueError naming ``where`` (the sink) and the shape expected."""
    block = np.asarray(block, dtype=float)
    if block.ndim != 2 or block.shape[1] != len(master_columns):
        raise ValueError(
            f"{where + ': ' if where else ''}a block of trace rows must have {len(master_columns)} "
            f"columns, got shape {block.shape}"
        )
    return block


class TraceAssembler:
    """Adds the derived columns to the master's rows, block by block (or all at once).

    Every derived column is a function of the row's own time and values, except the step index
    at a repeated time, which depends on the row before: the assembler keeps the last time it
    saw, so assembling a trace block by block gives the same rows as assembling it whole.
    ``roles`` maps role names to trace columns (``instance.variable``); the tracking error is
    the ``panel_angle`` role's column minus the reference.
    """

    def __init__(self, inputs: DriveInputs, roles: dict[str, str]):
        self.inputs, self.roles = inputs, dict(roles)
        self._panel_reference = inputs.panel_reference()
        self._rotor_reference = inputs.rotor_reference()
        self._previous_time: float | None = None

    def __call__(self, master_rows: pd.DataFrame) -> pd.DataFrame:
        """The next rows of the trace (the master's columns, then the derived ones)."""
        trace = master_rows.copy()
        time = trace["time"].to_numpy()
        trace["panel_angle_ref"] = self._panel_reference(time)
        trace["rotor_angle_ref"] = self._rotor_reference(time)
        index = step_indices(time, self.inputs.schedule, self._previous_time)
        trace["step_index"] = index.astype(float)
        trace["rotor_angle_cmd"] = self.inputs.sequencer.position(index)
        panel = self.roles.get("panel_angle")
        if panel in trace:
            trace["panel_angle_error"] = trace[panel] - trace["panel_angle_ref"]
        if len(time):
            self._previous_time = float(time[-1])
        return trace

    def columns(self, master_columns: list[str]) -> list[str]:
        """The assembled trace's columns for the master's columns."""
        derived = ["panel_angle_ref", "rotor_angle_ref", "step_index", "rotor_angle_cmd"]
        if self.roles.get("panel_angle") in master_columns:
            derived.append("panel_angle_error")
        return list(master_columns) + derived


def assemble_trace(master_trace: pd.DataFrame, inputs: DriveInputs, roles: dict[str, str]) -> pd.DataFrame:
    """Add the reference, the commanded position and the tracking error to the master's trace
    (:class:`TraceAssembler` on the whole trace)."""
    return TraceAssembler(inputs, roles)(master_trace)
