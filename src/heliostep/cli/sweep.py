"""``heliostep sweep SWEEP.yaml``: run a sizing sweep on Dask (see :mod:`heliostep.sweep`), one row
per case in ``results.parquet`` and the sweep's figures.

Details: docs/sweep.md, ``heliostep.cli.sweep``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pandas as pd

from heliostep.cli.signals import exit_status, stop_requests
from heliostep.errors import HeliostepError, InputError
from heliostep.results.output.files import check_out_name
from heliostep.results.output.folder import claimed, owned_folder, write_swapped
from heliostep.sweep import (
    SweepOutcome,
    check_results_owner,
    execute_cases,
    expand_cases,
    load_sweep,
    read_results,
    sweep_metadata,
)
from heliostep.sweep.certificate import CERTIFICATE_CASES, CERTIFIED_FIGURES
from heliostep.sweep.local_worker import silence_distributed_logs

__all__ = ["add_family_options", "case_count", "register"]

RESULTS_FILE = "results.parquet"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` command to the ``heliostep`` command line.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        From :meth:`argparse.ArgumentParser.add_subparsers`.
    """
    parser = subparsers.add_parser(
        "sweep",
        help="run a sizing sweep (days x mirrors x motors ...) on Dask, results in one Parquet table",
        description="Run every case of a sweep file on a local dask.distributed cluster (one worker "
        "process per core) or on --scheduler, writing out/<name>/results.parquet as cases "
        "finish; a rerun skips the cases already done. See docs/sweep.md.",
    )
    parser.add_argument("sweep", type=Path, help="sweep YAML file")
    parser.add_argument(
        "--out", metavar="DIR", help="folder of results.parquet and the plots (default: out/<sweep name>)"
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on this Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: a local cluster)",
    )
    parser.add_argument(
        "--workers", type=int, metavar="N", help="worker processes of the local cluster (default: one per core)"
    )
    parser.add_argument(
        "--connect-timeout",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="how long to try reaching --scheduler (default: 5)",
    )
    parser.add_argument(
        "--retry-failed",
        action="store_true",
        help="run again the cases recorded as failed (they are skipped otherwise)",
    )
    parser.add_argument(
        "--replace",
        action="store_true",
        help="run even when the folder's results.parquet holds another sweep's rows, dropping them (refused otherwise)",
    )
    add_family_options(parser)
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.add_argument("--list", action="store_true", help="list the cases and whether each is done; run nothing")
    parser.set_defaults(func=_run_command)


