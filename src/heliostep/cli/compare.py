"""``heliostep compare ACTUAL REFERENCE``: check a trace against a reference trace.

Exit status: 0 every compared signal is inside its tolerance tube, 1 some signal
deviates (or the actual trace is marked ``complete: false``), 2 bad input, including a
signal of the reference that the actual trace lacks when ``--signals`` is not given (reported
by :mod:`heliostep.cli` from the :class:`~heliostep.errors.InputError` raised here).
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import time
from pathlib import Path

from heliostep.errors import InputError
from heliostep.results.compare.signal_map import (
    SignalMatch,
    load_signal_map,
    match_signals,
    parse_map_options,
    signal_units,
)
from heliostep.results.compare.traces import (
    ToleranceSet,
    compare_matched,
    format_matches,
    format_table,
    load_tolerances,
)
from heliostep.results.compare.verdicts import SuiteVerdict, github_annotations, junit_xml
from heliostep.results.trace.files import is_complete, read_trace

__all__ = ["register", "run", "format_table"]

_DESCRIPTION = """\
Compare the signals of trace ACTUAL with those of trace REFERENCE (Parquet, CSV,
OpenModelica CSV, or a Dymola/OpenModelica .mat result file) using a tolerance
tube around the reference: half-width max(abs, rel*|ref|),
widened by the time tolerance (the bounds at t are the max/min over
[t - time, t + time]). Exit status 0: all signals inside their tube;
1: some signal outside (or ACTUAL is marked complete: false); 2: bad input
(including a signal of REFERENCE missing from ACTUAL, unless --signals names
the signals to compare). CSV: ',' or ';' separated (';' with ',' or '.'
decimals), UTF-8 with or without a byte order mark.
Tolerances: built-in defaults (abs 1e-6, rel 1e-4, time 1e-3 s) < the 'default'
section of --tolerances FILE < --abs-tol/--rel-tol/--time-tol; the per-signal
entries of FILE override the fields they name; an entry naming a signal in neither trace is
bad input. Signals are matched by --map/--map-file, else by role (both traces' role.<role>
metadata), else by name; the output says which was matched to which and how.
"""


def register(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``compare`` command to *subparsers*."""
    parser = subparsers.add_parser(
        "compare",
        help="compare a trace with a reference trace (tolerance tube)",
        description=_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("actual", metavar="ACTUAL", help="trace to check (.parquet or .csv)")
    parser.add_argument("reference", metavar="REFERENCE", help="reference trace (.parquet or .csv)")
    parser.add_argument(
        "--signals",
        metavar="A,B,...",
        help="comma-separated signals to compare (default: every signal of REFERENCE, each of which "
        "ACTUAL must have: a missing one is bad input, exit 2)",
    )
    parser.add_argument("--abs-tol", metavar="X", help="absolute tolerance, signal units, for all signals")
    parser.add_argument("--rel-tol", metavar="X", help="relative tolerance (fraction of |reference|)")
    parser.add_argument("--time-tol", metavar="SECONDS", help="time tolerance in seconds")
    parser.add_argument(
        "--tolerances",
        metavar="FILE",
        help="YAML file: 'default: {abs: .., rel: .., time: ..}' and 'signals: {NAME: {abs: ..}}'",
    )
    parser.add_argument(
        "--report",
        metavar="DIR",
        help="write index.html (self-contained: images embedded), index.md and a PNG per failing signal into DIR",
    )
    parser.add_argument(
        "--map",
        action="append",
        metavar="ACTUAL=REFERENCE",
        help="compare signal ACTUAL of the actual trace with REFERENCE of the reference (repeatable)",
    )
    parser.add_argument(
        "--map-file", metavar="FILE", help="signal mapping: YAML 'ACTUAL: REFERENCE' or CSV 'actual,reference'"
    )
    parser.add_argument("--junit", metavar="FILE", help="write the verdicts as JUnit XML (one test case per signal)")
    add_annotations_option(parser)
    parser.set_defaults(func=run)
    return parser


def add_annotations_option(parser: argparse.ArgumentParser) -> None:
    """``--annotations {auto,github,none}`` (for ``compare`` and ``regress``)."""
    parser.add_argument(
        "--annotations",
        choices=("auto", "github", "none"),
        default="auto",
        help="print GitHub Actions '::error' annotations for failing signals (auto: when GITHUB_ACTIONS=true)",
    )
    parser.add_argument(
        "--annotations-root",
        type=Path,
        metavar="DIR",
        help="the annotations' file paths relative to this folder, the repository's root on GitHub "
        "(default: the git top level of the current folder, else the current folder)",
    )


def _tolerance_option(value: str | None, option: str) -> float | None:
    if value is None:
        return None
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not math.isfinite(number) or number < 0:
        raise InputError(f"{option}: expected a non-negative number, got {value!r}")
    return number


def _tolerances(args: argparse.Namespace) -> ToleranceSet:
    tolerances = load_tolerances(args.tolerances) if args.tolerances else ToleranceSet()
    changes = {
        key: number
        for key, option, value in (
            ("abs", "--abs-tol", args.abs_tol),
            ("rel", "--rel-tol", args.rel_tol),
            ("time", "--time-tol", args.time_tol),
        )
        if (number := _tolerance_option(value, option)) is not None
    }
    return tolerances.with_default(**changes) if changes else tolerances


def _signals(value: str | None) -> list[str] | None:
    if value is None:
        return None
    names = list(dict.fromkeys(part.strip() for part in value.split(",") if part.strip()))
    if not names:
        raise InputError(f"--signals: no signal name in {value!r}")
    return names


def check_output_dir(value: str | Path, option: str) -> Path:
    """*value* as a folder heliostep can write into (made later if missing), checked before any
    work: InputError if it is a file, or it (or, when missing, its nearest existing parent) is not
    a writable folder."""
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise InputError(f"{option} {path}: is a file, expected a folder")
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path}: folder {existing} is not writable")
    return path


