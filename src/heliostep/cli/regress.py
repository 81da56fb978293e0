"""``heliostep regress``: run scenarios and compare them with their reference traces."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from heliostep.cli.signals import stop_requests
from heliostep.errors import InputError
from heliostep.results.compare import format_table, load_tolerances
from heliostep.results.regress import (
    Outcome,
    check_against_reference,
    reference_path,
    shipped_scenarios,
    tolerances_path,
)
from heliostep.run import RunFailed, run_scenario


def regress_one(
    scenario: Path,
    tolerances,
    update: bool = False,
    report_dir: Path | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> Outcome:
    """Run ``scenario`` and compare it with its reference (or rewrite the reference); ``should_stop``
    as for :func:`~heliostep.run.run_scenario` (a stopped run is an outcome with a problem)."""
    if not update and not reference_path(scenario).exists():
        raise InputError(
            f"{scenario}: no reference trace {reference_path(scenario).name}; "
            f"create it with: heliostep regress --update {scenario}"
        )
    try:
        run = run_scenario(scenario, should_stop=should_stop, supervise=True)  # a crashing FMU fails this one only
    except RunFailed as failed:
        return Outcome(scenario, None, f"the run failed: {failed}")
    metadata = run.trace_metadata()
    outcome = check_against_reference(
        scenario, run.trace, metadata, run.metadata["roles"], tolerances.for_scenario(run.scenario.name), update
    )
    if report_dir is not None and outcome.comparison is not None and not outcome.comparison.passed:
        from heliostep.plots.compare import write_report

        write_report(outcome.comparison, outcome.actual, outcome.reference, report_dir / scenario.stem, metadata, {})
    return outcome


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "regress",
        help="run scenarios and compare them with their reference traces",
        description="Run each scenario and compare its trace with scenarios/NAME.reference.parquet "
        "(tolerance tube, tolerances from scenarios/regress-tolerances.yaml). "
        "Exit status 0 all pass, 1 any deviation, 2 bad input.",
    )
    parser.add_argument(
        "scenarios",
        nargs="*",
        type=Path,
        metavar="SCENARIO",
        help="scenario files (default: every shipped scenario with a reference)",
    )
    parser.add_argument("--update", action="store_true", help="rewrite the reference traces (and say what changed)")
    parser.add_argument(
        "--tolerances",
        type=Path,
        default=None,
        metavar="FILE",
        help="tolerance YAML (default: scenarios/regress-tolerances.yaml)",
    )
    parser.add_argument("--report", type=Path, metavar="DIR", help="write a report per failing scenario here")
    parser.set_defaults(func=_run_regress)


def _run_regress(args: argparse.Namespace) -> int:
    scenarios = args.scenarios or shipped_scenarios()
    if not scenarios:
        raise InputError(
            "no shipped scenario has a reference trace; create them with heliostep regress --update SCENARIO"
        )
    tolerances = load_tolerances(args.tolerances or tolerances_path())
    with stop_requests() as stop:  # SIGINT/SIGTERM: the run stops, its temporary files go, exit 130/143
        return _regress_all(args, scenarios, tolerances, stop)


def _regress_all(args: argparse.Namespace, scenarios, tolerances, stop) -> int:
    status = 0
    for scenario in scenarios:
        outcome = regress_one(scenario, tolerances, args.update, args.report, stop.is_set)
        if stop.is_set():
            print(f"{scenario}: stopped by {stop.name}; nothing compared or written", file=sys.stderr)
            return stop.exit_status
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
