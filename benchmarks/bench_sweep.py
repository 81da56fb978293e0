"""Benchmark of ``heliostep sweep`` on dask.distributed (prints figures; not a test).

Runs (3 times, the median shown) a fixed set of 8 cases of the paper's 5-minute window (days 21, 111, 172, 264 x
mirrors 0 and 12) on a local cluster of 1 and of 2 single-threaded worker processes,
and prints the cases per minute, the scaling factor, and the wall time of the full
year (365 days) x 13 mirrors on N workers estimated from the measured time per case.
With ``--full-day`` it also times one sunrise-to-sunset case, the case of
``scenarios/sweeps/year-field.yaml``, and estimates that sweep (365 x 14 cases).

The clusters are started and their workers warmed up (heliostep imported) before the
clock starts; the FMUs are built before. Timed: validation, shipping the FMUs, the
runs and writing the results table.

Usage::

    .venv/bin/python benchmarks/bench_sweep.py [--full-day] [--workers 1 2]
"""

from __future__ import annotations

import argparse
import importlib
import logging
import statistics
import tempfile
import time as clock
from pathlib import Path

import yaml
from distributed import Client, LocalCluster

from heliostep.fmu.build import ensure_fmu
from heliostep.sweep import execute_cases, expand_cases, load_sweep

ROOT = Path(__file__).resolve().parents[1]
BASE = ROOT / "scenarios" / "jan21-central.yaml"
DAYS = (21, 111, 172, 264)
MIRRORS = (0, 12)
YEAR_CASES = 365 * 13  # the full year x 13 mirrors
YEAR_FIELD_CASES = 365 * 14  # year-field.yaml: plus the shared primary per day
CLUSTER_SIZES = (2, 16, 64)


def write_sweep(folder: Path, name: str, axes: dict, overrides: dict | None = None) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"name": name, "base": str(BASE), "axes": axes,
                                    "overrides": overrides or {}}, sort_keys=False))
    return path


def timed_sweep(sweep: Path, folder: Path, n_workers: int, repeat: int = 1) -> tuple[float, float, object]:
    """(validation time [s], median execution wall time [s], last outcome) of a sweep.

    Runs it ``repeat`` times, each into a fresh results table, on one local cluster of
    ``n_workers`` started (and warmed up) before the clock.
    """
    validations, walls = [], []
    with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=":0", silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        client.wait_for_workers(n_workers)
        client.run(importlib.import_module, "heliostep.sweep")  # warm up: imports outside the clock
        for attempt in range(repeat):
            started = clock.perf_counter()
            cases = expand_cases(load_sweep(sweep))
            validated = clock.perf_counter()
            outcome = execute_cases(cases, folder / f"results-{n_workers}-{attempt}.parquet", client=client)
            walls.append(clock.perf_counter() - validated)
            validations.append(validated - started)
            if outcome.failed:
                raise SystemExit(f"{outcome.failed} case(s) failed: {outcome.table['error'].dropna().tolist()}")
    return statistics.median(validations), statistics.median(walls), outcome


def duration_text(seconds: float) -> str:
    """A wall time [s] in minutes below two hours, else in hours."""
    return f"{seconds / 60.0:8.1f} min" if seconds < 7200.0 else f"{seconds / 3600.0:8.2f} h"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="cluster sizes to time")
    parser.add_argument("--repeat", type=int, default=3, help="timings per cluster size (median shown)")
    parser.add_argument("--full-day", action="store_true", help="also time one sunrise-to-sunset case")
    args = parser.parse_args(argv)
    for variant in ("StepperMotor", "PanelMechanics"):
        ensure_fmu(variant)

    with tempfile.TemporaryDirectory(prefix="heliostep-bench-") as scratch:
        folder = Path(scratch)
        sweep = write_sweep(folder, "bench", {"day_of_year": list(DAYS), "mirror": list(MIRRORS)})
        n_cases = len(DAYS) * len(MIRRORS)
        print(f"{n_cases} cases of the paper's 5-minute window (days {DAYS} x mirrors {MIRRORS}), "
              f"single-threaded worker processes; median of {args.repeat} runs")
        rates, per_case = {}, {}
        for n_workers in args.workers:
            validation, wall, outcome = timed_sweep(sweep, folder, n_workers, args.repeat)
            rates[n_workers] = n_cases / wall * 60.0
            per_case[n_workers] = wall / n_cases
            in_case = outcome.table["wall_time_s"]
            print(f"  {n_workers} worker(s): {wall:6.2f} s wall -> {rates[n_workers]:6.1f} cases/min "
                  f"(a case runs {in_case.mean():.3f} s on its worker, mean; validation {validation:.3f} s)")
        first, last = min(rates), max(rates)
        if last > first:
            scaling = rates[last] / rates[first]
            print(f"  scaling {first} -> {last} workers: x{scaling:.2f} "
                  f"(parallel efficiency {scaling / (last / first):.0%})")
        one_case = per_case[first] * first  # [s] of one worker per case, overheads included
        print(f"\nfull year x 13 mirrors = {YEAR_CASES} cases of 5 minutes, from {one_case:.3f} s per case "
              f"per worker (ideal scaling):")
        for size in CLUSTER_SIZES:
            print(f"  {size:3d} workers: {duration_text(YEAR_CASES * one_case / size)}")

        if args.full_day:
            day = write_sweep(folder, "day", {"day_of_year": [172]},
                              {"window.start": "sunrise", "window.end": "sunset", "window.duration": None,
                               "output.interval": 1.0})
            _, wall, outcome = timed_sweep(day, folder / "day", 1)
            simulated = outcome.table["duration_s"].item()
            print(f"\none sunrise-to-sunset case (day 172, {simulated / 3600:.1f} h simulated, "
                  f"{outcome.table['steps_commanded'].item()} steps): {wall:.1f} s on 1 worker")
            print(f"year-field.yaml = {YEAR_FIELD_CASES} such cases (ideal scaling; shorter winter days "
                  f"make it somewhat less):")
            for size in CLUSTER_SIZES:
                print(f"  {size:3d} workers: {duration_text(YEAR_FIELD_CASES * wall / size)}")


if __name__ == "__main__":
    main()