def check_output_file(value: str | Path, option: str) -> Path:
    """*value* as a file heliostep can write, checked before any work: its folder must exist and be
    writable, and it must not be a folder."""
    path = Path(value)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder, expected a file name")
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: no folder {folder}")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise InputError(f"{option} {path}: not writable")
    return path


def annotations_root(given: Path | None) -> Path:
    """``--annotations-root``, else ``git rev-parse --show-toplevel`` of the current folder, else the folder."""
    if given is not None:
        if not given.is_dir():
            raise InputError(f"--annotations-root {given}: not a folder")
        return given.resolve()
    try:
        done = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):  # no git: the current folder
        return Path.cwd()
    top = done.stdout.strip()
    return Path(top).resolve() if done.returncode == 0 and top else Path.cwd()


def annotations_wanted(choice: str) -> bool:
    """``--annotations``: ``github`` always, ``none`` never, ``auto`` when ``GITHUB_ACTIONS=true``."""
    return choice == "github" or (choice == "auto" and os.environ.get("GITHUB_ACTIONS") == "true")


def _matches(
    args: argparse.Namespace, actual, actual_meta, reference, reference_meta
) -> tuple[dict[str, SignalMatch], dict[str, SignalMatch]]:
    """Every match, and those to compare (all, or those --signals names)."""
    explicit = load_signal_map(args.map_file) if args.map_file else {}
    for actual_name, reference_name in parse_map_options(args.map).items():
        if actual_name in explicit and explicit[actual_name] != reference_name:
            raise InputError(
                f"--map {actual_name}={reference_name}: {args.map_file} maps it to {explicit[actual_name]!r}"
            )
        explicit[actual_name] = reference_name
    matches = match_signals(
        list(actual.columns),
        list(reference.columns),
        actual_meta,
        reference_meta,
        explicit,
        actual_name=str(args.actual),
        reference_name=str(args.reference),
    )
    signals = _signals(args.signals)
    if signals is None:
        missing = [c for c in reference.columns if c != "time" and c not in matches]
        if missing:
            raise InputError(
                f"{args.actual}: no column matches the signal(s) {', '.join(map(repr, missing))} of the reference "
                f"{args.reference} (by name, by role or by --map/--map-file); to compare only some signals, "
                f"name them with --signals"
            )
        return matches, matches
    by_actual = {m.actual: m for m in matches.values()}
    chosen = {}
    for name in signals:
        match = matches.get(name) or by_actual.get(name)
        if match is None:
            where = args.reference if name not in reference.columns else args.actual
            raise InputError(f"{where}: no column {name!r} (requested signal), nor a match for it")
        chosen[match.reference] = match
    return matches, chosen


