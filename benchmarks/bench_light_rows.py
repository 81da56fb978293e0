"""A run's figures drawn on two cores with its figures' light kept, against the light computed again (prints figures).

    .venv/bin/python benchmarks/bench_light_rows.py [--repeat 9]

One run of the paper's case, then ``RunResult.plot`` (the 8 PNGs, a forked child drawing the power on the tube)
alternately with ``RunResult.light_rows`` (the light its figures computed at every row, as a held run draws it)
and without (the light computed again from the trace, as before), in one process, median of ``--repeat``; and
whether the power on the tube is the same PNG byte for byte. First line, for scripts:
``light rows: <s> s, again <s> s, ratio <r>``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from heliostep.paths import scenarios_dir
from heliostep.results.run_files import POWER_FILE
from heliostep.run import run_scenario


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args(argv)
    os.environ["HELIOSTEP_PARALLEL_PLOTS"] = "1"  # on two cores, as a run draws them
    kept = run_scenario(scenarios_dir() / "jan21-central.yaml")
    variants = {"kept": kept, "again": dataclasses.replace(kept, light_rows=None)}
    times: dict[str, list[float]] = {name: [] for name in variants}
    with tempfile.TemporaryDirectory() as tmp:
        kept.plot(Path(tmp) / "warm-up")
        for i in range(args.repeat):
            for name in sorted(variants, reverse=i % 2 == 1):  # alternating which goes first
                started = time.perf_counter()
                variants[name].plot(Path(tmp) / f"{name}{i}")
                times[name].append(time.perf_counter() - started)
        same = all(
            (Path(tmp) / f"kept{i}" / POWER_FILE).read_bytes() == (Path(tmp) / f"again{i}" / POWER_FILE).read_bytes()
            for i in range(args.repeat)
        )
    medians = {name: statistics.median(values) for name, values in times.items()}
    ratio = medians["kept"] / medians["again"]
    print(f"light rows: {medians['kept']:.3f} s, again {medians['again']:.3f} s, ratio {ratio:.3f}")
    for name, values in times.items():
        print(f"  {name:6s} " + " ".join(f"{value:.2f}" for value in values))
    print(
        f"  {POWER_FILE} the same byte for byte: {same}; load {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores"
    )
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
