"""``heliostep run --band N`` over a sunrise-to-sunset day, its samples composed from step families beside
``--exact`` (every sample co-simulated in full), alternately in one sitting (prints figures; not a test).

    .venv/bin/python benchmarks/bench_band.py [--samples 8] [--repeat 1]

The wall time of the whole command on the local cluster (one worker per core), the nominal run included.
Last line: ``band <N> samples: <s> s (families), <s> s (--exact), ratio <r>, certified max deviation
<figure> <value>``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DAY = ["window.start=sunrise", "window.end=sunset", "window.duration=null", "output.step_detail=0"]
HELIOSTEP = [sys.executable, "-c", "from heliostep.cli import console_main; console_main()"]


def run_once(samples: int, exact: bool) -> tuple[float, dict]:
    """The wall time [s] of one band into a fresh folder, and its ``band`` record."""
    sets = [item for pair in DAY for item in ("--set", pair)]
    with tempfile.TemporaryDirectory() as folder:
        command = [*HELIOSTEP, "run", str(ROOT / "scenarios" / "jan21-central.yaml"), *sets, "--no-plots"]
        command += ["--band", str(samples), "--out", folder, *(["--exact"] if exact else [])]
        started = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True)
        wall = time.perf_counter() - started
        if done.returncode != 0:
            sys.exit(f"heliostep run --band failed:\n{done.stderr}")
        band = json.loads((Path(folder) / "summary.json").read_text())["band"]
    return wall, band


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    times: dict[bool, list[float]] = {False: [], True: []}
    worst = ("none", 0.0)
    for _ in range(args.repeat):
        for exact in (False, True):
            wall, band = run_once(args.samples, exact)
            times[exact].append(wall)
            print(f"{'--exact' if exact else 'families'}: {wall:.1f} s, {band['composition']['methods']}")
            for name, figure in band["composition"]["certificate"].items():
                deviation, tolerance = figure["max_deviation"], figure["tolerance"]
                if deviation is not None and tolerance and deviation / tolerance > worst[1]:  # (counts: exact)
                    worst = (f"{name} {deviation:.2e}", deviation / tolerance)
    composed, exact = min(times[False]), min(times[True])
    print(
        f"band {args.samples} samples: {composed:.1f} s (families), {exact:.1f} s (--exact), "
        f"ratio {composed / exact:.2f}, certified max deviation {worst[0]}"
    )


if __name__ == "__main__":
    main()
