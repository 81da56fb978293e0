"""How far each regression signal moves with the solver's tolerance, beside its tube (prints a table).

    .venv/bin/python benchmarks/tolerance_study.py [scenario.yaml ...] [--factor 100]

Per shipped scenario (default: all) and regression signal: the largest |difference| between the run at the
scenario's rtol and at rtol / ``--factor`` (the solver error), the tube of ``scenarios/regress-tolerances.yaml``
at the signal's largest magnitude, and their ratio; exit status 1 when a tube is less than twice the solver error.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _run(path: Path, overrides=()):
    from heliostep.run import run_scenario

    return run_scenario(path, overrides=tuple(overrides))


def _largest_difference(a, b, signal: str) -> float:
    """Row by row: both runs have the same rows (the output grid and two rows at every event)."""
    if len(a) != len(b) or not np.array_equal(a["time"].to_numpy(), b["time"].to_numpy()):
        raise SystemExit(f"{signal}: the runs' rows differ ({len(a)} vs {len(b)} rows)")
    return float(np.max(np.abs(a[signal].to_numpy() - b[signal].to_numpy())))


def main() -> int:
    from heliostep.results.compare.regress import reference_signals, shipped_scenarios, tolerances_path
    from heliostep.results.compare.traces import load_tolerances
    from heliostep.scenario import load_scenario

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--factor", type=float, default=100.0)
    args = parser.parse_args()
    paths = [Path(p) for p in args.scenarios] or shipped_scenarios()
    tolerances = load_tolerances(tolerances_path())
    print(f"{'scenario':22} {'signal':20} {'solver':>10} {'tube':>10} {'tube/solver':>11}")
    worst = np.inf
    for path in paths:
        scenario = load_scenario(path)
        tight = [f"solver.rtol={scenario.solver.rtol / args.factor:g}"]
        if scenario.solver.atol is not None:
            tight.append(f"solver.atol={scenario.solver.atol / args.factor:g}")
        default, fine = _run(path), _run(path, tight)
        roles = default.metadata["roles"]
        for signal in (s for s in reference_signals(roles) if s in default.trace):
            solver_error = _largest_difference(default.trace, fine.trace, signal)
            tolerance = tolerances.for_scenario(scenario.name).for_signal(signal)
            tube = max(tolerance.abs, tolerance.rel * float(np.max(np.abs(default.trace[signal]))))
            ratio = tube / solver_error if solver_error > 0 else np.inf
            worst = min(worst, ratio)
            print(
                f"{path.stem:22} {signal:20} {solver_error:10.2e} {tube:10.2e} {ratio:11.1f}",
                flush=True,
            )
    print(f"smallest tube / solver error: {worst:.1f}")
    return 0 if worst >= 2 else 1


if __name__ == "__main__":
    sys.exit(main())
