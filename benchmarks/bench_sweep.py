"""``heliostep sweep`` on dask.distributed (prints figures; not a test).

    .venv/bin/python benchmarks/bench_sweep.py [--full-day [--baseline-set KEY=VALUE]] [--workers 1 2] [--repeat 3]

8 cases of the paper's 5-minute window (days 21, 111, 172, 264 x mirrors 0 and 12) on local clusters of 1 and 2
single-threaded workers (median of ``--repeat``): cases per minute, the scaling, the year x 13 mirrors estimated.
With ``--full-day``, sunrise-to-sunset cases of ``scenarios/sweeps/year-field.yaml`` on days 1, 62, 123, 184, 245,
306 x mirrors 0, 3, 6, 9, 12 and the shared primary, plus day 172, on the smallest cluster of ``--workers``, and
the whole sweep (365 x 14 cases) in full estimated from their mean CPU time per case (the workers' and their
children's, counted with psutil): ``year-field: <h> core-hours, <h> h on 2 workers``; the same cases composed
from their step families, each figure's largest deviation from the full runs; then year-field.yaml run whole
with its families on the largest cluster of ``--workers``, its CPU time measured (the client's, the scheduler's
and the workers'): ``year-field: <h> core-hours (families), <h> core-hours (full), certified max deviation
<figure> <value>``. ``--baseline-set KEY=VALUE`` first
estimates the same with that override on top, in the same run. Clusters are started and warmed up, and the FMUs
built, before the clock starts.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import statistics
import tempfile
import time as clock
from pathlib import Path

import yaml
from distributed import Client, LocalCluster

from heliostep.fmu.build import ensure_fmu
from heliostep.scenario.yaml_io import parse_yaml_value, read_yaml_file
from heliostep.sweep import execute_cases, expand_cases, load_sweep

ROOT = Path(__file__).resolve().parents[1]
BASE = ROOT / "scenarios" / "jan21-central.yaml"
DAYS = (21, 111, 172, 264)
MIRRORS = (0, 12)
YEAR_CASES = 365 * 13  # the full year x 13 mirrors
YEAR_FIELD_CASES = 365 * 14  # year-field.yaml: plus the shared primary per day
CLUSTER_SIZES = (2, 16, 64)
YEAR_SAMPLE_DAYS = (1, 62, 123, 184, 245, 306)  # every 61st day: the year's spread of day lengths
LONGEST_DAY = 172
YEAR_MIRRORS = (0, 3, 6, 9, 12)  # the field's ends, its centre and between
YEAR_FIELD = ROOT / "scenarios" / "sweeps" / "year-field.yaml"


def write_sweep(
    folder: Path, name: str, axes: dict, overrides: dict | None = None, shared_primary: bool = False
) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": name,
                "base": str(BASE),
                "axes": axes,
                "overrides": overrides or {},
                "shared_primary": shared_primary,
            },
            sort_keys=False,
        )
    )
    return path


def worker_cpu_seconds() -> float:
    """CPU time [s] of this Dask worker process and of every process it started: the children it has
    reaped, and each live child (the forkserver context's server) with the children it has reaped. Run on the worker."""
    import psutil  # a dependency of distributed

    own = psutil.Process()
    times = own.cpu_times()
    total = times.user + times.system + times.children_user + times.children_system
    for child in own.children():
        try:
            t = child.cpu_times()
        except psutil.NoSuchProcess:
            continue
        total += t.user + t.system + t.children_user + t.children_system
    return total


@contextlib.contextmanager
def local_client(n_workers: int):
    """A client of a local cluster of ``n_workers`` single-threaded worker processes, all of them started."""
    with (
        LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=":0",
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,
    ):
        client.wait_for_workers(n_workers)
        yield client


def timed_sweep(
    sweep: Path, folder: Path, n_workers: int, repeat: int = 1, exact: bool = True
) -> tuple[float, float, object, float]:
    """(validation time [s], median execution wall time [s], last outcome, the workers' CPU time over the
    last run, their simulation children's included [s]) of a sweep.

    Runs it ``repeat`` times, each into a fresh results table, on one local cluster of
    ``n_workers`` started (and warmed up) before the clock.
    """
    validations, walls = [], []
    with local_client(n_workers) as client:
        # warm up: the imports a case needs, outside the clock (heliostep.sweep loads its modules on first
        # use, and pvlib is imported where the sun is computed: both would fall on the first case)
        for module in ("heliostep.sweep.worker", "heliostep.run", "pvlib", "scipy.interpolate"):
            client.run(importlib.import_module, module)
        for attempt in range(repeat):
            started = clock.perf_counter()
            cases = expand_cases(load_sweep(sweep))
            validated = clock.perf_counter()
            cpu_before = sum(client.run(worker_cpu_seconds).values())
            results = folder / f"results-{n_workers}-{attempt}-{'exact' if exact else 'families'}.parquet"
            outcome = execute_cases(cases, results, client=client, exact=exact)
            walls.append(clock.perf_counter() - validated)
            cpu_seconds = sum(client.run(worker_cpu_seconds).values()) - cpu_before
            validations.append(validated - started)
            if outcome.failed:
                raise SystemExit(f"{outcome.failed} case(s) failed: {outcome.table['error'].dropna().tolist()}")
    return statistics.median(validations), statistics.median(walls), outcome, cpu_seconds


def duration_text(seconds: float) -> str:
    """A wall time [s] in minutes below two hours, else in hours."""
    return f"{seconds / 60.0:8.1f} min" if seconds < 7200.0 else f"{seconds / 3600.0:8.2f} h"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="cluster sizes to time")
    parser.add_argument("--repeat", type=int, default=3, help="timings per cluster size (median shown)")
    parser.add_argument("--full-day", action="store_true", help="also time one sunrise-to-sunset case")
    parser.add_argument(
        "--baseline-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="with --full-day, first estimate year-field.yaml with this override on top (repeatable; e.g. "
        "output.step_detail=0.05, the fine grid it dropped), then as shipped: the two side by side",
    )
    args = parser.parse_args(argv)
    for variant in ("StepperMotor", "PanelMechanics"):
        ensure_fmu(variant)

    with tempfile.TemporaryDirectory(prefix="heliostep-bench-") as scratch:
        folder = Path(scratch)
        sweep = write_sweep(folder, "bench", {"day_of_year": list(DAYS), "mirror": list(MIRRORS)})
        n_cases = len(DAYS) * len(MIRRORS)
        print(
            f"{n_cases} cases of the paper's 5-minute window (days {DAYS} x mirrors {MIRRORS}), "
            f"single-threaded worker processes; median of {args.repeat} runs"
        )
        rates, per_case = {}, {}
        for n_workers in args.workers:
            validation, wall, outcome, _ = timed_sweep(sweep, folder, n_workers, args.repeat)
            rates[n_workers] = n_cases / wall * 60.0
            per_case[n_workers] = wall / n_cases
            in_case = outcome.table["wall_time_s"]
            print(
                f"  {n_workers} worker(s): {wall:6.2f} s wall -> {rates[n_workers]:6.1f} cases/min "
                f"(a case runs {in_case.mean():.3f} s on its worker, mean; validation {validation:.3f} s)"
            )
        first, last = min(rates), max(rates)
        if last > first:
            scaling = rates[last] / rates[first]
            print(
                f"  scaling {first} -> {last} workers: x{scaling:.2f} "
                f"(parallel efficiency {scaling / (last / first):.0%})"
            )
        one_case = per_case[first] * first  # [s] of one worker per case, overheads included
        print(
            f"\nfull year x 13 mirrors = {YEAR_CASES} cases of 5 minutes, from {one_case:.3f} s per case "
            f"per worker (ideal scaling):"
        )
        for size in CLUSTER_SIZES:
            print(f"  {size:3d} workers: {duration_text(YEAR_CASES * one_case / size)}")

        if args.full_day:
            shipped = read_yaml_file(YEAR_FIELD, "sweep")["overrides"]
            if args.baseline_set:
                changed = dict(item.split("=", 1) for item in args.baseline_set)
                label = ", ".join(f"{key}={value}" for key, value in changed.items())
                values = {key: parse_yaml_value(value) for key, value in changed.items()}  # as --set reads them
                baseline = full_day(folder / "baseline", min(args.workers), {**shipped, **values}, label)[0]
            core_seconds, table = full_day(folder, min(args.workers), shipped, "as shipped")
            worst = with_families(folder, min(args.workers), table)
            families = whole_year_field(folder, max(args.workers))
            # the lines a script reads: the year-field estimate, in core-hours and on 2 workers
            print(f"year-field: {core_seconds / 3600:.2f} core-hours, {core_seconds / 2 / 3600:.2f} h on 2 workers")
            print(
                f"year-field: {families / 3600:.3f} core-hours (families), {core_seconds / 3600:.2f} core-hours "
                f"(full), certified max deviation {worst[0]} {worst[1]:.2e}"
            )
            if args.baseline_set:
                ratio = core_seconds / baseline
                print(f"  baseline ({label}): {baseline / 3600:.2f} core-hours; shipped / baseline {ratio:.2f}")


def full_day(folder: Path, n_workers: int, overrides: dict, label: str) -> tuple[float, object]:
    """Sunrise-to-sunset cases over the year and the estimate of year-field.yaml with ``overrides`` (its
    own, or changed): the core-seconds of the whole sweep in full (see the module docstring) and the cases'
    table."""
    folder.mkdir(parents=True, exist_ok=True)
    days = write_sweep(
        folder,
        "days",
        {"day_of_year": [*YEAR_SAMPLE_DAYS, LONGEST_DAY], "mirror": list(YEAR_MIRRORS)},
        overrides,
        shared_primary=True,
    )
    _, wall, outcome, cpu_seconds = timed_sweep(days, folder / "days", n_workers)
    table = outcome.table
    primary = table["role"] == "shared-primary"
    print(
        f"\nsunrise-to-sunset cases of year-field.yaml, {label} (days {YEAR_SAMPLE_DAYS} and {LONGEST_DAY} x "
        f"mirrors {YEAR_MIRRORS} and the shared primary: {len(table)} cases, {wall:.1f} s on {n_workers} "
        f"worker(s)); mean time of a case on its worker:"
    )
    print("  (the mirror cases' mean weighs the sampled mirrors equally, as the field's 13 are)")
    for day_of_year, rows in table.groupby("day_of_year"):
        mirrors, shared = rows[~primary.loc[rows.index]], rows[primary.loc[rows.index]]
        print(
            f"  day {int(day_of_year):3d}: {rows['duration_s'].iloc[0] / 3600:4.1f} h simulated, "
            f"{int(mirrors['steps_commanded'].max()):5d} steps: mirrors {mirrors['wall_time_s'].mean():5.2f} s, "
            f"primary ({int(shared['steps_commanded'].max())} steps) {shared['wall_time_s'].mean():5.2f} s"
        )
    spread = table["day_of_year"].isin(YEAR_SAMPLE_DAYS)
    per_mirror = table.loc[spread & ~primary, "wall_time_s"].mean()
    per_primary = table.loc[spread & primary, "wall_time_s"].mean()
    wall_seconds = 365 * 13 * per_mirror + 365 * per_primary
    # a supervised case runs on two cores at once (the child simulates, the worker computes the figures
    # from its rows): its CPU time, not its wall time, is what a full cluster pays per case
    cpu_ratio = cpu_seconds / table["wall_time_s"].sum()
    core_seconds = wall_seconds * cpu_ratio
    print(
        f"the workers' CPU time {cpu_seconds:.1f} s over the cases' {table['wall_time_s'].sum():.1f} s "
        f"of wall time: x{cpu_ratio:.2f} (the simulating child beside the worker)"
    )
    print(
        f"year-field.yaml = {YEAR_FIELD_CASES} cases: {core_seconds / 3600:.1f} core-hours from the spread "
        f"days' means ({per_mirror:.2f} s a mirror case, {per_primary:.2f} s a primary case, wall, x{cpu_ratio:.2f}"
        f" for the CPU); ideal scaling:"
    )
    for size in CLUSTER_SIZES:
        print(f"  {size:3d} workers: {duration_text(core_seconds / size)}")
    longest = table.loc[table["day_of_year"] == LONGEST_DAY, "wall_time_s"].max() * cpu_ratio
    print(
        f"  (were every case as slow as the longest day's slowest, {longest:.2f} s of CPU: "
        f"{duration_text(YEAR_FIELD_CASES * longest / 2)} on 2 workers)"
    )
    return core_seconds, table


def with_families(folder: Path, n_workers: int, exact) -> tuple[str, float]:
    """The same cases composed from their step families: each figure's largest deviation from the full runs
    (``exact``) over every case; the figure nearest its tolerance, and its deviation."""
    from heliostep.sweep.certificate import CERTIFIED_FIGURES, row_deviation

    days = folder / "days.yaml"
    _, wall, outcome, _ = timed_sweep(days, folder / "families", n_workers, exact=False)
    table = outcome.table.set_index("case_id")
    full = exact.set_index("case_id")
    methods = table["method"].value_counts().to_dict()
    print(f"\nthe same {len(table)} cases with step families: {wall:.1f} s on {n_workers} worker(s), rows {methods}")
    ratios = {}
    for name, tolerance in CERTIFIED_FIGURES.items():
        values = [row_deviation(full.loc[case_id], row, name) for case_id, row in table.iterrows()]
        ratios[name] = max(values)
        print(f"  {name:24s} largest deviation over every case {max(values):.2e} (tolerance {tolerance:.1e})")
    worst = max(ratios, key=lambda name: ratios[name] / (CERTIFIED_FIGURES[name] or 1.0))
    return worst, ratios[worst]


def whole_year_field(folder: Path, n_workers: int) -> float:
    """year-field.yaml run whole with its families, as ``heliostep sweep`` runs it, on a fresh local cluster of
    ``n_workers``: its CPU time [s], this process's (the sweep's client and the cluster's scheduler) and the
    workers' with their children, from reading the sweep file to the last row written."""
    import resource

    with local_client(n_workers) as client:
        workers_before = sum(client.run(worker_cpu_seconds).values())
        own = resource.getrusage(resource.RUSAGE_SELF)
        started = clock.perf_counter()
        outcome = execute_cases(expand_cases(load_sweep(YEAR_FIELD)), folder / "year-field.parquet", client=client)
        wall = clock.perf_counter() - started
        ended = resource.getrusage(resource.RUSAGE_SELF)
        workers = sum(client.run(worker_cpu_seconds).values()) - workers_before
    client_cpu = (ended.ru_utime - own.ru_utime) + (ended.ru_stime - own.ru_stime)
    methods = outcome.table["method"].value_counts().to_dict()
    if outcome.failed or len(outcome.table) != YEAR_FIELD_CASES:
        raise SystemExit(f"year-field: {outcome.failed} case(s) failed, {len(outcome.table)} rows")
    print(
        f"\nyear-field.yaml whole with families, measured: {len(outcome.table)} cases {methods}, "
        f"{wall / 60:.1f} min wall on {n_workers} worker(s); CPU {(client_cpu + workers) / 60:.1f} core-min "
        f"(client and scheduler {client_cpu / 60:.1f}, workers {workers / 60:.1f})"
    )
    return client_cpu + workers


if __name__ == "__main__":
    main()
