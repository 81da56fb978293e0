"""How much each summary figure moves with a 100x tighter tolerance and a 100x finer output grid.

    .venv/bin/python benchmarks/check_convergence.py [scenario.yaml] [--factor 100] [--set key=value ...]

Runs the scenario (default scenarios/jan21-central.yaml) as it is, then with ``solver.rtol``
(and ``solver.atol``, when set) divided by ``--factor`` ("rtol"), with the output grid
(``output.interval`` and ``output.step_interval``) made ``--factor`` times finer ("grid"), and
with both ("both"), and prints per summary figure every value with its relative change
|variant - base| / |variant| and absolute change (figures near zero, e.g. ``final_lag_steps``,
are judged by the absolute one). A variant that fails is reported as failed (exit status 1). The figures come
from every solver step, so the output grid should not move them; what moves is solver error.
Exit status 1 when ``--max-change`` is given and a numeric figure moved by more than it.
Not a test (the fine run takes tens of seconds).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from heliostep.run import RunFailed, run_scenario
from heliostep.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
FIGURES = (
    "max_tracking_error_deg",
    "rms_tracking_error_deg",
    "peak_torque_Nm",
    "peak_phase_current_A",
    "electrical_energy_J",
    "settling_time_s.max",
    "settling_time_s.mean",
    "settling_time_s.not_settled",
    "steps_commanded",
    "steps_executed",
    "missed_steps",
    "steps_lost",
    "final_lag_steps",
    "final_panel_angle_deg",
)


def _value(summary: dict, key: str):
    for part in key.split("."):
        summary = summary.get(part) if isinstance(summary, dict) else None
    return summary


def fine_overrides(scenario_path: Path, factor: float, extra: list[str]) -> dict[str, list[str]]:
    """The variants: tolerance only, output grid only, both."""
    scenario = load_scenario(scenario_path, extra)
    tolerance = [f"solver.rtol={scenario.solver.rtol / factor:g}"]
    if scenario.solver.atol is not None:
        tolerance.append(f"solver.atol={scenario.solver.atol / factor:g}")
    grid = [
        f"output.interval={scenario.output.interval / factor:g}",
        f"output.step_interval={scenario.output.step_interval / factor:g}",
    ]
    return {"rtol": tolerance, "grid": grid, "both": tolerance + grid}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "jan21-central.yaml"))
    parser.add_argument("--factor", type=float, default=100.0)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--max-change", type=float, default=None, help="fail when a figure moves more (relative)")
    args = parser.parse_args()
    path = Path(args.scenario)
    variants = {"base": [], **fine_overrides(path, args.factor, args.overrides)}
    runs, failed = {}, False
    for name, overrides in variants.items():
        started = time.perf_counter()
        try:
            runs[name] = run_scenario(path, overrides=[*args.overrides, *overrides]).summary
            print(
                f"{name}: {time.perf_counter() - started:.1f} s wall, {runs[name]['rows']} trace rows "
                f"({', '.join(overrides) or 'as the scenario is'})",
                flush=True,
            )
        except RunFailed as exc:
            failed = True
            print(f"{name}: FAILED ({', '.join(overrides)}): {exc}", flush=True)
    if "base" not in runs:
        return 1
    others = [n for n in variants if n != "base" and n in runs]
    print(f"{'figure':30} {'base':>16}" + "".join(f" {n:>16} {'rel.':>9} {'abs.':>9}" for n in others))
    worst = 0.0
    for key in FIGURES:
        base = _value(runs["base"], key)
        line = f"{key:30} {_fmt(base):>16}"
        for name in others:
            value = _value(runs[name], key)
            if isinstance(base, (int, float)) and isinstance(value, (int, float)):
                change = abs(value - base) / abs(value) if value else (0.0 if base == value else math.inf)
                worst = max(worst, change)
                line += f" {_fmt(value):>16} {change:9.2e} {abs(value - base):9.2e}"
            else:
                line += f" {_fmt(value):>16} {'' if value == base else 'differs':>9} {'':>9}"
        print(line)
    print(f"largest relative change: {worst:.2e}" + (" (a variant failed)" if failed else ""))
    if failed or (args.max_change is not None and worst > args.max_change):
        return 1
    return 0


def _fmt(value) -> str:
    return f"{value:.10g}" if isinstance(value, float) else str(value)


if __name__ == "__main__":
    sys.exit(main())
