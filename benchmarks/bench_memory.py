"""Peak memory (RSS) of ``heliostep run`` on long windows, or of README's ``heliostep end-loss`` (prints
figures; not a test).

    .venv/bin/python benchmarks/bench_memory.py [--hours 0.25 1 4 16] [--max-rss-mb N] [--csv] [--plots]
    .venv/bin/python benchmarks/bench_memory.py --end-loss [--against /work/base] [--repeat 2] [--max-rss-mb N]

Per window (the paper's case with ``window.duration`` set, a 10 s output grid), a fresh ``heliostep run``
subprocess: wall time, trace rows, solver-step rows, ``trace.parquet``'s size, the peak RSS while simulating
and in all (``ru_maxrss`` from ``wait4``: the child's own, where ``RUSAGE_CHILDREN`` would keep the largest
of all the children so far), and the growth per simulated hour. With ``--max-rss-mb`` the exit status is 1
when a window's peak exceeds it.

``--end-loss``: README's example, ``heliostep end-loss --latitude 40 --length 100 --tube-height 5`` (a year
at 5 min, shading and blocking), in a fresh subprocess: wall, user and system CPU time, peak RSS, and the
21 December line it prints; with ``--against`` another checkout (its ``src`` first on the path) run
alternately with this one, the best of ``--repeat`` each, and whether their day tables are the same.
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


#: README's example of ``heliostep end-loss`` (its defaults written out).
END_LOSS = ["end-loss", "--latitude", "40", "--length", "100", "--tube-height", "5"]


def measure_end_loss(checkout: Path, out: Path) -> dict:
    """README's ``end-loss`` run from ``checkout``'s sources in a fresh subprocess: its times [s], peak RSS
    [MB] and the lines it printed."""
    env = {**os.environ, "PYTHONPATH": str(checkout / "src")}
    with tempfile.TemporaryFile("w+") as printed, tempfile.TemporaryFile("w+") as said:
        started = time.perf_counter()
        process = subprocess.Popen([*HELIOSTEP, *END_LOSS, "--out", str(out)], stdout=printed, stderr=said, env=env)
        _, status, usage = os.wait4(process.pid, 0)
        wall = time.perf_counter() - started
        printed.seek(0), said.seek(0)
        lines, errors = printed.read().splitlines(), said.read()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{checkout}: end-loss failed: {errors[-2000:]}")
    return {
        "checkout": str(checkout),
        "wall_s": wall,
        "user_s": usage.ru_utime,
        "system_s": usage.ru_stime,
        "peak_rss_mb": usage.ru_maxrss / 1024,  # KiB on Linux
        "december": next((line.strip() for line in lines if "21 December" in line), ""),
        "table": (out / "end_loss_days.csv").read_text(),
    }


def end_loss_main(args: argparse.Namespace) -> int:
    checkouts = [ROOT] + ([Path(args.against).resolve()] if args.against else [])
    best: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="heliostep-bench-memory-") as tmp:
        print(f"{'checkout':<28} {'wall [s]':>9} {'user [s]':>9} {'system [s]':>11} {'peak RSS [MB]':>14}")
        for attempt in range(args.repeat):
            for index, checkout in enumerate(checkouts):  # alternately: a busy machine slows both alike
                r = measure_end_loss(checkout, Path(tmp) / f"{index}-{attempt}")
                name = str(checkout)[-28:]
                print(
                    f"{name:<28} {r['wall_s']:9.1f} {r['user_s']:9.1f} {r['system_s']:11.1f} {r['peak_rss_mb']:14.0f}",
                    flush=True,
                )
                kept = best.get(r["checkout"])
                if kept is None or r["user_s"] + r["system_s"] < kept["user_s"] + kept["system_s"]:
                    best[r["checkout"]] = r
    for r in best.values():
        print(f"{r['checkout']}: best {r['user_s'] + r['system_s']:.1f} CPU s, peak {r['peak_rss_mb']:.0f} MB")
        print(f"  {r['december']}")
    if len(best) == 2:
        mine, other = (best[str(c)] for c in checkouts)
        columns = len(other["table"].partition("\n")[0].split(","))  # the other's columns (new ones come last)
        lines = zip(mine["table"].splitlines(), other["table"].splitlines())
        same = [a.split(",")[:columns] == b.split(",")[:columns] for a, b in lines]
        print(f"day tables: {sum(same)} of {len(same)} lines the same in the {columns} columns they share")
    if args.max_rss_mb is not None and best[str(ROOT)]["peak_rss_mb"] > args.max_rss_mb:
        print(f"over the bound: {best[str(ROOT)]['peak_rss_mb']:.0f} MB > {args.max_rss_mb:g} MB")
        return 1
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hours", type=float, nargs="+", default=[0.25, 1.0, 4.0, 16.0])
    parser.add_argument("--max-rss-mb", type=float, default=None)
    parser.add_argument("--csv", action="store_true", help="also write trace.csv")
    parser.add_argument("--plots", action="store_true", help="also draw the figures")
    parser.add_argument("--end-loss", action="store_true", help="README's end-loss instead of run")
    parser.add_argument("--against", metavar="CHECKOUT", help="with --end-loss: also this checkout, alternately")
    parser.add_argument("--repeat", type=int, default=1, help="with --end-loss: runs of each, the best kept")
    args = parser.parse_args()
    if args.end_loss:
        return end_loss_main(args)
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
