"""The plan of a sizing (:mod:`heliostep.sizing.size`): its cases and what they share."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from heliostep.errors import InputError
from heliostep.run import HELD_TRACE_MAX_DURATION
from heliostep.run.estimate import RunEstimate, check_budget, estimate_run
from heliostep.scenario import Scenario, validate_scenario
from heliostep.scenario.catalogue import MotorCandidate
from heliostep.scenario.keys import apply_overrides
from heliostep.sizing.days import DaySelection
from heliostep.sweep.band import ParameterRange

__all__ = ["SizingCase", "SizingPlan", "case_scenario", "check_case_count", "check_cases", "count_cases"]


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
    mechanics: dict[str, float] = field(default_factory=dict)  # T_c, M_c, J_p, J_m (run.load_budget.mechanics_values)
    fmu_paths: dict[str, Path] = field(default_factory=dict)  # instance -> FMU, resolved once for every case
    day_selection: DaySelection | None = None  # the days and why each (heliostep.sizing.days)
    ranges: tuple[ParameterRange, ...] = ()  # the drive physics' ranges (heliostep.sizing.band)
    corner: dict[str, float] = field(default_factory=dict)  # the worst corner's values the band's days set
    inputs: dict = field(default_factory=dict)  # what it is sized for: the sheet's inputs (heliostep.sizing.inputs)


def case_scenario(raw: dict, overrides: Sequence[str], source: str, folder: Path) -> Scenario:
    """A case's scenario: the file's mapping with the case's overrides, validated."""
    data = apply_overrides(copy.deepcopy(raw), overrides, source)
    return validate_scenario(data, source=source, folder=folder)


def count_cases(candidates: Sequence[MotorCandidate], days: Sequence[int], at_worst_corner: bool) -> int:
    """The cases of a sizing, counted, not built: every candidate's currents on every day, twice with the
    days again at the worst corner."""
    return sum(len(candidate.currents) for candidate in candidates) * len(days) * (2 if at_worst_corner else 1)


def check_case_count(
    catalogue: str, candidates: Sequence[MotorCandidate], days: Sequence[int], at_worst_corner: bool, max_cases: int
) -> None:
    """Refuse (InputError) a sizing of more than ``max_cases`` cases, naming the catalogue entry whose currents
    or the ``--days`` that make it large, and the count; before any case is built."""
    count = count_cases(candidates, days, at_worst_corner)
    if count <= max_cases:
        return
    widest = max(candidates, key=lambda candidate: len(candidate.currents))
    if len(widest.currents) >= len(days):
        culprit = f"motors.{widest.name}.currents ({len(widest.currents):,} currents)"
        fewer = f"fewer currents in motors.{widest.name}"
    else:
        culprit, fewer = f"--days ({len(days):,} days)", "fewer --days"
    currents = sum(len(candidate.currents) for candidate in candidates)
    again = " x 2 (each day again at the worst corner; --no-band-days: once)" if at_worst_corner else ""
    raise InputError(
        f"{catalogue}: {culprit} makes the sizing too large: {currents:,} current(s) of {len(candidates)} "
        f"candidate(s) x {len(days):,} days{again} make {count:,} cases, over --max-cases = {max_cases:,}; "
        f"each case is a run: {fewer}, or size --max-cases N if meant"
    )


def check_cases(plan: SizingPlan) -> None:
    """The largest case's estimate (:func:`heliostep.run.estimate.estimate_run`, as a case runs: no trace kept)
    within the scenario's budget, then every case's scenario validated; an InputError before any case runs. A
    case's estimate depends on its candidate and day, not on its current or the worst corner: one per pair."""
    largest: tuple[SizingCase, Scenario, RunEstimate] | None = None
    estimated: dict[tuple[str, int], SizingCase] = {}
    for case in plan.cases:
        if (case.candidate, case.day_of_year) in estimated:
            continue
        estimated[case.candidate, case.day_of_year] = case
        scenario = case_scenario(plan.raw, case.overrides, plan.scenario.source, plan.folder)
        estimate = estimate_run(scenario, HELD_TRACE_MAX_DURATION, keep_trace=False)
        if largest is None or estimate.memory_bytes > largest[2].memory_bytes:
            largest = (case, scenario, estimate)
    if largest is not None:
        case, scenario, estimate = largest
        try:
            check_budget(scenario, estimate)
        except InputError as exc:
            raise InputError(f"the largest case, {case.key}: {exc}") from None
    validated = {case.key for case in estimated.values()}
    for case in plan.cases:
        if case.key not in validated:
            case_scenario(plan.raw, case.overrides, plan.scenario.source, plan.folder)
