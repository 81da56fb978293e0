"""Regression of the shipped scenarios against their reference traces: ``heliostep regress``.

Details: docs/compare.md, ``heliostep.results.compare.regress``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from heliostep.errors import InputError
from heliostep.paths import scenarios_dir
from heliostep.results.compare.traces import ComparisonResult, ToleranceSet, compare_traces
from heliostep.results.trace.files import read_trace, write_trace

#: The signals a reference trace keeps, by role (the FMU columns) or by name (the derived
#: columns): what a model or FMU change must not move unnoticed.
REFERENCE_ROLES = ("rotor_angle", "panel_angle", "torque", "current_a", "current_b")
REFERENCE_COLUMNS = ("panel_angle_error", "rotor_angle_cmd")


def tolerances_path() -> Path:
    """The shipped regression tolerances (``scenarios/regress-tolerances.yaml``)."""
    return scenarios_dir() / "regress-tolerances.yaml"


def reference_signals(roles: Mapping[str, str]) -> list[str]:
    """The trace columns a reference keeps for a run with these roles."""
    by_role = {role: roles[role] for role in REFERENCE_ROLES if role in roles}
    ordered = [
        by_role.get("rotor_angle"),
        by_role.get("panel_angle"),
        *REFERENCE_COLUMNS,
        by_role.get("torque"),
        by_role.get("current_a"),
        by_role.get("current_b"),
    ]
    return [column for column in ordered if column]


def reference_path(scenario: Path) -> Path:
    """Where a scenario's reference trace lives: beside it, ``NAME.reference.parquet``
    (:class:`~heliostep.errors.InputError` when the scenario file itself is not there)."""
    if not scenario.is_file():
        raise InputError(f"{scenario}: scenario file not found")
    return scenario.with_name(scenario.stem + ".reference.parquet")


def shipped_scenarios(folder: Path | None = None) -> list[Path]:
    """The scenarios that have a reference trace (default: the shipped ones)."""
    folder = scenarios_dir() if folder is None else Path(folder)
    return sorted(p for p in folder.glob("*.yaml") if reference_path(p).exists())


@dataclass
class Outcome:
    """One scenario's regression: its comparison, or why there is none."""

    scenario: Path
    comparison: ComparisonResult | None
    problem: str | None = None
    #: the compared signals of the new run and of the reference (for a report)
    actual: pd.DataFrame | None = None
    reference: pd.DataFrame | None = None

    @property
    def passed(self) -> bool:
        return self.problem is None and self.comparison is not None and self.comparison.passed


def check_against_reference(
    scenario: Path,
    trace: pd.DataFrame,
    metadata: Mapping[str, str],
    roles: Mapping[str, str],
    tolerances: ToleranceSet,
    update: bool = False,
) -> Outcome:
    """Compare a run of ``scenario`` with its reference trace (or rewrite the reference).

    ``trace`` and ``metadata`` are the run's trace and trace metadata; ``roles`` names its
    columns. Only :func:`reference_signals` are compared and kept.
    """
    reference_file = reference_path(scenario)
    signals = [s for s in reference_signals(roles) if s in trace]
    actual = trace[["time", *signals]]
    comparison = None
    reference = None
    if reference_file.exists():
        reference, _ = read_trace(reference_file)
        common = [s for s in signals if s in reference]
        comparison = compare_traces(
            actual,
            reference,
            tolerances,
            common,
            actual_name=f"{scenario.name} (new run)",
            reference_name=str(reference_file),
        )
    if update:
        write_trace(actual, reference_file, metadata)
    return Outcome(scenario, comparison, actual=actual, reference=reference)
