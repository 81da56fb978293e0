"""Speed of the co-simulation master (prints figures; not a test).

    .venv/bin/python benchmarks/bench_run.py [--skip-day] [--profile] [--repeat N]

Printed side by side in one run:
1. the paper's 5-minute case (scenarios/jan21-central.yaml): simulation wall time, RHS evaluations;
2. sunrise to sunset (scenarios/jan21-day.yaml): simulation wall time, RHS per motor step;
3. the same day with fmpy.simulate_fmu on the monolithic DriveSystem FMU (same inputs, start
   values, tolerance and output grid) and the ratio master / fmpy;
each for the master's two right-hand sides: the Python callbacks (the path of systems the kernel
cannot take, forced here) and the compiled kernel (heliostep.cosim.kernel: right-hand side, root
function and the loop over CVODE's internal steps in C; the default), the output rows interpolated.
4. RHS evaluations per motor step of the paper's case with a smooth current loop, a chopper
   that never saturates, a wider friction regularisation and a looser tolerance (what sets them);
5. with --profile: where the time of the 5-minute case goes (cProfile, top functions);
6. last, unless --skip-day, one line for scripts, ``day: <s> s, floor <s> s, ratio <r>, fmpy <r>``: the
   day's simulation on the default path, the plain-C floor's (benchmarks/floor_plain_c.py, the same CVODE),
   heliostep / floor and heliostep / fmpy, all measured in this run.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"


def best_of(function, repeat: int):
    """Smallest wall time of ``repeat`` calls, and the last result."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


#: the master's paths: (label, compiled right-hand side)
PATHS = [
    ("python callbacks", False),
    ("compiled kernel (default)", True),
]


def run_path(name: str, compiled: bool, repeat: int):
    """run_scenario on one path: (best simulation wall time, run, the CoSimulation and its arguments)."""
    import heliostep.cosim.integrator as integrator
    import heliostep.cosim.master as master
    from heliostep.run import run_scenario

    captured = {}
    simulate = master.CoSimulation.simulate

    def capture(self, *args, **kwargs):
        captured.update(system=self, args=args)
        return simulate(self, *args, **kwargs)

    chosen = integrator.compiled_kernel
    integrator.compiled_kernel = chosen if compiled else (lambda *args: None)
    master.CoSimulation.simulate = capture
    try:
        walls, run = [], None
        for _ in range(repeat):
            run = run_scenario(SCENARIOS / f"{name}.yaml")
            walls.append(run.metadata["statistics"]["wall_time"])
    finally:
        master.CoSimulation.simulate = simulate
        integrator.compiled_kernel = chosen
    return min(walls), run, captured


def monolithic(captured, repeat: int) -> tuple[float, dict]:
    """fmpy.simulate_fmu on DriveSystem with the master's inputs, start values, rtol and grid."""
    from fmpy import simulate_fmu

    from heliostep.cosim.fmi import read_fmu
    from heliostep.fmu.build import ensure_fmu

    system, (start, stop, grid, solver) = captured["system"], captured["args"][:4]
    drive = str(ensure_fmu("DriveSystem"))
    variables = read_fmu(drive).variables
    inputs = [s for s in system.inputs if s.target.split(".", 1)[1] in variables]
    edges = np.unique(np.concatenate([[start, stop], *[s.times for s in inputs]]))
    rows = []
    for k in range(len(edges) - 1):  # a repeated time is a step in fmpy's input table
        values = tuple(s.value_at(edges[k]) for s in inputs)
        rows += [(edges[k], *values), (edges[k + 1], *values)]
    table = np.array(rows, dtype=[("time", float)] + [(s.target.split(".", 1)[1], float) for s in inputs])
    start_values = {
        f"{instance}.{name}": value
        for instance, values in system.parameters.items()
        for name, value in values.items()
        if f"{instance}.{name}" in variables
    }
    interval = float(np.median(np.diff(grid)))

    def call():
        # fmpy's CVodeSolver allows 500 steps per output interval: give it the master's limit
        import fmpy.sundials as sundials

        original = sundials.CVodeSolver

        class Solver(original):
            def __init__(self, **kwargs):
                super().__init__(**{**kwargs, "maxNumSteps": solver.max_num_steps})

        sundials.CVodeSolver = Solver
        try:
            return simulate_fmu(
                drive,
                fmi_type="ModelExchange",
                solver="CVode",
                start_time=start,
                stop_time=stop,
                output_interval=interval,
                relative_tolerance=solver.rtol,
                input=table,
                start_values=start_values,
                output=["mechanics.theta", "motor.tau"],
            )
        finally:
            sundials.CVodeSolver = original

    return best_of(call, repeat)


