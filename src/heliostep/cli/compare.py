"""``heliostep compare ACTUAL REFERENCE``: check a trace against a reference trace.

Exit status: 0 every compared signal is inside its tolerance tube, 1 some signal
deviates (or the actual trace is marked ``complete: false``), 2 bad input, including a
signal of the reference that the actual trace lacks when ``--signals`` is not given (reported
by :mod:`heliostep.cli` from the :class:`~heliostep.errors.InputError` raised here).
"""

from __future__ import annotations

import argparse
import math
import sys

from heliostep.errors import InputError
from heliostep.results.compare import (
    ToleranceSet,
    compare_traces,
    format_table,
    load_tolerances,
)
from heliostep.results.trace_io import is_complete, read_trace

__all__ = ["register", "run", "format_table"]

_DESCRIPTION = """\
Compare the signals of trace ACTUAL with those of trace REFERENCE (Parquet or CSV)
using a tolerance tube around the reference: half-width max(abs, rel*|ref|),
widened by the time tolerance (the bounds at t are the max/min over
[t - time, t + time]). Exit status 0: all signals inside their tube;
1: some signal outside (or ACTUAL is marked complete: false); 2: bad input
(including a signal of REFERENCE missing from ACTUAL, unless --signals names
the signals to compare). CSV: ',' or ';' separated (';' with ',' or '.'
decimals), UTF-8 with or without a byte order mark.
Tolerances: built-in defaults (abs 1e-6, rel 1e-4, time 1e-3 s) < the 'default'
section of --tolerances FILE < --abs-tol/--rel-tol/--time-tol; the per-signal
entries of FILE override the fields they name.
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
        help="write index.md, index.html and a PNG per failing signal into DIR",
    )
    parser.set_defaults(func=run)
    return parser


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


def run(args: argparse.Namespace) -> int:
    """Run the command; returns the exit status (0 pass, 1 deviation)."""
    tolerances = _tolerances(args)
    signals = _signals(args.signals)
    actual, actual_meta = read_trace(args.actual)
    reference, reference_meta = read_trace(args.reference)
    if signals is None:
        missing = [c for c in reference.columns if c != "time" and c not in actual.columns]
        if missing:
            raise InputError(
                f"{args.actual}: no column(s) {', '.join(map(repr, missing))} of the reference {args.reference}; "
                f"to compare only some signals, name them with --signals"
            )
    result = compare_traces(
        actual,
        reference,
        tolerances,
        signals,
        actual_name=str(args.actual),
        reference_name=str(args.reference),
    )

    present = set(actual.columns) | set(reference.columns)
    unknown = [name for name in tolerances.signals if name not in present]
    if unknown:
        print(
            f"heliostep compare: warning: {args.tolerances}: tolerance given for signal(s) in neither trace: "
            + ", ".join(unknown),
            file=sys.stderr,
        )

    print(format_table(result))
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

    if args.report:
        from heliostep.plots.compare import write_report

        index = write_report(result, actual, reference, args.report, actual_meta, reference_meta)
        print(f"report: {index}")
    return 1 if failed or incomplete else 0
