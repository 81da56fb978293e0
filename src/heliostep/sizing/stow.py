"""The margin to slip while stowing: a stow move's load against the pull-out torque at its step rate.

Details: docs/sizing.md, ``heliostep.sizing.stow``.
"""

from __future__ import annotations

import numpy as np

from heliostep.drive.inputs import prepare_inputs
from heliostep.run.load_budget import stow_load
from heliostep.run.speed_torque import SpeedTorqueCurve
from heliostep.scenario.catalogue import MotorCandidate, MotorDrive
from heliostep.sizing.days import panel_angle_range
from heliostep.sizing.plan import SizingPlan, case_scenario

__all__ = ["ANGLE_POINTS", "stow_angles", "stow_margin", "stow_step_rates"]

#: Panel angles at which a stow move's load and margin are evaluated.
ANGLE_POINTS = 181


def stow_angles(plan: SizingPlan) -> np.ndarray | None:
    """The panel angles a stow or return move travels [rad]: from ``wind.stow_angle`` to the farthest
    tracking angle of the year: the ideal panel angle within the window on each of its 365 days
    (:func:`heliostep.sizing.days.panel_angle_range`, the sun up), and the tracking reference of the
    days simulated (each day's reference, the first candidate's cases); None when the scenario never
    stows. A wind may call for a stow on any day, not only on those simulated."""
    wind = plan.scenario.wind
    if wind.stow_speed is None or not plan.cases:
        return None
    low = high = float(np.radians(wind.stow_angle))
    year = panel_angle_range(plan.scenario)
    if year is not None:
        low, high = min(low, year[0]), max(high, year[1])
    first = plan.cases[0].candidate
    for case in plan.cases:
        if case.candidate == first and case.current == plan.cases[0].current and not case.at_worst_corner:
            scenario = case_scenario(plan.raw, case.overrides, plan.scenario.source, plan.folder)
            panel = prepare_inputs(scenario).panel_angle_ref
            low, high = min(low, float(np.min(panel))), max(high, float(np.max(panel)))
    return np.linspace(low, high, ANGLE_POINTS)


def stow_step_rates(plan: SizingPlan, candidate: MotorCandidate, angles: np.ndarray | None) -> np.ndarray:
    """The step rates of a stow move [full steps/s] at ``angles`` (empty when it never stows)."""
    if angles is None:
        return np.zeros(0)
    drive = candidate.drive()
    load = stow_load(plan.scenario, angles, plan.mechanics, drive.rotor_inertia, drive.step_angle)
    return np.zeros(0) if load is None else load.step_rate_per_s


def stow_margin(
    plan: SizingPlan,
    candidate: MotorCandidate,
    current: float,
    step_limit: float,
    curve: SpeedTorqueCurve | None,
    angles: np.ndarray | None,
    drive: MotorDrive | None = None,
) -> dict | None:
    """The margin to slip while stowing at ``current`` [A] and its worst angle's figures (module
    docstring); None without a stow or a curve. ``drive``: the candidate's drive with other parameters
    (e.g. at the ranges' worst corner, with that corner's ``curve`` and ``step_limit``); by default its own."""
    if angles is None or curve is None:
        return None
    drive = drive if drive is not None else candidate.drive()
    load = stow_load(plan.scenario, angles, plan.mechanics, drive.rotor_inertia, drive.step_angle)
    if load is None:
        return None
    scale = drive.holding_torque(current) / drive.holding_torque(curve.current)
    pull_out = np.array([curve.at(rate) for rate in load.step_rate_per_s]) * scale
    deliverable = np.minimum(pull_out, step_limit)
    margins = np.where(load.total_Nm > 0, deliverable / np.where(load.total_Nm > 0, load.total_Nm, 1.0), np.inf)
    worst = int(np.argmin(margins))
    wind = plan.scenario.wind
    return {
        "stow_margin": float(margins[worst]),
        "stow_load": {
            "stow_speed_m_s": float(wind.stow_speed) if wind.stow_speed is not None else None,
            "slew_rate_deg_s": float(wind.slew_rate),
            "angles_travelled_deg": [float(np.degrees(angles[0])), float(np.degrees(angles[-1]))],
            "panel_angle_deg": float(np.degrees(load.panel_angles[worst])),
            "ratio": float(load.ratio[worst]),
            "step_rate_per_s": float(load.step_rate_per_s[worst]),
            "wind_moment_Nm": float(load.wind_moment_Nm[worst]),
            "wind_Nm": float(load.wind_Nm[worst]),
            "friction_Nm": float(load.friction_Nm[worst]),
            "inertia_Nm": float(load.inertia_Nm[worst]),
            "total_Nm": float(load.total_Nm[worst]),
            "pull_out_Nm": float(pull_out[worst]),
            "deliverable_Nm": float(deliverable[worst]),
        },
    }
