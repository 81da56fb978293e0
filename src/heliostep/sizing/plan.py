"""The plan of a sizing (:mod:`heliostep.sizing.size`): its cases and what they share."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from heliostep.scenario import Scenario, validate_scenario
from heliostep.scenario.catalogue import MotorCandidate
from heliostep.scenario.keys import apply_overrides
from heliostep.sizing.days import DaySelection
from heliostep.sweep.band import ParameterRange

__all__ = ["SizingCase", "SizingPlan", "case_scenario"]


@dataclass(frozen=True)
class SizingCase:
    """One simulation: a candidate at a current on a day, as ``--set``-style overrides of the scenario;
    ``at_worst_corner``: the day again with the drive physics' ranges at their worst corner (the band's
    days, :attr:`SizingPlan.corner`)."""

    candidate: str
    current: float  # [A]
    day_of_year: int
    overrides: tuple[str, ...]
    at_worst_corner: bool = False

    @property
    def key(self) -> str:
        return f"{self.candidate}@{self.current:g}A/day{self.day_of_year}" + (
            "/worst-corner" if self.at_worst_corner else ""
        )


@dataclass
class SizingPlan:
    """Everything ``heliostep size`` will do, checked before any simulation."""

    scenario: Scenario
    raw: dict  # the scenario file's mapping (each case applies its overrides to a copy)
    folder: Path
    candidates: list[MotorCandidate]
    days: list[int]
    wind_moment: float | None  # [N.m] on the panel axis; None: the scenario's wind over time
    wind_source: str
    safety_factor: float
    curve_rates: tuple[float, ...]
    cases: list[SizingCase] = field(default_factory=list)
    mechanics: dict[str, float] = field(default_factory=dict)  # T_c, M_c, J_p
    fmu_paths: dict[str, Path] = field(default_factory=dict)  # instance -> FMU, resolved once for every case
    day_selection: DaySelection | None = None  # the days and why each (heliostep.sizing.days)
    ranges: tuple[ParameterRange, ...] = ()  # the drive physics' ranges (heliostep.sizing.band)
    corner: dict[str, float] = field(default_factory=dict)  # the worst corner's values the band's days set


def case_scenario(raw: dict, overrides: Sequence[str], source: str, folder: Path) -> Scenario:
    """A case's scenario: the file's mapping with the case's overrides, validated."""
    data = apply_overrides(copy.deepcopy(raw), overrides, source)
    return validate_scenario(data, source=source, folder=folder)
