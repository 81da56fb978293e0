"""The sizing's uncertainty band: each candidate's margins over the corners of the drive physics' ranges.

Details: docs/sizing.md, ``heliostep.sizing.band``.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence

from heliostep.run.load_budget import LoadBudget, static_step_limit
from heliostep.scenario.catalogue import MotorDrive
from heliostep.sweep.band import ParameterRange

__all__ = ["DRIVE_FIELDS", "corner_parameters", "corners", "drive_at", "margin_band", "worst_corner"]

#: Motor FMU parameters (``StepperMotor``'s names) -> the MotorDrive field they set.
DRIVE_FIELDS = {"V_supply": "bus_voltage", "K_current": "current_gain"}
#: The end of each range that lowers the deliverable torque ("low" or "high").
WORST_END = {"V_supply": "low", "K_current": "low", "B_m": "high"}


def _name(key: str, motor: str) -> str | None:
    """The motor parameter a range's key sets (None: another instance's, or a scenario key)."""
    parts = key.split(".")
    return parts[2] if len(parts) == 3 and parts[0] == "parameters" and parts[1] == motor else None


def corners(ranges: Sequence[ParameterRange]) -> list[dict[str, float]]:
    """Every combination of the ranges' ends: key -> value."""
    return [dict(zip([r.key for r in ranges], ends)) for ends in itertools.product(*[(r.low, r.high) for r in ranges])]


def drive_at(drive: MotorDrive, values: dict[str, float], motor: str = "motor") -> MotorDrive:
    """``drive`` with the motor parameters among ``values`` (bus, loop gain) set."""
    fields = {}
    for key, value in values.items():
        name = _name(key, motor)
        if name in DRIVE_FIELDS:
            fields[DRIVE_FIELDS[name]] = float(value)
    return dataclasses.replace(drive, **fields)


def worst_corner(ranges: Sequence[ParameterRange]) -> dict[str, float]:
    """The corner at which every key is at the end that lowers the deliverable torque (:data:`WORST_END`);
    a key not listed there at its low end."""
    return {r.key: (r.high if WORST_END.get(r.key.rsplit(".", 1)[-1]) == "high" else r.low) for r in ranges}


def corner_parameters(corner: dict[str, float], instances: Sequence[str]) -> dict[str, float]:
    """The FMU parameters (``parameters.<instance>.<name>``) of a corner that the scenario's ``instances``
    have: what the days co-simulated again at it set; a key of another instance, or a scenario key (the
    current, which each case sets itself), is left out."""
    return {
        key: value
        for key, value in corner.items()
        if len(parts := key.split(".")) == 3 and parts[0] == "parameters" and parts[1] in instances
    }


def margin_band(
    drive: MotorDrive,
    current: float,
    budget: LoadBudget,
    ranges: Sequence[ParameterRange],
    sequencer,
    motor: str = "motor",
) -> dict:
    """The tracking and idle margins [1] at every corner of ``ranges``: their least and largest, the corner
    of the least tracking margin, and which keys entered the figures."""
    tracking, idle = [], []
    for values in corners(ranges):
        varied = drive_at(drive, values, motor)
        limit = static_step_limit(varied, current, sequencer.mode, sequencer.microsteps)
        held = varied.holding_torque(current * sequencer.idle_current_fraction)
        tracking.append((limit / budget.total_Nm if budget.total_Nm > 0 else float("inf"), values))
        idle.append(held / budget.wind_Nm if budget.wind_Nm > 0 else float("inf"))
    least = min(tracking, key=lambda item: item[0])
    entered = [r.key for r in ranges if _name(r.key, motor) == "K_current"]
    return {
        "corners": len(tracking),
        "tracking_margin_min": least[0],
        "tracking_margin_max": max(value for value, _ in tracking),
        "idle_margin_min": min(idle),
        "idle_margin_max": max(idle),
        "least_tracking_corner": least[1],
        "keys_in_the_margins": entered,
        "keys_not_in_the_margins": [r.key for r in ranges if r.key not in entered],
    }
