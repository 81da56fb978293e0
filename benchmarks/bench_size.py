"""README's ``heliostep size`` example timed from outside, beside another checkout's (prints figures; not a test).

    .venv/bin/python benchmarks/bench_size.py [--repeat 2] [--baseline SRC] [--set KEY=VALUE ...]

The wall time of the whole process of ``heliostep size scenarios/jan21-central.yaml --design-gust 30``,
alternating with the same command on the code in ``SRC`` (another checkout's ``src``, through ``PYTHONPATH``)
where given; best of N each. Last line: ``size: <s> s, baseline <s> s, ratio <r>``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ["size", str(ROOT / "scenarios" / "jan21-central.yaml"), "--design-gust", "30"]
HELIOSTEP = [sys.executable, "-c", "from heliostep.cli import console_main; console_main()"]


def run_once(extra: list[str], src: str | None) -> float:
    """The wall time [s] of one sizing into a fresh folder."""
    env = {**os.environ, **({"PYTHONPATH": src} if src else {})}
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        done = subprocess.run([*HELIOSTEP, *COMMAND, *extra, "--out", folder], capture_output=True, text=True, env=env)
        wall = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"heliostep size failed ({src or 'this tree'}):\n{done.stderr}")
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--baseline", help="another checkout's src folder, run alternately")
    parser.add_argument("--set", action="append", default=[], help="KEY=VALUE passed to heliostep size --set")
    args = parser.parse_args()
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
