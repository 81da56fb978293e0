"""How far each regression signal moves with the solver's path and its tolerance (prints a table).

    .venv/bin/python benchmarks/tolerance_study.py [scenario.yaml ...] [--factor 100]

For each shipped scenario (default: all of them) and each signal the regression compares, the
largest |difference| between runs of the same scenario:

- ``path``: output rows interpolated from CVODE's polynomial (the default) against CVODE
  stopping at every output time, both at the scenario's rtol: what the choice of path moves;
- ``solver``: the default path at the scenario's rtol against rtol / ``--factor``: the solver
  error at the scenario's tolerance (the tighter run is the better answer);

beside the regression tube (``scenarios/regress-tolerances.yaml``, the half-width at the
signal's largest magnitude). A tube narrower than the solver error would fail on a change that
is only solver noise; a tube much wider than it would hide real changes. The ratio
``tube / solver`` is printed; the tubes are chosen so it is at least 2 for every scenario.
Not a test (it runs every scenario three times).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _run(path: Path, interpolate: bool, overrides=()):
    import heliostep.cosim.master as master
    from heliostep.run import run_scenario

    saved = master.INTERPOLATE_OUTPUTS
    master.INTERPOLATE_OUTPUTS = interpolate
    try:
        return run_scenario(path, tuple(overrides))
    finally:
        master.INTERPOLATE_OUTPUTS = saved


def _largest_difference(a, b, signal: str) -> float:
    """Row by row: both runs have the same rows (the output grid and two rows at every event)."""
    if len(a) != len(b) or not np.array_equal(a["time"].to_numpy(), b["time"].to_numpy()):
        raise SystemExit(f"{signal}: the runs' rows differ ({len(a)} vs {len(b)} rows)")
    return float(np.max(np.abs(a[signal].to_numpy() - b[signal].to_numpy())))


def main() -> int:
    from heliostep.results.compare import load_tolerances
    from heliostep.results.regress import reference_signals, shipped_scenarios, tolerances_path
    from heliostep.scenario import load_scenario

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--factor", type=float, default=100.0)
    args = parser.parse_args()
    paths = [Path(p) for p in args.scenarios] or shipped_scenarios()
    tolerances = load_tolerances(tolerances_path())
    print(f"{'scenario':22} {'signal':20} {'path':>10} {'solver':>10} {'tube':>10} {'tube/solver':>11}")
    worst = np.inf
    for path in paths:
        scenario = load_scenario(path)
        tight = [f"solver.rtol={scenario.solver.rtol / args.factor:g}"]
        if scenario.solver.atol is not None:
            tight.append(f"solver.atol={scenario.solver.atol / args.factor:g}")
        default, stopped, fine = _run(path, True), _run(path, False), _run(path, True, tight)
        roles = default.metadata["roles"]
        for signal in (s for s in reference_signals(roles) if s in default.trace):
            path_move = _largest_difference(default.trace, stopped.trace, signal)
            solver_error = _largest_difference(default.trace, fine.trace, signal)
            tolerance = tolerances.for_scenario(scenario.name).for_signal(signal)
            tube = max(tolerance.abs, tolerance.rel * float(np.max(np.abs(default.trace[signal]))))
            ratio = tube / solver_error if solver_error > 0 else np.inf
            worst = min(worst, ratio)
            print(
                f"{path.stem:22} {signal:20} {path_move:10.2e} {solver_error:10.2e} {tube:10.2e} {ratio:11.1f}",
                flush=True,
            )
    print(f"smallest tube / solver error: {worst:.1f}")
    return 0 if worst >= 2 else 1


if __name__ == "__main__":
    sys.exit(main())
