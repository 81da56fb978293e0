"""Regression of the shipped scenarios against their reference traces: ``heliostep regress``.

Each ``scenarios/NAME.yaml`` keeps its reference trace beside it as
``scenarios/NAME.reference.parquet``: only the signals in :data:`REFERENCE_SIGNALS`, on the
run's own output grid (regular grid, fine grid after each step, rows before/after each
step). ``heliostep regress`` runs the scenarios and compares each with its reference by the
tolerance tube of :mod:`heliostep.compare`, with the tolerances of
``scenarios/regress-tolerances.yaml``; ``--update`` rewrites the references on purpose and
says what changed against the old ones.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from heliostep.build import PROJECT_ROOT
from heliostep.compare import ComparisonResult, ToleranceSet, compare_traces, load_tolerances
from heliostep.compare_cli import format_table
from heliostep.errors import InputError
from heliostep.run import RunFailed, run_scenario
from heliostep.trace_io import read_trace, write_trace

#: The signals a reference trace keeps: what a model or FMU change must not move unnoticed.
REFERENCE_SIGNALS = ("mechanics.theta", "mechanics.theta_p", "panel_angle_error", "rotor_angle_cmd",
                     "motor.tau", "motor.i_a", "motor.i_b")
SCENARIO_DIR = PROJECT_ROOT / "scenarios"
TOLERANCES = SCENARIO_DIR / "regress-tolerances.yaml"


def reference_path(scenario: Path) -> Path:
    """Where a scenario's reference trace lives: beside it, ``NAME.reference.parquet``."""
    return scenario.with_name(scenario.stem + ".reference.parquet")


def shipped_scenarios(folder: Path = SCENARIO_DIR) -> list[Path]:
    """The scenarios that have a reference trace."""
    return sorted(p for p in folder.glob("*.yaml") if reference_path(p).exists())


@dataclass
class Outcome:
    """One scenario's regression: its comparison, or why there is none."""

    scenario: Path
    comparison: ComparisonResult | None
    problem: str | None = None

    @property
    def passed(self) -> bool:
        return self.problem is None and self.comparison is not None and self.comparison.passed


def regress_one(scenario: Path, tolerances: ToleranceSet, update: bool = False,
                report_dir: Path | None = None) -> Outcome:
    """Run ``scenario`` and compare it with its reference (or rewrite the reference)."""
    reference_file = reference_path(scenario)
    if not update and not reference_file.exists():
        raise InputError(f"{scenario}: no reference trace {reference_file.name}; "
                         f"create it with: heliostep regress --update {scenario}")
    try:
        run = run_scenario(scenario)
    except RunFailed as failed:
        return Outcome(scenario, None, f"the run failed: {failed}")
    signals = [s for s in REFERENCE_SIGNALS if s in run.trace]
    actual = run.trace[["time", *signals]]
    comparison = None
    if reference_file.exists():
        reference, _ = read_trace(reference_file)
        common = [s for s in signals if s in reference]
        comparison = compare_traces(actual, reference, tolerances, common,
                                    actual_name=f"{scenario.name} (new run)", reference_name=str(reference_file))
        if report_dir is not None and not comparison.passed:
            from heliostep.plots.compare import write_report

            write_report(comparison, actual, reference, report_dir / scenario.stem, run.trace_metadata(), {})
    if update:
        write_trace(actual, reference_file, run.trace_metadata())
    return Outcome(scenario, comparison)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "regress", help="run scenarios and compare them with their reference traces",
        description="Run each scenario and compare its trace with scenarios/NAME.reference.parquet "
                    "(tolerance tube, tolerances from scenarios/regress-tolerances.yaml). "
                    "Exit status 0 all pass, 1 any deviation, 2 bad input.")
    parser.add_argument("scenarios", nargs="*", type=Path, metavar="SCENARIO",
                        help="scenario files (default: every scenario in scenarios/ with a reference)")
    parser.add_argument("--update", action="store_true",
                        help="rewrite the reference traces (and say what changed)")
    parser.add_argument("--tolerances", type=Path, default=TOLERANCES, metavar="FILE",
                        help="tolerance YAML (default: scenarios/regress-tolerances.yaml)")
    parser.add_argument("--report", type=Path, metavar="DIR", help="write a report per failing scenario here")
    parser.set_defaults(func=_run_regress)


def _run_regress(args: argparse.Namespace) -> int:
    scenarios = args.scenarios or shipped_scenarios()
    if not scenarios:
        raise InputError(f"{SCENARIO_DIR}: no scenario has a reference trace; create them with "
                         "heliostep regress --update SCENARIO")
    tolerances = load_tolerances(args.tolerances)
    status = 0
    for scenario in scenarios:
        outcome = regress_one(scenario, tolerances, args.update, args.report)
        if outcome.problem:
            print(f"{scenario}: FAIL: {outcome.problem}")
            status = 1
            continue
        if outcome.comparison is None:
            print(f"{scenario}: reference written ({reference_path(scenario).name})")
            continue
        verdict = "PASS" if outcome.passed else ("CHANGED" if args.update else "FAIL")
        print(f"{scenario}: {verdict}")
        if not outcome.passed or args.update:
            print(format_table(outcome.comparison))
        if args.update:
            print(f"  reference rewritten: {reference_path(scenario).name}")
        elif not outcome.passed:
            status = 1
    return status