def bench(name: str, repeat: int, against_fmpy: bool) -> tuple[float, float | None]:
    """Print each path's line; return the default path's wall time [s] and fmpy's [s] (None without it)."""
    fmpy_wall = None
    for label, compiled in PATHS:
        wall, run, captured = run_path(name, compiled, repeat)
        stats = run.metadata["statistics"]
        steps = max(1, int(run.summary["steps_commanded"]))
        line = (
            f"{name:14s} {label:40s} simulation {wall:7.3f} s  {stats['rhs']:>9,d} RHS  "
            f"{stats['rhs'] / steps:7.1f} RHS/motor step  {stats['integrator_calls']:>6,d} solver calls"
        )
        if against_fmpy:
            if fmpy_wall is None:
                fmpy_wall, reference = monolithic(captured, 1)
                last = (
                    abs(run.trace["mechanics.theta"].iloc[-1] - reference["mechanics.theta"][-1])
                    if "mechanics.theta" in run.trace
                    else float("nan")
                )
                print(
                    f"{name:14s} {'fmpy.simulate_fmu on DriveSystem':40s} simulation {fmpy_wall:7.3f} s  "
                    f"(final rotor angles of the first path differ by {last:.1e} rad)"
                )
            line += f"  = {wall / fmpy_wall:.2f}x fmpy"
        print(line, flush=True)
    return wall, fmpy_wall


def floor_time(name: str, repeat: int) -> float:
    """The plain-C floor's simulation time [s] of ``name`` (benchmarks/floor_plain_c.py), best of ``repeat``."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import floor_plain_c
    from heliostep.drive.inputs import prepare_inputs
    from heliostep.scenario import load_scenario

    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    inputs = prepare_inputs(scenario)
    with tempfile.TemporaryDirectory() as folder:
        library = floor_plain_c.compile_floor(Path(folder))
        return min(floor_plain_c.floor_run(library, scenario, inputs)[0] for _ in range(repeat))


#: Variants of the paper's case that tell what sets the RHS evaluations per motor step: the
#: chopper's saturation corners (min/max, no event indicators) against a smooth current loop and
#: a chopper that never saturates, and the friction that ends the ringing.
RHS_VARIANTS = [
    ("StepperMotor (clamped chopper)", ()),
    ("StepperMotorIdealCurrent (smooth)", ("fmus.motor=StepperMotorIdealCurrent",)),
    ("chopper never saturates (V_supply 100 V)", ("parameters.motor.V_supply=100",)),
    ("friction regularised 10x wider (w_s 0.1)", ("parameters.mechanics.w_s=0.1",)),
    ("rtol 1e-5 instead of 1e-6", ("solver.rtol=1e-5",)),
]


def rhs_per_step() -> None:
    """RHS evaluations per motor step of the paper's case and its variants (exact counts)."""
    from heliostep.run import run_scenario

    for label, overrides in RHS_VARIANTS:
        run = run_scenario(SCENARIOS / "jan21-central.yaml", overrides=overrides)
        rhs, steps = run.metadata["statistics"]["rhs"], max(1, int(run.summary["steps_commanded"]))
        print(
            f"jan21-central  {label:42s} {rhs:>8,d} RHS  {rhs / steps:7.1f} RHS/motor step  "
            f"peak torque {run.summary['peak_torque_Nm']:.3f} N.m",
            flush=True,
        )


def profile_paper_case(top: int = 15) -> None:
    from heliostep.run import run_scenario

    run_scenario(SCENARIOS / "jan21-central.yaml")  # warm up: FMUs built and extracted
    profiler = cProfile.Profile()
    profiler.enable()
    run_scenario(SCENARIOS / "jan21-central.yaml")
    profiler.disable()
    print(f"where the time of the 5-minute case goes (cProfile, top {top} by own time):")
    pstats.Stats(profiler, stream=sys.stdout).sort_stats("tottime").print_stats(top)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-day", action="store_true", help="skip the sunrise-to-sunset run")
    parser.add_argument("--profile", action="store_true", help="profile the 5-minute case")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    from heliostep.fmu.build import build_all

    build_all()
    bench("jan21-central", args.repeat, against_fmpy=True)
    rhs_per_step()
    if not args.skip_day:
        day_wall, fmpy_wall = bench("jan21-day", 1, against_fmpy=True)
        floor = floor_time("jan21-day", 3)
        assert fmpy_wall is not None
        # the one line a script reads (issue #26): the day, its floor and the ratios, measured in this run
        print(
            f"day: {day_wall:.3f} s, floor {floor:.3f} s, ratio {day_wall / floor:.2f}, fmpy {day_wall / fmpy_wall:.2f}"
        )
    if args.profile:
        profile_paper_case()


if __name__ == "__main__":
    main()
