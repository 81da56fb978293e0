"""A day tracked closed loop and hybrid beside the same day open loop (prints figures; not a test).

    .venv/bin/python benchmarks/bench_closed_loop.py [--repeat N] [--scenario NAME]

``run_scenario`` on ``jan21-day`` (sunrise to sunset) in each ``tracking.mode``, the default sensor and
controller (in this process, no plots): the best wall time of N, its ratio to open loop's, the steps
commanded and the worst tracking error. Last, one line for scripts:
``closed-loop day: <ratio> x open loop, hybrid <ratio> x``.
"""

from __future__ import annotations

import argparse
import time

MODES = ("open_loop", "closed_loop", "hybrid")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--scenario", default="jan21-day")
    args = parser.parse_args()

    from heliostep.run import RunOptions, run_scenario
    from heliostep.scenario import load_scenario

    best: dict[str, float] = {}
    print(f"{'mode':<12} {'wall [s]':>9} {'x open':>7} {'steps':>6} {'max error [deg]':>16}")
    for mode in MODES:
        scenario = load_scenario(args.scenario, (f"tracking.mode={mode}",))
        times = []
        for _ in range(args.repeat):
            started = time.perf_counter()
            result = run_scenario(scenario, RunOptions(supervise=False))
            times.append(time.perf_counter() - started)
        best[mode] = min(times)
        summary = result.summary
        print(
            f"{mode:<12} {best[mode]:9.2f} {best[mode] / best['open_loop']:7.2f} "
            f"{summary['steps_commanded']:6d} {summary['max_tracking_error_deg']:16.4f}"
        )
    closed, hybrid = best["closed_loop"] / best["open_loop"], best["hybrid"] / best["open_loop"]
    print(f"closed-loop day: {closed:.2f} x open loop, hybrid {hybrid:.2f} x")


if __name__ == "__main__":
    main()
