"""``heliostep run --band N``: the options, the design checked before the nominal run, the band after it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from heliostep.errors import InputError
from heliostep.sweep.band import DEFAULT_SEED, MAX_BAND_SAMPLES, RANGES_FILE, BandDesign, band_design, load_ranges

#: How long to try reaching --scheduler [s].
CONNECT_TIMEOUT = 5.0

BAND_HELP = (
    "Uncertainty band (--band N): after the nominal run, the scenario runs at N Latin-hypercube samples "
    "of the uncertain parameters of the ranges file (--band-ranges; default the shipped "
    "heliostep/data/parameter_ranges.yaml: bus voltage and current-loop gain, each with its source) "
    "on the local Dask cluster (one worker per core, 127.0.0.1) or --scheduler; keys the scenario "
    "pins (band.pinned) keep its value. summary.json gains 'band': each figure's nominal, min, median "
    "and max over the samples, the design (seed, ranges, each sample's values) and each sample's "
    "figures; a failed sample is listed there and named on stderr. Ctrl+C during the band keeps the "
    "nominal run's files and writes the band of the samples finished. A window of more than 4 hours "
    "composes each sample from its drive's step family, certified by 2 samples run both ways "
    "(docs/sweep.md); --exact runs every sample in full."
)


def add_band_options(parser: argparse.ArgumentParser) -> None:
    """--band, --band-seed, --band-ranges, --exact, --scheduler, --workers."""
    group = parser.add_argument_group("uncertainty band", BAND_HELP)
    group.add_argument(
        "--band",
        type=int,
        metavar="N",
        help=f"also run N samples (2 to {MAX_BAND_SAMPLES}) over the parameters' ranges; N samples cost N runs",
    )
    group.add_argument(
        "--band-seed",
        type=int,
        default=DEFAULT_SEED,
        metavar="SEED",
        help=f"the Latin hypercube's seed ({DEFAULT_SEED})",
    )
    group.add_argument(
        "--band-ranges",
        type=Path,
        default=RANGES_FILE,
        metavar="FILE",
        help="the ranges file (default: the shipped one)",
    )
    group.add_argument(
        "--exact", action="store_true", help="with --band: every sample co-simulated in full, none composed"
    )
    group.add_argument("--scheduler", metavar="ADDRESS", help="run the band on this Dask scheduler (tcp://HOST:PORT)")
    group.add_argument("--workers", type=int, metavar="N", help="worker processes of the local cluster (one per core)")


def prepare_band(args: argparse.Namespace, scenario, fmu_paths) -> BandDesign | None:
    """The band's design, checked before anything runs (an InputError, exit 2, names the key or option);
    None without --band."""
    if args.band is None:
        if args.exact:
            raise InputError("--exact: only with --band (a run without a band is co-simulated in full)")
        return None
    design = band_design(
        scenario, load_ranges(args.band_ranges), args.band, args.band_seed, fmu_paths, ranges_file=args.band_ranges
    )
    for index in range(design.samples):  # each sample's scenario valid (an error names the sample)
        design.scenario_of(scenario, index)
    # the band's runner and Dask imported only with --band (``heliostep run`` stays light without)
    from heliostep.sweep.band_run import check_band_budget
    from heliostep.sweep.cluster import _probe_scheduler

    if args.scheduler is None:
        check_band_budget(scenario, design.samples, args.workers)
    else:  # reachable, before the nominal run
        _probe_scheduler(args.scheduler, CONNECT_TIMEOUT)
    return design


def run_band_after(
    args: argparse.Namespace, design: BandDesign, result, out_dir: Path, fmu_paths, stop, status: int
) -> int:
    """The band of a nominal run written into ``out_dir`` (its exit ``status`` 0 and no stop asked,
    else nothing is run and ``status`` returned): summary.json rewritten with ``band``, the band
    printed; the exit status (0, 1 when a sample failed, the signal's when stopped)."""
    if status != 0 or stop.is_set():
        print("heliostep run: the band was not run: the nominal run did not complete or was stopped", file=sys.stderr)
        return status
    print(
        f"heliostep run: band: {design.samples} samples of {', '.join(p.key for p in design.ranges)} "
        f"(Latin hypercube, seed {design.seed}) on {args.scheduler or 'a local Dask cluster'}",
        file=sys.stderr,
    )

    from heliostep.sweep.band_run import band_record, run_band, run_figures, write_band_summary

    finished = []

    def report(sample: dict) -> None:
        finished.append(sample["index"])
        if sample["status"] == "ok":
            print(
                f"heliostep run: band sample {sample['index']} finished ({len(finished)} of {design.samples})",
                file=sys.stderr,
            )
        else:
            print(f"heliostep run: band sample {sample['index']} failed: {sample['error']}", file=sys.stderr)

    outcome = run_band(
        result.scenario,
        design,
        fmu_paths,
        scheduler=args.scheduler,
        n_workers=args.workers,
        connect_timeout=CONNECT_TIMEOUT,
        should_stop=stop.is_set,
        on_sample=report,
        exact=args.exact,
    )
    record = band_record(run_figures(result), outcome)
    write_band_summary(out_dir, result.summary_record(), record)
    print(band_report(record))
    if outcome.interrupted:
        print(
            f"heliostep run: stopped by {stop.name} during the band: the nominal run's files are kept; "
            f"{len(outcome.finished)} of {design.samples} samples finished "
            f"({', '.join(map(str, outcome.finished)) or 'none'}), their band is in summary.json",
            file=sys.stderr,
        )
        return stop.exit_status
    if outcome.failed:
        print(f"heliostep run: band: sample(s) {', '.join(map(str, outcome.failed))} failed", file=sys.stderr)
        return 1
    return 0


def band_report(record: dict) -> str:
    """The band beside each figure: nominal, min, median, max."""
    finished, samples = len(record["finished"]) - len(record["failed"]), record["samples"]
    lines = [f"  band over {finished} of {samples} samples:", f"  {'figure':34s} {'nominal':>11s} {'min':>11s} "]
    lines[-1] += f"{'median':>11s} {'max':>11s}"
    for name, entry in record["figures"].items():
        if "min" not in entry:
            continue
        values = (entry[key] for key in ("nominal", "min", "median", "max"))
        lines.append(f"  {name:34s} " + " ".join(f"{value:11.5g}" for value in values))
    composition = record.get("composition") or {}
    if composition.get("methods", {}).get("composed") or composition.get("certificate_failed"):
        methods = ", ".join(f"{count} {method}" for method, count in sorted(composition["methods"].items()))
        lines.append(f"  samples by method: {methods}")
        for name, figure in composition["certificate"].items():
            deviation = figure["max_deviation"]
            shown = "n/a" if deviation is None else f"{deviation:.2e}"
            lines.append(f"  certified max deviation {name:26s} {shown} (tolerance {figure['tolerance']:.1e})")
        if composition.get("certificate_failed"):
            lines.append(f"  the certificate failed on {', '.join(composition['certificate_failed'])}: all in full")
    if record.get("note"):
        lines.append(f"  note: {record['note']}")
    return "\n".join(lines)