def case_count(text: str) -> int:
    """A whole number of cases >= 1 (``--certify``, ``size --max-cases``; argparse's type: exit 2 naming the
    option otherwise)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text}: expected a whole number of cases >= 1")
    return value


def add_family_options(parser: argparse.ArgumentParser) -> None:
    """``--exact``, ``--certify`` and ``--seed``: how the step families compose the cases (docs/sweep.md);
    ``heliostep size`` takes them too."""
    parser.add_argument(
        "--exact",
        action="store_true",
        help="co-simulate every case in full (default: cases that share a drive are composed from its step family, "
        "certified against full runs of a sample)",
    )
    parser.add_argument(
        "--certify",
        type=case_count,
        default=CERTIFICATE_CASES,
        metavar="N",
        help=f"cases run in full to certify the composed ones, spread over the sweep (default: {CERTIFICATE_CASES})",
    )
    parser.add_argument(
        "--seed", type=int, default=0, metavar="N", help="seed of the certificate's random cases (default: 0)"
    )


def _run_command(args: argparse.Namespace) -> int:
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}")
    if args.connect_timeout <= 0:
        raise InputError(f"--connect-timeout must be > 0 s, got {args.connect_timeout}")
    out_name = check_out_name(str(args.out)) if args.out is not None else None  # "" refused before anything
    results_path = None
    try:
        with stop_requests(raise_exception=_Stopped), _scratch_tmpdir():
            spec = load_sweep(args.sweep)
            cases = expand_cases(spec)
            out_dir = out_name or Path("out") / spec.name
            results_path = out_dir / RESULTS_FILE
            if args.list:
                print(_case_listing(cases, read_results(results_path)))
                return 0
            outcome, plots = _sweep_in_folder(args, spec, cases, out_dir)
    except KeyboardInterrupt as stopped:
        signum = stopped.signum if isinstance(stopped, _Stopped) else signal.SIGINT
        print(f"heliostep sweep: stopped by {signal.Signals(signum).name}; {_recorded(results_path)}", file=sys.stderr)
        return exit_status(signum)
    except OSError as exc:  # a full disk, a file-size limit, a folder that cannot be made: a run failure
        where = results_path.parent if results_path is not None else "the output folder"
        print(
            f"heliostep sweep: error: could not write the results in {where}: {exc.strerror or exc}; "
            f"{_recorded(results_path)}",
            file=sys.stderr,
        )
        return 1
    print(_report(spec.name, outcome, plots))
    if outcome.failed:
        print(
            f"heliostep sweep: {outcome.failed} case(s) failed; rerun with --retry-failed to try them again",
            file=sys.stderr,
        )
    return 1 if outcome.failed else 0


def _sweep_in_folder(args: argparse.Namespace, spec, cases, out_dir: Path) -> tuple[SweepOutcome, list[Path]]:
    """The cases run into ``out_dir``, its lock held meanwhile: results.parquet (listed in the
    folder's manifest, then updated in place as cases finish: a rerun resumes it) and the
    figures, swapped in; the earlier figures are removed before any case runs (they would show
    other results). A table of another sweep's rows is refused first, unless ``--replace``."""
    from heliostep.plots.sweep import HEATMAPS, TORQUE_FILE

    out_dir.mkdir(parents=True, exist_ok=True)  # a folder that cannot be made: an OSError, a run failure
    names = [RESULTS_FILE, *(name for _, name, _ in HEATMAPS), TORQUE_FILE]
    with owned_folder(out_dir, names, in_place=[RESULTS_FILE]):  # a killed sweep's table: taken up again
        with claimed(out_dir, [RESULTS_FILE]):  # listed while the cases update it, its digest recorded after
            check_results_owner(out_dir / RESULTS_FILE, sweep_metadata(spec), args.replace)  # before figures go
            write_swapped(out_dir, lambda staging: [], keep={RESULTS_FILE})  # the older figures out
            outcome = execute_cases(
                cases,
                out_dir / RESULTS_FILE,
                scheduler=args.scheduler,
                n_workers=args.workers,
                connect_timeout=args.connect_timeout,
                retry_failed=args.retry_failed,
                progress=True,
                metadata=sweep_metadata(spec),
                replace=args.replace,
                exact=args.exact,
                certify=args.certify,
                seed=args.seed,
            )

        def draw(staging: Path) -> list[Path]:
            if args.no_plots or not len(outcome.table):
                return []
            from heliostep.plots.sweep import plot_sweep

            return plot_sweep(outcome.table, staging)

        plots = list(write_swapped(out_dir, draw, keep={RESULTS_FILE}).values())
    return outcome, plots


def _recorded(results_path: Path | None) -> str:
    if results_path is None:
        return "no case was run"
    try:
        done = len(read_results(results_path))
    except (OSError, HeliostepError):  # only for the message
        return f"the cases finished so far are in {results_path}"
    return f"{done} case(s) recorded in {results_path}; rerun the same command to run the rest"


@contextmanager
def _scratch_tmpdir() -> Iterator[Path]:
    """TMPDIR of the sweep's local processes: a folder removed on every exit path.

    Dask's scratch space and the workers' FMU unpack folders and trace streams go there. On
    SIGINT/SIGTERM the cluster's shutdown kills the worker processes, which then cannot remove
    their own temporary folders; this process removes the whole folder once the cluster is gone,
    distributed's messages silenced first: a work folder of the closed cluster that distributed
    releases later (as the stop's traceback lets go of it) is found gone, which it would report.
    """
    scratch = Path(tempfile.mkdtemp(prefix="heliostep-sweep-"))
    saved_env, saved_tempdir = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"], tempfile.tempdir = str(scratch), None  # inherited by the workers
    try:
        yield scratch
    finally:
        if saved_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = saved_env
        tempfile.tempdir = saved_tempdir
        silence_distributed_logs()  # the cluster is closed: what distributed says now is about its folders
        shutil.rmtree(scratch, ignore_errors=True)


class _Stopped(KeyboardInterrupt):
    """SIGINT or SIGTERM while the sweep runs (raised in the main thread, waiting on Dask)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _case_listing(cases, table: pd.DataFrame) -> str:
    status = dict(zip(table["case_id"], table["status"])) if len(table) else {}
    lines = [f"{len(cases)} cases"]
    for case in cases:
        lines.append(f"  {case.index:5d} {case.case_id} {status.get(case.case_id, 'todo'):6s} {case.label}")
    return "\n".join(lines)


def _report(name: str, outcome: SweepOutcome, plots: list[Path]) -> str:
    table = outcome.table
    lines = [
        f"{name}: {len(table)} cases: {outcome.executed} run now, {outcome.skipped} already done, "
        f"{outcome.failed} failed -> {outcome.results_path}"
    ]
    ok = table[table["status"] == "ok"]
    for column, label, unit in (
        ("max_tracking_error_deg", "max tracking error", "deg"),
        ("peak_torque_Nm", "peak torque", "N.m"),
        ("load_torque_Nm", "load torque (worst instant)", "N.m"),
        ("primary_sharing_error_max_deg", "primary sharing error", "deg"),
    ):
        values = ok[column].dropna()
        if len(values):
            worst = ok.loc[values.idxmax()]
            lines.append(
                f"  {label + ' [' + unit + ']':36s} max {values.max():.4g} (case {worst['case_index']}: "
                f"{worst['overrides']})"
            )
    holding = ok["holding_torque_Nm"].dropna()
    if len(holding):
        lines.append(
            f"  {'holding torque k_e x I [N.m]':36s} {', '.join(f'{h:.4g}' for h in sorted(holding.unique()))}"
        )
    lines += _certificate_lines(table)
    failed = table[table["status"] == "failed"]
    for row in failed.head(5).itertuples(index=False):
        first_line = (row.error or "").splitlines()[0] if row.error else ""
        lines.append(f"  FAILED case {row.case_index} ({row.overrides}): {row.error_type}: {first_line[:200]}")
    if len(failed) > 5:
        lines.append(f"  ... and {len(failed) - 5} more failed cases (see the table's error column)")
    for path in plots:
        lines.append(f"  plot: {path}")
    return "\n".join(lines)


def _certificate_lines(table: pd.DataFrame) -> list[str]:
    """How the rows were made (full, composed, certificate) and, with composed rows, each certified figure's
    largest deviation on the certificate rows against its tolerance."""
    methods = table["method"].fillna("full").value_counts()
    lines = ["  rows: " + ", ".join(f"{count} {method}" for method, count in methods.items())]
    fallbacks = table["fallback"].dropna()
    if len(fallbacks):
        reason, count = fallbacks.value_counts().index[0], int(fallbacks.value_counts().iloc[0])
        lines.append(f"  run in full instead of composed: {len(fallbacks)} (most often: {reason}, {count})")
    if not methods.get("composed", 0):
        return lines
    lines.append("  certified max deviation (tolerance):")
    certified = table[table["method"] == "certificate"]
    for name, tolerance in CERTIFIED_FIGURES.items():
        worst = certified[f"deviation_{name}"].max()
        lines.append(f"    {name:28s} {worst:.2e} ({tolerance:.1e})")
    return lines
