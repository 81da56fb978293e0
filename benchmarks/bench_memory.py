"""Peak memory (RSS) of ``heliostep run`` on long windows (prints figures; not a test).

    .venv/bin/python benchmarks/bench_memory.py [--hours 0.25 1 4 16] [--max-rss-mb N] [--csv] [--plots]

Per window (the paper's case with ``window.duration`` set, a 10 s output grid), a fresh ``heliostep run``
subprocess: wall time, trace rows, solver-step rows, ``trace.parquet``'s size, the peak RSS while simulating
and in all (``ru_maxrss`` from ``wait4``), and the growth per simulated hour. With ``--max-rss-mb`` the exit
status is 1 when a window's peak exceeds it.
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
SCENARIO = ROOT / "scenarios" / "jan21-central.yaml"
HELIOSTEP = [sys.executable, "-c", "from heliostep.cli import console_main; console_main()"]


def measure(hours: float, out: Path, csv: bool, plots: bool) -> dict:
    args = [
        *HELIOSTEP,
        "run",
        str(SCENARIO),
        "--out",
        str(out),
        *([] if plots else ["--no-plots"]),
        "--set",
        f"window.duration={hours * 3600:g}",
        "--set",
        "output.interval=10",
        "--csv" if csv else "--no-csv",
    ]
    started = time.perf_counter()
    process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - started
    stderr = process.stderr.read().decode(errors="replace")
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode != 0:
        raise SystemExit(f"heliostep run failed ({process.returncode}): {stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    metadata = json.loads((out / "metadata.json").read_text())
    return {
        "hours": hours,
        "wall_s": wall,
        "rows": summary["rows"],
        "solution_rows": metadata.get("solution_figures", {}).get("solution_rows"),
        "parquet_mb": (out / "trace.parquet").stat().st_size / 1e6,
        "simulating_mb": metadata.get("statistics", {}).get("peak_rss_mb_simulating") or float("nan"),
        "peak_rss_mb": usage.ru_maxrss / 1024,
    }  # ru_maxrss is in KiB on Linux


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hours", type=float, nargs="+", default=[0.25, 1.0, 4.0, 16.0])
    parser.add_argument("--max-rss-mb", type=float, default=None)
    parser.add_argument("--csv", action="store_true", help="also write trace.csv")
    parser.add_argument("--plots", action="store_true", help="also draw the figures")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="heliostep-bench-memory-") as tmp:
        print(
            f"{'hours':>6} {'wall [s]':>9} {'rows':>9} {'solver rows':>12} {'parquet [MB]':>13} "
            f"{'peak simulating [MB]':>21} {'peak RSS [MB]':>14}"
        )
        for hours in args.hours:
            r = measure(hours, Path(tmp) / f"h{hours:g}", args.csv, args.plots)
            rows.append(r)
            print(
                f"{r['hours']:6g} {r['wall_s']:9.1f} {r['rows']:9d} {r['solution_rows'] or 0:12d} "
                f"{r['parquet_mb']:13.2f} {r['simulating_mb']:21.0f} {r['peak_rss_mb']:14.0f}",
                flush=True,
            )
    if len(rows) > 1:
        first, last = rows[0], rows[-1]
        slope = (last["peak_rss_mb"] - first["peak_rss_mb"]) / (last["hours"] - first["hours"])
        per_row = (last["peak_rss_mb"] - first["peak_rss_mb"]) * 1e6 / max(last["rows"] - first["rows"], 1)
        print(
            f"peak RSS grows {slope:.1f} MB per simulated hour, {per_row:.0f} B per trace row "
            f"(a 10-day window: about {first['peak_rss_mb'] + slope * (240 - first['hours']):.0f} MB)"
        )
        sim_slope = (last["simulating_mb"] - first["simulating_mb"]) / (last["hours"] - first["hours"])
        after = max(r["peak_rss_mb"] - r["simulating_mb"] for r in rows)
        print(
            f"while simulating (master, trace stream, solution figures) it grows {sim_slope:.2f} MB per "
            f"simulated hour; the figures after the simulation add at most {after:.0f} MB over it"
        )
    if args.max_rss_mb is not None:
        over = [r for r in rows if r["peak_rss_mb"] > args.max_rss_mb]
        for r in over:
            print(f"over the bound: {r['hours']:g} h peaks at {r['peak_rss_mb']:.0f} MB > {args.max_rss_mb:g} MB")
        return 1 if over else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
