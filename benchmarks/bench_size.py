"""README's ``heliostep size`` example timed from outside, beside another checkout's (prints figures; not a test).

    .venv/bin/python benchmarks/bench_size.py [--repeat 2] [--baseline SRC] [--set KEY=VALUE ...]
        [--days-all [--candidate NAME ...]]

The wall time of the whole process of ``heliostep size scenarios/jan21-central.yaml --design-gust 30``,
alternating with the same command on the code in ``SRC`` (another checkout's ``src``, through ``PYTHONPATH``)
where given; best of N each. Last line: ``size: <s> s, baseline <s> s, ratio <r>``.

``--days-all``: the same with ``--days all`` (the shipped catalogue, or its ``--candidate`` entries, and their
currents, every day, and again at the ranges' worst corner) once, its days composed from step families on the
machine's cores; its wall time, and beside it the full co-simulation's CPU, estimated from the days
co-simulated in full (the certificate's, those that fell back) times the days. Last line:
``size --days all: <min> min on <n> cores (families), full co-simulation <h> core-hours (<min> min on <n> cores)``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ["size", str(ROOT / "scenarios" / "jan21-central.yaml"), "--design-gust", "30"]
HELIOSTEP = [sys.executable, "-c", "from heliostep.cli import console_main; console_main()"]


def run_once(extra: list[str], src: str | None, sheet: dict | None = None) -> float:
    """The wall time [s] of one sizing into a fresh folder (its ``sizing.json`` into ``sheet`` if given)."""
    env = {**os.environ, **({"PYTHONPATH": src} if src else {})}
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        done = subprocess.run([*HELIOSTEP, *COMMAND, *extra, "--out", folder], capture_output=True, text=True, env=env)
        wall = time.perf_counter() - started
        if sheet is not None and done.returncode == 0:
            sheet.update(json.loads((Path(folder) / "sizing.json").read_text()))
    if done.returncode != 0:
        sys.exit(f"heliostep size failed ({src or 'this tree'}):\n{done.stderr}")
    return wall


def days_all(candidates: list[str]) -> None:
    """``--days all`` with families (of ``candidates`` alone, where named), and the full co-simulation's
    estimate from the days co-simulated in full."""
    sheet: dict = {}
    named = [item for name in candidates for item in ("--candidate", name)]
    wall = run_once(["--days", "all", "--max-cases", "30000", *named], None, sheet)
    records = [
        record
        for candidate in sheet["candidates"]
        for current in candidate["currents"]
        for record in (current.get("simulation") or {}).get("per_day", {}).values()
    ]
    methods = sheet["composition"]["methods"]
    full = [record["wall_time_s"] for record in records if record.get("method") in ("full", "certificate")]
    fell_back = sum(1 for record in records if record.get("method") == "full")
    days = sum(methods.values())
    estimate = days * sum(full) / len(full)
    cores = os.cpu_count() or 1
    print(
        f"days {days}: {methods}; a day in full {sum(full) / len(full):.2f} s (mean of {len(full)}), "
        f"{fell_back} fell back"
    )
    for name, figure in sheet["composition"]["certificate"].items():
        print(
            f"  {name:24s} certified max deviation {figure['max_deviation']:.2e} (tolerance {figure['tolerance']:.1e})"
        )
    print(
        f"size --days all: {wall / 60:.1f} min on {cores} cores (families), "
        f"full co-simulation {estimate / 3600:.2f} core-hours ({estimate / cores / 60:.1f} min on {cores} cores)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--baseline", help="another checkout's src folder, run alternately")
    parser.add_argument("--set", action="append", default=[], help="KEY=VALUE passed to heliostep size --set")
    parser.add_argument("--days-all", action="store_true", help="--days all, composed, beside full's estimate")
    parser.add_argument("--candidate", action="append", default=[], help="with --days-all: only this catalogue entry")
    args = parser.parse_args()
    if args.days_all:
        days_all(args.candidate)
        return
    extra = [item for pair in args.set for item in ("--set", pair)]
    variants = {"this tree": None, **({"baseline": args.baseline} if args.baseline else {})}
    times: dict[str, list[float]] = {name: [] for name in variants}
    for k in range(args.repeat):
        for name, src in variants.items():
            times[name].append(run_once(extra, src))
            print(f"{k + 1}  {name:<10} wall {times[name][-1]:7.1f} s", flush=True)
    best = {name: min(runs) for name, runs in times.items()}
    if args.baseline:
        ratio = best["this tree"] / best["baseline"]
        print(f"size: {best['this tree']:.1f} s, baseline {best['baseline']:.1f} s, ratio {ratio:.2f}")
    else:
        print(f"size: {best['this tree']:.1f} s")


if __name__ == "__main__":
    main()
