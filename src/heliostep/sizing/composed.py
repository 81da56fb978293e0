"""A sizing's day cases composed from step families (:mod:`heliostep.run.step_family`), certified.

The cases of one candidate at one current (and at the band's corner) share a drive, so a family; each
family's days are composed from it, and a sample of them, spread over the days, is also co-simulated in
full: its records carry each certified figure's deviation. A family whose certificate exceeds a tolerance,
or that cannot be built, has its days co-simulated in full, as has a day that leaves what a family assumes.
The same rules as a sweep's (:mod:`heliostep.sweep.composed`); method: docs/sweep.md.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Sequence

from heliostep.drive.inputs import prepare_inputs
from heliostep.run.step_family import build_family, compose_case, family_key, not_composable
from heliostep.sizing.plan import SizingCase, SizingPlan, case_scenario
from heliostep.sweep.certificate import (
    CERTIFICATE_CASES,
    certificate_sample,
    certified_row,
    failed_figures,
    window_seconds,
)

__all__ = ["CASE_FIGURES", "compose_days"]

#: A day case's figures in the sheet's records.
CASE_FIGURES = (
    "max_tracking_error_deg",
    "steps_commanded",
    "missed_steps",
    "steps_lost",
    "electrical_energy_J",
    "drive_energy_per_day_J",
    "drive_power_mean_W",
    "peak_torque_Nm",
    "peak_phase_current_A",
    "light_energy_ideal_J",
    "light_energy_J",
    "light_lost_J",
    "light_lost_stowed_J",
    "stowed_time_s",
)


def compose_days(
    plan: SizingPlan,
    run_full: Callable[[SizingCase], dict],
    on_record: Callable[[SizingCase, dict], None],
    should_stop: Callable[[], bool] | None = None,
    certify: int = CERTIFICATE_CASES,
    seed: int = 0,
) -> list[tuple[SizingCase, str]]:
    """Compose the plan's cases that families can, here, one family after another: each record (with its
    ``method`` and, on a certificate's, ``deviation_<figure>``) to ``on_record``; ``run_full(case)`` runs a
    certificate's case in full. Returns the cases left to co-simulate in full, each with why."""
    left: list[tuple[SizingCase, str]] = []
    groups: dict[str, list] = {}
    for case in plan.cases:
        scenario = case_scenario(plan.raw, case.overrides, plan.scenario.source, plan.folder)
        reason = not_composable(scenario)
        if reason is not None:
            left.append((case, reason))
        else:
            groups.setdefault(family_key(scenario), []).append((case, scenario))
    durations = {key: [window_seconds(scenario) for _, scenario in group] for key, group in groups.items()}
    sample = certificate_sample(durations, certify, seed)
    for key, group in groups.items():
        if should_stop is not None and should_stop():
            break
        if sample[key] is None:
            left += [(case, "too few cases for a family to pay") for case, _ in group]
            continue
        left += _compose_family(group, sample[key], run_full, on_record, should_stop)
    return left


def _compose_family(group, sample: Sequence[int], run_full, on_record, should_stop) -> list[tuple[SizingCase, str]]:
    """One family's cases: its certificate run in full and compared, then (it holds) the rest composed and
    recorded, or (it does not, or the family cannot be built) all of them left to run in full."""
    try:
        family = build_family(group[0][1], should_stop)
    except InterruptedError:
        return []
    except Exception as exc:  # noqa: BLE001 - the days run in full, which reports what is wrong
        return [(case, f"no family: {str(exc)[:200]}") for case, _ in group]
    composed: dict[str, dict] = {}
    left: list[tuple[SizingCase, str]] = []
    for case, scenario in group:
        if should_stop is not None and should_stop():
            return left
        started = clock.perf_counter()
        composition = compose_case(scenario, family, prepare_inputs(scenario))
        if composition.fallback is not None:
            left.append((case, composition.fallback))
            continue
        figures = {name: composition.figures.get(name) for name in CASE_FIGURES}
        composed[case.key] = {**figures, "complete": True, "wall_time_s": clock.perf_counter() - started}
    certificate = []
    for index in sample:
        case = group[index][0]
        if case.key not in composed:
            continue  # fell back: run in full among the rest
        full = run_full(case)
        if full.get("interrupted"):
            return left
        certificate.append(certified_row(full, composed.pop(case.key)))
        on_record(case, certificate[-1])
    failed = failed_figures(certificate)
    for case, _ in group:
        if case.key in composed:
            if failed:
                left.append((case, f"the family's certificate fails on {', '.join(failed)}"))
            else:
                on_record(case, {**composed[case.key], "method": "composed"})
    return left
