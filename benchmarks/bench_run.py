"""Speed of the co-simulation master (prints figures; not a test).

    .venv/bin/python benchmarks/bench_run.py [--skip-day] [--profile]

Figures:
1. the paper's 5-minute case (scenarios/jan21-central.yaml): wall time of the simulation and
   of the whole run_scenario, right-hand-side evaluations (target: under 2 s);
2. sunrise to sunset (scenarios/jan21-day.yaml) (target: under 60 s);
3. the master on StepperMotor + PanelMechanics against fmpy.simulate_fmu on the monolithic
   DriveSystem FMU with the same inputs, tolerance and output grid (target: within 1.5x);
4. with --profile: where the time of the 5-minute case goes (cProfile, top functions).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
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


def bench_scenario(name: str, repeat: int) -> None:
    from heliostep.run import run_scenario

    wall, run = best_of(lambda: run_scenario(SCENARIOS / f"{name}.yaml"), repeat)
    stats = run.metadata["statistics"]
    print(f"{name}: simulation {stats['wall_time']:.2f} s, run_scenario {wall:.2f} s "
          f"(best of {repeat}); {run.summary['steps_commanded']} steps, {stats['rhs']} RHS evaluations, "
          f"{stats['integrator_calls']} integrator calls, {stats['events']} events, {len(run.trace)} trace rows")


def bench_against_monolithic(repeat: int) -> None:
    from fmpy import simulate_fmu

    from heliostep.fmu.build import ensure_fmu
    from heliostep.cosim.fmi import read_fmu
    from heliostep.drive.inputs import prepare_inputs
    from heliostep.cosim.master import CoSimulation, Connection, SolverOptions
    from heliostep.scenario import load_scenario

    scenario = load_scenario(SCENARIOS / "jan21-central.yaml")
    inputs = prepare_inputs(scenario, frozenset())
    duration, rtol, interval = inputs.duration, scenario.solver.rtol, 0.1
    grid = np.round(np.arange(0.0, duration + 1e-9, interval), 9)
    parameters = {"mechanics": {"theta_p_start": inputs.mechanics_parameters["theta_p_start"]},
                  "motor": dict(inputs.motor_parameters)}
    fmus = {"motor": read_fmu(ensure_fmu("StepperMotor")), "mechanics": read_fmu(ensure_fmu("PanelMechanics"))}
    connections = [Connection(s, t) for s, t in scenario.connection_pairs()]

    def master():
        system = CoSimulation(fmus, connections, inputs.signals, parameters)
        return system.simulate(0.0, duration, grid, SolverOptions(rtol=rtol))

    # the same piecewise-constant currents as an fmpy input table (a repeated time is a step)
    currents = {s.name: s for s in inputs.signals}
    edges = np.concatenate([[0.0], inputs.schedule.times, [duration]])
    rows = []
    for k in range(len(edges) - 1):
        values = (currents["i_a_ref"].values[k], currents["i_b_ref"].values[k], 0.0)
        rows += [(edges[k], *values), (edges[k + 1], *values)]
    table = np.array(rows, dtype=[("time", float), ("i_a_ref", float), ("i_b_ref", float), ("m_ext", float)])
    drive = str(ensure_fmu("DriveSystem"))
    start_values = {"mechanics.theta_p_start": parameters["mechanics"]["theta_p_start"],
                    "motor.i_a_start": parameters["motor"]["i_a_start"],
                    "motor.i_b_start": parameters["motor"]["i_b_start"]}

    def monolithic():
        return simulate_fmu(drive, fmi_type="ModelExchange", solver="CVode", stop_time=duration,
                            output_interval=interval, relative_tolerance=rtol, input=table,
                            start_values=start_values, output=["mechanics.theta", "motor.tau"])

    master_wall, result = best_of(master, repeat)
    fmpy_wall, reference = best_of(monolithic, repeat)
    difference = abs(result.trace["mechanics.theta"].iloc[-1] - reference["mechanics.theta"][-1])
    print(f"master (2 FMUs) vs fmpy.simulate_fmu (DriveSystem), paper's 5-minute window, rtol {rtol:g}: "
          f"{master_wall:.3f} s vs {fmpy_wall:.3f} s = {master_wall / fmpy_wall:.2f}x "
          f"(best of {repeat}); master {result.statistics['rhs']} RHS evaluations; "
          f"final rotor angles differ by {difference:.2e} rad")


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
    bench_scenario("jan21-central", args.repeat)
    bench_against_monolithic(args.repeat)
    if not args.skip_day:
        bench_scenario("jan21-day", 1)
    if args.profile:
        profile_paper_case()


if __name__ == "__main__":
    main()
