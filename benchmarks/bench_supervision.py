"""What supervision costs (issue 22): jan21-day in-process and supervised, side by side in one run.

    .venv/bin/python benchmarks/bench_supervision.py [--repeat N] [--scenario FILE]

A supervised run (``run_scenario(..., supervise=True)``, the default; heliostep.run.supervised)
simulates in a child process (``python -m heliostep.cosim.child``) that streams its rows back;
an in-process one (``supervise=False``, ``heliostep run --no-supervise``) calls the FMUs in the
process itself. The two are run alternately ``--repeat`` times (the machine's load drifts alike
for both) and the wall time of the whole ``run_scenario`` call is printed per run, with the
median of each and their ratio. Also checked: both give the same trace, bit for bit.
Prints figures; not a test.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "jan21-day.yaml")
    args = parser.parse_args()

    from heliostep.run import run_scenario

    run_scenario(args.scenario, supervise=False)  # FMUs and kernel built, files cached: not timed
    times: dict[bool, list[float]] = {False: [], True: []}
    traces = {}
    for k in range(args.repeat):
        for supervise in (False, True) if k % 2 == 0 else (True, False):
            start = time.perf_counter()
            result = run_scenario(args.scenario, supervise=supervise)
            times[supervise].append(time.perf_counter() - start)
            traces[supervise] = result.trace
            print(f"  run {k + 1}: {'supervised ' if supervise else 'in-process '} {times[supervise][-1]:7.3f} s")
    same = list(traces[False].columns) == list(traces[True].columns) and all(
        np.array_equal(traces[False][c].to_numpy(), traces[True][c].to_numpy(), equal_nan=True)
        for c in traces[False].columns
    )
    inside, supervised = statistics.median(times[False]), statistics.median(times[True])
    print(f"{args.scenario.name}: {len(traces[True])} trace rows, {args.repeat} runs each")
    print(f"  in-process  median {inside:7.3f} s  (min {min(times[False]):.3f})")
    print(f"  supervised  median {supervised:7.3f} s  (min {min(times[True]):.3f})")
    print(
        f"  supervised / in-process: {supervised / inside:.3f} (medians), "
        f"{min(times[True]) / min(times[False]):.3f} (minima)"
    )
    print(f"  same trace bit for bit: {same}")


if __name__ == "__main__":
    main()
