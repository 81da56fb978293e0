"""``heliostep regress``: run scenarios and compare them with their reference traces."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

from heliostep.cli.compare import (
    add_annotations_option,
    annotations_root,
    annotations_wanted,
    check_output_dir,
    check_output_file,
)
from heliostep.cli.signals import stop_requests
from heliostep.errors import InputError
from heliostep.progress import over_bars, progress_bar
from heliostep.results.compare.regress import (
    Outcome,
    check_against_reference,
    reference_path,
    shipped_scenarios,
    tolerances_path,
)
from heliostep.results.compare.traces import format_table, load_tolerances
from heliostep.results.compare.verdicts import SuiteVerdict, github_annotations, junit_xml
from heliostep.run import RunFailed, RunOptions, run_scenario
from heliostep.scenario import resolve_scenario_path


def regress_one(
    scenario: Path,
    tolerances,
    update: bool = False,
    report_dir: Path | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> tuple[Outcome, dict[str, str]]:
    """Run ``scenario`` and compare it with its reference (or rewrite the reference); also the run's
    trace metadata (units, roles). ``should_stop`` as for :func:`~heliostep.run.run_scenario` (a stopped
    run is an outcome with a problem)."""
    if not update and not reference_path(scenario).exists():
        raise InputError(
            f"{scenario}: no reference trace {reference_path(scenario).name}; "
            f"create it with: heliostep regress --update {scenario}"
        )
    try:
        # supervised: a crashing FMU fails this one only
        run = run_scenario(scenario, RunOptions(should_stop=should_stop, supervise=True))
    except RunFailed as failed:
        return Outcome(scenario, None, f"the run failed: {failed}"), {}
    metadata = run.trace_metadata()
    outcome = check_against_reference(
        scenario, run.trace, metadata, run.metadata["roles"], tolerances.for_scenario(run.scenario.name), update
    )
    if report_dir is not None and outcome.comparison is not None and not outcome.comparison.passed:
        from heliostep.plots.compare import write_report

        write_report(outcome.comparison, outcome.actual, outcome.reference, report_dir / scenario.stem, metadata, {})
    return outcome, metadata


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
        help="scenario files or shipped scenarios' names (default: every shipped scenario with a reference)",
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
    parser.add_argument(
        "--junit",
        type=Path,
        metavar="FILE",
        help="write the verdicts as JUnit XML (a test case per scenario and signal)",
    )
    add_annotations_option(parser)
    parser.set_defaults(func=_run_regress)


def _run_regress(args: argparse.Namespace) -> int:
    scenarios = [resolve_scenario_path(path) for path in args.scenarios] or shipped_scenarios()
    if not scenarios:
        raise InputError(
            "no shipped scenario has a reference trace; create them with heliostep regress --update SCENARIO"
        )
    if args.report:
        check_output_dir(args.report, "--report")
    junit = check_output_file(args.junit, "--junit") if args.junit else None
    tolerances = load_tolerances(args.tolerances or tolerances_path())
    with stop_requests() as stop:  # SIGINT/SIGTERM: the run stops, its temporary files go, exit 130/143
        return _regress_all(args, scenarios, tolerances, stop, junit)


def _regress_all(args: argparse.Namespace, scenarios, tolerances, stop, junit: Path | None) -> int:
    status = 0
    verdicts = []
    with progress_bar(len(scenarios), "regress", "scenario") as bar:
        for scenario in scenarios:
            started = time.monotonic()
            bar.set_postfix_str(Path(scenario).stem, refresh=False)
            outcome, metadata = regress_one(scenario, tolerances, args.update, args.report, stop.is_set)
            if stop.is_set():
                print(f"{scenario}: stopped by {stop.name}; nothing compared or written", file=sys.stderr)
                return stop.exit_status
            if outcome.comparison is not None or outcome.problem:
                verdicts.append(_verdict(scenario, outcome, metadata, time.monotonic() - started))
            with over_bars():
                status = max(status, _report(scenario, outcome, args.update))
            bar.update(1)
    if annotations_wanted(args.annotations) and not args.update:
        print("\n".join(github_annotations(verdicts, annotations_root(args.annotations_root))))
    if junit is not None:
        junit.write_text(junit_xml(verdicts, "heliostep regress"), encoding="utf-8")
        print(f"junit: {junit}")
    return status


def _report(scenario: Path, outcome: Outcome, update: bool) -> int:
    """A scenario's verdict on stdout (with its table when it failed or changed); 1 when it failed, else 0."""
    if outcome.problem:
        print(f"{scenario}: FAIL: {outcome.problem}")
        return 1
    if outcome.comparison is None:
        print(f"{scenario}: reference written ({reference_path(scenario).name})")
        return 0
    verdict = "PASS" if outcome.passed else ("CHANGED" if update else "FAIL")
    print(f"{scenario}: {verdict}")
    if not outcome.passed or update:
        print(format_table(outcome.comparison))
    if update:
        print(f"  reference rewritten: {reference_path(scenario).name}")
        return 0
    return 0 if outcome.passed else 1


def _verdict(scenario: Path, outcome: Outcome, metadata: dict[str, str], seconds: float) -> SuiteVerdict:
    """A scenario's regression as a JUnit test suite (named by the scenario's file stem)."""
    units = {key[len("unit.") :]: value for key, value in metadata.items() if key.startswith("unit.")}
    return SuiteVerdict(scenario.stem, outcome.comparison, units, outcome.problem, seconds=seconds, file=str(scenario))
