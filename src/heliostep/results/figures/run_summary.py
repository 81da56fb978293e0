"""The typed shape of a run's figures (``summary.json``) and metadata (``metadata.json``).

:class:`RunSummary` holds every figure of a run (the definitions: :mod:`heliostep.results.figures.summary`);
its field names are the keys of ``summary.json``. :func:`summary_record` is the one function
that makes ``summary.json`` of a run: its status (:class:`RunStatus`), then
:meth:`RunSummary.figures`. :func:`night` says whether the sun stays below the horizon over
the window (every run's summary says so). :class:`RunMetadata` is the shape of a run's metadata.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, TypedDict

import numpy as np
import pandas as pd

from heliostep.results.figures.steps import JudgedSteps, Settling
from heliostep.solar import solar_position

__all__ = [
    "STEP_FIELDS",
    "Peaks",
    "RunMetadata",
    "RunStatus",
    "RunSummary",
    "StepFigures",
    "Tracking",
    "night",
    "status_record",
    "summary_record",
]


@dataclass(frozen=True)
class Tracking:
    """The tracking error: the panel angle minus its reference [deg]."""

    max_tracking_error_deg: float
    rms_tracking_error_deg: float


@dataclass(frozen=True)
class Peaks:
    """Peak magnitudes over every solver step (None: the FMUs have no such output)."""

    peak_torque_Nm: float | None
    peak_phase_current_A: float | None


@dataclass(frozen=True)
class StepFigures:
    """The figures that judge the steps."""

    missed_steps: int
    steps_executed: int
    settling_time_s: Settling
    missed_step_times_s: list[float]
    steps_lost: int
    final_lag_steps: float

    @classmethod
    def of(cls, judged: JudgedSteps, lost: tuple[int, float]) -> StepFigures:
        """From the judged steps and (steps lost, elastic lag left) [increments]."""
        return cls(
            judged.missed_steps,
            judged.steps_executed,
            judged.settling_time_s,
            judged.missed_step_times_s,
            lost[0],
            lost[1],
        )


#: The summary's keys that depend on judging each step (what the summary at a cut recomputes).
STEP_FIELDS = ("steps_commanded", *(f.name for f in dataclasses.fields(StepFigures)))


@dataclass(frozen=True)
class RunSummary:
    """Every figure of a run, in the order of ``summary.json``; a part that is None is absent
    from it (no such role, too few rows, or nothing to say)."""

    duration_s: float  # [s] first to last trace row
    rows: int  # trace rows
    tracking: Tracking | None
    peaks: Peaks | None
    electrical_energy_J: float | None
    steps_commanded: int | None
    steps: StepFigures | None
    figures_from: str  # "solution" (every solver step) or "output rows" (a stored trace without them)
    final_panel_angle_deg: float | None
    light: dict[str, Any] | None = None  # light on the tube (results.light.LightIntegrals.figures)
    tradeoffs: dict[str, Any] | None = None  # holding torque, energy per day (results.tradeoffs)
    wind: dict[str, Any] | None = None  # the wind's peak moment, the stow moves (results.stow)
    step_in_progress_at_cut_s: float | None = None  # an interrupted run: the step not judged [s]
    night: bool | None = None  # the sun below the horizon during the whole window
    night_warning: str | None = None

    def figures(self) -> dict[str, Any]:
        """The figures as ``summary.json`` holds them (after the status)."""
        record: dict[str, Any] = {"duration_s": self.duration_s, "rows": self.rows}
        for part in (self.tracking, self.peaks):
            if part is not None:
                record.update(dataclasses.asdict(part))
        if self.electrical_energy_J is not None:
            record["electrical_energy_J"] = self.electrical_energy_J
        if self.steps_commanded is not None:
            record["steps_commanded"] = self.steps_commanded
        if self.steps is not None:
            record.update(dataclasses.asdict(self.steps))
        record["figures_from"] = self.figures_from
        if self.final_panel_angle_deg is not None:
            record["final_panel_angle_deg"] = self.final_panel_angle_deg
        for figures in (self.light, self.tradeoffs, self.wind):
            if figures is not None:
                record.update(figures)
        if self.step_in_progress_at_cut_s is not None:
            record["step_in_progress_at_cut_s"] = self.step_in_progress_at_cut_s
        if self.night is not None:
            record["night"] = self.night
        if self.night_warning is not None:  # after the other warnings, if any
            record["warnings"] = [*record.get("warnings", []), self.night_warning]
        return record


@dataclass(frozen=True)
class RunStatus:
    """How a run ended: ``complete``, else ``reason`` ("failed" or "interrupted"), the error and
    the simulated time reached [s]."""

    complete: bool
    error: str | None = None
    reason: str | None = None
    time_reached: float | None = None


def status_record(status: RunStatus) -> dict[str, Any]:
    """The status keys that open ``summary.json`` and ``metadata.json``."""
    record: dict[str, Any] = {"complete": status.complete, "error": status.error}
    if not status.complete:
        record["reason"] = status.reason or "failed"
        record["time_reached_s"] = status.time_reached
    return record


def summary_record(
    summary: RunSummary | None, status: RunStatus, terminated: dict[str, Any] | None = None
) -> dict[str, Any]:
    """What ``summary.json`` holds: the status, the termination an FMU asked for (``terminated``: which
    instances, when [s], why; also when it came at the window's end and the run is complete), then the
    figures (none without a trace row)."""
    record = status_record(status)
    if terminated:
        record["terminated"] = dict(terminated)
    return {**record, **(summary.figures() if summary is not None else {})}


def night(site, window_start: pd.Timestamp, duration: float) -> tuple[bool, str | None]:
    """(night, warning): whether the sun is below the horizon during the whole window (97 instants
    from ``window_start`` over ``duration`` [s]; ``site`` with latitude, longitude [deg] and
    altitude [m]), and the warning that says so (None by day)."""
    times = window_start + pd.to_timedelta(np.linspace(0.0, duration, 97), unit="s")
    elevation = solar_position(pd.DatetimeIndex(times), site.latitude, site.longitude, site.altitude)["elevation"]
    is_night = bool((elevation.to_numpy() <= 0.0).all())
    if not is_night:
        return False, None
    return True, (
        f"the sun is below the horizon during the whole window ({window_start} + "
        f"{duration:g} s): the drive holds still and the figures are those of a night"
    )


class RunMetadata(TypedDict, total=False):
    """A run's metadata (``metadata.json`` after the status keys)."""

    heliostep: str  # version
    python: str
    packages: dict[str, str]  # package -> version
    scenario: dict[str, Any]  # the resolved scenario
    fmus: dict[str, dict[str, str]]  # instance -> path, sha256, guid
    communication_intervals: dict[str, dict[str, Any]]  # sampled instance -> interval_s, from (scenario or FMU)
    parameters: dict[str, dict[str, Any]]  # instance -> name -> value
    roles: dict[str, str]  # role -> trace column
    drive: dict[str, Any]  # results.trace.drive_metadata
    window_start: str  # ISO 8601
    timezone: str
    units: dict[str, str]  # trace column -> unit
    statistics: dict[str, Any]  # the master's counters, wall time, memory
    terminated: dict[str, Any]  # an FMU asked to stop: by whom, when [s]
    solution_figures: dict[str, Any]  # results.solution.SolutionRecorder.figures
    motor: dict[str, Any]  # heliostep run --motor: the catalogue entry (MotorCandidate.record), catalogue, current
