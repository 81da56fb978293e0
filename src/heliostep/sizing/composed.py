"""A sizing's day cases composed from step families (:mod:`heliostep.run.step_family`), certified.

The cases of one candidate at one current (and at the band's corner) share a drive, so a family; each
family's days are composed from it in a process of the pool (:mod:`heliostep.sizing.pool`), and a sample of
them, spread over the days, is also co-simulated in full: its records carry each certified figure's
deviation. A family whose certificate exceeds a tolerance, or that cannot be built, has its days
co-simulated in full, as has a day that leaves what a family assumes.
The same rules as a sweep's (:mod:`heliostep.sweep.composed`); method: docs/sweep.md.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from heliostep.drive.inputs import prepare_inputs
from heliostep.run.step_family import build_family, compose_case, family_key, not_composable
from heliostep.sizing.case import CASE_FIGURES, CERTIFIED_CASE_FIGURES, run_sizing_case
from heliostep.sizing.plan import SizingCase, SizingPlan, case_scenario
from heliostep.sizing.pool import on_every_core
from heliostep.sweep.certificate import (
    CERTIFICATE_CASES,
    certificate_sample,
    certified_row,
    failed_figures,
    window_seconds,
)

__all__ = ["FamilyTask", "compose_days"]


def compose_days(
    plan: SizingPlan,
    on_record: Callable[[SizingCase, dict], None],
    should_stop: Callable[[], bool] | None = None,
    certify: int = CERTIFICATE_CASES,
    seed: int = 0,
    workers: int | None = None,
) -> list[tuple[SizingCase, str]]:
    """Compose the plan's cases that families can, a family a task on every core
    (:func:`heliostep.sizing.pool.on_every_core`; ``workers``: how many), each record (with its ``method`` and,
    on a certificate's, ``deviation_<figure>``) to ``on_record`` as its family finishes. Returns the cases left
    to co-simulate in full, each with why (those of families a stop kept from beginning among them)."""
    left: list[tuple[SizingCase, str]] = []
    groups: dict[str, list] = {}
    for case in plan.cases:
        scenario = case_scenario(plan.raw, case.overrides, plan.scenario.source, plan.folder)
        reason = not_composable(scenario)
        if reason is not None:
            left.append((case, reason))
        else:
            groups.setdefault(family_key(scenario), []).append((case, window_seconds(scenario)))
    sample = certificate_sample({key: [d for _, d in group] for key, group in groups.items()}, certify, seed)
    tasks = {}
    for key, group in groups.items():
        cases = tuple(case for case, _ in group)
        if sample[key] is None:
            left += [(case, "too few cases for a family to pay") for case in cases]
        else:
            tasks[key] = FamilyTask(
                plan.raw, plan.scenario.source, str(plan.folder), plan.fmu_paths, cases, tuple(sample[key])
            )

    def done(key: str, outcome: tuple[list, list]) -> None:
        records, fell_back = outcome
        for case, record in records:
            on_record(case, record)
        left.extend(fell_back)

    finished, _ = on_every_core(tasks, should_stop, workers, done)
    for key, task in tasks.items():
        if key not in finished:  # a stop kept it from beginning
            left += [(case, "stopped before its family") for case in task.cases]
    return left


@dataclass(frozen=True)
class FamilyTask:
    """One family's days (``cases``, with the positions of its certificate's in ``sample``), composed where a
    pool's process runs it: its certificate co-simulated in full and compared, then (it holds) the rest
    composed, or (it does not, or the family cannot be built) all of them left to run in full. Returns the
    records and the cases left, each with why."""

    raw: dict
    source: str
    folder: str
    fmu_paths: Mapping[str, Path]
    cases: tuple[SizingCase, ...]
    sample: tuple[int, ...]

    def __call__(self) -> tuple[list, list]:
        folder = Path(self.folder)
        scenarios = [case_scenario(self.raw, case.overrides, self.source, folder) for case in self.cases]
        try:
            family = build_family(scenarios[0])
        except Exception as exc:  # noqa: BLE001 - the days run in full, which reports what is wrong
            return [], [(case, f"no family: {str(exc)[:200]}") for case in self.cases]
        composed: dict[str, dict] = {}
        left: list[tuple[SizingCase, str]] = []
        for case, scenario in zip(self.cases, scenarios):
            started = clock.perf_counter()
            composition = compose_case(scenario, family, prepare_inputs(scenario))
            if composition.fallback is not None:
                left.append((case, composition.fallback))
                continue
            figures = {name: composition.figures.get(name) for name in CASE_FIGURES}
            composed[case.key] = {**figures, "complete": True, "wall_time_s": clock.perf_counter() - started}
        records, certificate = [], []
        for index in self.sample:
            case = self.cases[index]
            if case.key in composed:  # (one that fell back runs in full among the rest)
                full = run_sizing_case(self.raw, case.overrides, self.source, self.folder, None, self.fmu_paths)
                certificate.append(certified_row(full, composed.pop(case.key), CERTIFIED_CASE_FIGURES))
                records.append((case, certificate[-1]))
        failed = failed_figures(certificate, CERTIFIED_CASE_FIGURES)
        for case in self.cases:
            if case.key in composed and failed:
                left.append((case, f"the family's certificate fails on {', '.join(failed)}"))
            elif case.key in composed:
                records.append((case, {**composed[case.key], "method": "composed"}))
        return records, left
