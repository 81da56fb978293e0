"""What supervision costs: jan21-day in-process and supervised, side by side in one run.

    .venv/bin/python benchmarks/bench_supervision.py [--repeat N] [--scenario FILE]

A supervised run (``run_scenario(..., supervise=True)``, the default; heliostep.run.supervision.supervisor)
simulates in a forked child process (heliostep.run.supervision.child) that streams its rows and figures back;
an in-process one (``supervise=False``, ``heliostep run --no-supervise``) calls the FMUs in the
process itself. The two are run alternately ``--repeat`` times (the machine's load drifts alike
for both) and the wall time of the whole ``run_scenario`` call is printed per run, with the
median of each and their ratio. Also checked: both give the same trace, bit for bit.
Supervised runs are timed for each ``--block-rows`` (the child's kernel block and outbox bound,
heliostep.run.supervision.child.BLOCK_ROWS; a crash loses none: the child's row journal keeps what no
message carried).
Prints figures; not a test.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--scenario", type=Path, default=ROOT / "scenarios" / "jan21-day.yaml")
    parser.add_argument(
        "--block-rows",
        type=int,
        nargs="+",
        default=[128, 4096],
        help="the supervised child's block sizes to time (run.supervision.child.BLOCK_ROWS; 128 is the default)",
    )
    args = parser.parse_args()

    import heliostep.run.supervision.child as child
    from heliostep.run import RunOptions, run_scenario

    run_scenario(args.scenario, RunOptions(supervise=False))  # FMUs and kernel built, files cached: not timed
    modes: list[int | None] = [None, *args.block_rows]  # None: in-process
    times: dict[int | None, list[float]] = {mode: [] for mode in modes}
    cpu: dict[int | None, list[float]] = {mode: [] for mode in modes}  # [s] this process's and the child's
    traces = {}
    for k in range(args.repeat):
        for mode in modes[k % len(modes) :] + modes[: k % len(modes)]:  # each first in turn: the load drifts alike
            if mode is not None:
                child.BLOCK_ROWS = mode  # read by the forked child
            start, cpu_start = time.perf_counter(), _cpu_seconds()
            result = run_scenario(args.scenario, RunOptions(supervise=mode is not None))
            times[mode].append(time.perf_counter() - start)
            cpu[mode].append(_cpu_seconds() - cpu_start)
            traces[mode] = result.trace
            print(f"  run {k + 1}: {_label(mode):34s} {times[mode][-1]:7.3f} s, CPU {cpu[mode][-1]:7.3f} s")
    reference = traces[None]
    print(f"{args.scenario.name}: {len(reference)} trace rows, {args.repeat} runs each")
    inside, inside_cpu = statistics.median(times[None]), statistics.median(cpu[None])
    for mode in modes:
        same = list(reference.columns) == list(traces[mode].columns) and all(
            np.array_equal(reference[c].to_numpy(), traces[mode][c].to_numpy(), equal_nan=True)
            for c in reference.columns
        )
        median = statistics.median(times[mode])
        print(
            f"  {_label(mode):34s} median {median:7.3f} s (min {min(times[mode]):.3f}); "
            f"/ in-process {median / inside:.3f}; CPU median {statistics.median(cpu[mode]):7.3f} s, "
            f"/ in-process {statistics.median(cpu[mode]) / inside_cpu:.3f}; same trace bit for bit: {same}"
        )


def _cpu_seconds() -> float:
    """CPU time [s] of this process and of its children that ended (the supervised child)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _label(mode: int | None) -> str:
    return "in-process" if mode is None else f"supervised, {mode}-row blocks (lost < {2 * mode})"


if __name__ == "__main__":
    main()