def _check_tolerance_signals(tolerances: ToleranceSet, matches, actual, reference, path) -> ToleranceSet:
    """The tolerance file's per-signal entries by reference name (an entry may name the actual's
    column of a matched signal); InputError for an entry naming a signal in neither trace, so a
    typo in a tightening entry cannot turn a FAIL into a PASS."""
    to_reference = {m.actual: m.reference for m in matches.values()}
    unknown = [n for n in tolerances.signals if n not in reference.columns and n not in actual.columns]
    if unknown:
        raise InputError(
            f"{path}: tolerance given for signal(s) in neither trace: {', '.join(map(repr, unknown))} "
            f"(signals of the reference: {', '.join(c for c in reference.columns if c != 'time')})"
        )
    renamed = {to_reference.get(n, n) if n not in reference.columns else n: v for n, v in tolerances.signals.items()}
    return ToleranceSet(tolerances.default, renamed)


def run(args: argparse.Namespace) -> int:
    """Run the command; returns the exit status (0 pass, 1 deviation)."""
    started = time.monotonic()
    report = check_output_dir(args.report, "--report") if args.report else None
    junit = check_output_file(args.junit, "--junit") if args.junit else None
    tolerances = _tolerances(args)
    actual, actual_meta = read_trace(args.actual)
    reference, reference_meta = read_trace(args.reference)
    every_match, matches = _matches(args, actual, actual_meta, reference, reference_meta)
    tolerances = _check_tolerance_signals(tolerances, every_match, actual, reference, args.tolerances)
    result = compare_matched(
        actual,
        reference,
        matches,
        tolerances,
        actual_name=str(args.actual),
        reference_name=str(args.reference),
        every_match=every_match,
    )
    units = signal_units(matches, actual_meta, reference_meta)

    print(format_table(result, units))
    print(format_matches(result))
    if result.only_in_actual:
        print(f"not compared, only in {args.actual}: {', '.join(result.only_in_actual)}")
    if result.only_in_reference:
        print(f"not compared, only in {args.reference}: {', '.join(result.only_in_reference)}")
    if not is_complete(reference_meta):
        print(f"heliostep compare: warning: {args.reference} is marked complete: false", file=sys.stderr)
    incomplete = not is_complete(actual_meta)
    if incomplete:
        print(f"{args.actual} is marked complete: false (the run that wrote it failed)")

    failed = result.failed
    if failed:
        print(f"FAIL: {len(failed)} of {len(result.signals)} signal(s) outside tolerance: {', '.join(failed)}")
    elif incomplete:
        print(f"FAIL: all {len(result.signals)} signal(s) inside tolerance, but the actual run is incomplete")
    else:
        print(f"PASS: all {len(result.signals)} signal(s) inside tolerance")

    verdict = SuiteVerdict(
        "compare", result, units, complete=not incomplete, seconds=time.monotonic() - started, file=str(args.reference)
    )
    if annotations_wanted(args.annotations):
        print("\n".join(github_annotations([verdict], annotations_root(args.annotations_root))))
    if junit is not None:
        junit.write_text(junit_xml([verdict]), encoding="utf-8")
        print(f"junit: {junit}")
    if report is not None:
        from heliostep.plots.compare import write_report

        index = write_report(result, actual, reference, report, actual_meta, reference_meta)
        print(f"report: {index}")
    return 1 if failed or incomplete else 0
